// The keyframe trajectory that the prescribed participant and dem_run play
// (cosim/trajectory.hpp): keyframes hit exactly, velocities are the derivatives of the
// positions, slerp turns at a constant rate, bad keyframes are refused.
#include <gtest/gtest.h>

#include <cmath>

#include "cosim/rotation.hpp"
#include "cosim/trajectory.hpp"

using cosim::Keyframe;
using cosim::Trajectory;

namespace {

Trajectory three_keys(Trajectory::Interpolation how) {
  Trajectory t;
  t.interpolation = how;
  const double half = std::sqrt(0.5);
  t.keyframes = {{0.0, {0, 0, 1}, {1, 0, 0, 0}},
                 {1.0, {1, 0, 0.5}, {half, 0, half, 0}},   // 90 deg about y
                 {3.0, {2, 1, 0.5}, {half, 0, half, 0}}};
  cosim::validate_keyframes(t.keyframes, "test");
  return t;
}

}  // namespace

TEST(Trajectory, HitsEveryKeyframeAndHoldsOutside) {
  for (auto how : {Trajectory::Interpolation::linear, Trajectory::Interpolation::cubic}) {
    const Trajectory t = three_keys(how);
    for (const Keyframe& k : t.keyframes) {
      const auto p = t.evaluate(k.time);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(p.position[c], k.position[c], 1e-15);
      for (int c = 0; c < 4; ++c) EXPECT_NEAR(p.orientation[c], k.orientation[c], 1e-15);
    }
    const auto before = t.evaluate(-1), after = t.evaluate(5);
    EXPECT_EQ(before.velocity, (cosim::Vec3{0, 0, 0}));
    EXPECT_EQ(after.position, t.keyframes.back().position);
  }
}

TEST(Trajectory, VelocitiesAreTheDerivativesOfTheInterpolation) {
  for (auto how : {Trajectory::Interpolation::linear, Trajectory::Interpolation::cubic}) {
    const Trajectory t = three_keys(how);
    for (double time : {0.2, 0.7, 1.3, 2.5}) {
      const double h = 1e-6;
      const auto a = t.evaluate(time - h), b = t.evaluate(time + h), p = t.evaluate(time);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(p.velocity[c], (b.position[c] - a.position[c]) / (2 * h), 1e-6) << time;
      // Angular velocity: the world-frame rotation from a to b over 2h.
      const auto w = cosim::quat_log(cosim::quat_multiply(b.orientation, cosim::quat_conjugate(a.orientation)));
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(p.angular_velocity[c], w[c] / (2 * h), 1e-6) << time;
    }
  }
  // Linear: the first segment moves at (1, 0, -0.5) m/s and turns at pi/2 rad/s about y.
  const auto p = three_keys(Trajectory::Interpolation::linear).evaluate(0.5);
  EXPECT_NEAR(p.velocity[0], 1.0, 1e-12);
  EXPECT_NEAR(p.velocity[2], -0.5, 1e-12);
  EXPECT_NEAR(p.angular_velocity[1], M_PI / 2, 1e-12);
  EXPECT_NEAR(p.orientation[0], std::cos(M_PI / 8), 1e-12);  // 45 deg at half time
}

TEST(Trajectory, CubicIsC1AtInnerKeyframes) {
  const Trajectory t = three_keys(Trajectory::Interpolation::cubic);
  const auto left = t.evaluate(1.0 - 1e-9), right = t.evaluate(1.0 + 1e-9);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(left.velocity[c], right.velocity[c], 1e-6);
  // Catmull-Rom tangent at keyframe 1: (p2 - p0) / (t2 - t0) = (2, 1, -0.5) / 3.
  EXPECT_NEAR(right.velocity[0], 2.0 / 3, 1e-6);
  EXPECT_NEAR(right.velocity[1], 1.0 / 3, 1e-6);
}

TEST(Trajectory, BadKeyframesAreRefusedWithTheReason) {
  std::vector<Keyframe> k = {{0, {0, 0, 0}, {1, 0, 0, 0}}, {0, {1, 0, 0}, {1, 0, 0, 0}}};
  EXPECT_THROW(cosim::validate_keyframes(k, "tools.0.keyframes"), std::invalid_argument);
  k = {{0, {0, 0, 0}, {0, 0, 0, 0}}};
  try {
    cosim::validate_keyframes(k, "tools.0.keyframes");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("quaternion"), std::string::npos);
  }
  k = {{0, {NAN, 0, 0}, {1, 0, 0, 0}}};
  EXPECT_THROW(cosim::validate_keyframes(k, "k"), std::invalid_argument);
  k.clear();
  EXPECT_THROW(cosim::validate_keyframes(k, "k"), std::invalid_argument);
  EXPECT_THROW(cosim::load_keyframes_csv("/nonexistent/motion.csv"), std::runtime_error);
}
