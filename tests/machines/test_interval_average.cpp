// IntervalAverage: the trapezoid mean of a machine's samples over a macro step, against closed
// forms (docs/machines.md).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "interval_average.hpp"

namespace {

mbs::MachineSample sample(double t) {
  mbs::MachineSample s;
  s.body.position = {1 + 2 * t, -t, 3};
  s.body.velocity = {2, -1, 0};
  // a rotation about z by t rad
  s.body.orientation = {std::cos(t / 2), 0, 0, std::sin(t / 2)};
  s.body.angular_velocity = {0, 0, 1};
  s.scalars = {t * t, 5};
  return s;
}

}  // namespace

// A linear signal's trapezoid mean is its value at the midpoint; t^2 over [0, 1] with n
// intervals is 1/3 + 1/(6 n^2) (the trapezoid rule's error for a parabola).
TEST(machines_layer, TrapezoidMeanOfLinearAndQuadraticSignals) {
  for (int n : {1, 4, 10}) {
    mbs::IntervalAverage avg(sample(0));
    for (int k = 1; k <= n; ++k) avg.add(sample(static_cast<double>(k) / n));
    const mbs::MachineSample m = avg.mean();
    EXPECT_NEAR(m.body.position[0], 2.0, 1e-14) << n;
    EXPECT_NEAR(m.body.position[1], -0.5, 1e-14) << n;
    EXPECT_NEAR(m.body.velocity[0], 2.0, 1e-14) << n;
    EXPECT_NEAR(m.scalars[0], 1.0 / 3 + 1.0 / (6.0 * n * n), 1e-14) << n;
    EXPECT_NEAR(m.scalars[1], 5.0, 1e-14) << n;
    // the mean quaternion of a rotation about z from 0 to 1 rad, normalized: about z by 0.5 rad
    // (the chord mean of a uniform arc points at its middle)
    EXPECT_NEAR(m.body.orientation[3] / m.body.orientation[0], std::tan(0.25), 1e-12) << n;
    EXPECT_NEAR(m.body.orientation[0] * m.body.orientation[0] + m.body.orientation[3] * m.body.orientation[3],
                1.0, 1e-14);
  }
}

// q and -q are one orientation: a sample given with the other sign is folded onto the first
// sample's hemisphere, so it does not cancel the mean.
TEST(machines_layer, QuaternionSignIsKeptOnTheFirstHemisphere) {
  mbs::IntervalAverage avg(sample(0));
  mbs::MachineSample flipped = sample(0.2);
  for (double& c : flipped.body.orientation) c = -c;
  avg.add(flipped);
  const auto m = avg.mean();
  EXPECT_GT(m.body.orientation[0], 0.99);
  EXPECT_NEAR(m.body.orientation[3] / m.body.orientation[0], std::tan(0.05), 1e-12);
}

TEST(machines_layer, AverageNeedsASampleAfterTheFirstAndTheSameScalars) {
  mbs::IntervalAverage avg(sample(0));
  EXPECT_THROW(avg.mean(), std::logic_error);
  mbs::MachineSample other = sample(1);
  other.scalars.pop_back();
  EXPECT_THROW(avg.add(other), std::logic_error);
}
