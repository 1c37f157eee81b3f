// solve_newton, the machines' static-equilibrium solver (docs/machines.md), on systems with
// known roots.
#include <gtest/gtest.h>

#include <cmath>

#include "simbody_machine.hpp"

namespace {

// x^2 + y^2 = 4, x = y: the root (sqrt 2, sqrt 2) from (1, 0.5).
SimTK::Vector circle(const SimTK::Vector& v) {
  SimTK::Vector r(2);
  r[0] = v[0] * v[0] + v[1] * v[1] - 4;
  r[1] = v[0] - v[1];
  return r;
}

}  // namespace

TEST(machines_layer, NewtonFindsTheRootAndLeavesTheStateThere) {
  SimTK::Vector y(2);
  y[0] = 1;
  y[1] = 0.5;
  SimTK::Vector last(2, 0.0);
  int calls = 0;
  auto residual = [&](const SimTK::Vector& v) {
    ++calls;
    last = v;
    return circle(v);
  };
  const SimTK::Vector r = mbs::solve_newton(residual, y, {50, 1e-13, {1e-7, 1e-7}, {1, 1}});
  EXPECT_LT(r.normInf(), 1e-13);
  EXPECT_NEAR(y[0], std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(y[1], std::sqrt(2.0), 1e-12);
  EXPECT_EQ(last[0], y[0]);  // the last call was at the solution
  EXPECT_EQ(last[1], y[1]);
  EXPECT_LT(calls, 50);  // quadratic convergence: a handful of iterations of 3 calls
}

// The trust region: from far away no unknown moves more than its limit per iteration, so
// reaching a root 10 units away with a limit of 0.5 takes at least 20 iterations.
TEST(machines_layer, NewtonStepsStayInsideTheTrustRegion) {
  SimTK::Vector y(1, 0.0);
  double largest = 0, previous = 0;
  int iterations = 0;
  auto residual = [&](const SimTK::Vector& v) {
    SimTK::Vector r(1);
    r[0] = v[0] - 10;
    return r;
  };
  // watch the accepted iterates through the residual at the solution of each iteration
  const SimTK::Vector r = mbs::solve_newton(
      [&](const SimTK::Vector& v) {
        if (std::abs(v[0] - previous) > 1e-3) {  // not a finite-difference probe
          largest = std::max(largest, std::abs(v[0] - previous));
          previous = v[0];
          ++iterations;
        }
        return residual(v);
      },
      y, {100, 1e-12, {1e-7}, {0.5}});
  EXPECT_NEAR(y[0], 10.0, 1e-12);
  EXPECT_LT(r.normInf(), 1e-12);
  EXPECT_LE(largest, 0.5 + 1e-12);
  EXPECT_GE(iterations, 20);
}

// No root (x^2 + 1 = 0): it stops at the iteration limit or when no step lowers the residual,
// and says so through the residual it returns.
TEST(machines_layer, NewtonWithoutARootReturnsTheResidualItReached) {
  SimTK::Vector y(1, 0.7);
  const SimTK::Vector r = mbs::solve_newton(
      [](const SimTK::Vector& v) {
        SimTK::Vector out(1);
        out[0] = v[0] * v[0] + 1;
        return out;
      },
      y, {30, 1e-11, {1e-7}, {0.05}});
  EXPECT_GE(r.normInf(), 1.0);
  EXPECT_NEAR(r[0], y[0] * y[0] + 1, 1e-15);
}

TEST(machines_layer, NewtonRefusesSettingsOfTheWrongSize) {
  SimTK::Vector y(2, 0.0);
  EXPECT_THROW(mbs::solve_newton(circle, y, {50, 1e-11, {1e-7}, {1, 1}}), std::logic_error);
}
