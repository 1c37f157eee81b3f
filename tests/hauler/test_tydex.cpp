// The TYDEX C-axis transformation: axes built from the spin axis and the road normal, on a
// level, a pitched and a rolled (cambered) axle and on a sloped road.
#include <gtest/gtest.h>

#include <cmath>

#include "tydex.hpp"

using namespace hauler;

namespace {

void expect_vec(const Dir3& a, const Dir3& b, double tol, const char* what) {
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a[i], b[i], tol) << what << " component " << i;
}

// a unit, right-handed, orthogonal triad
void expect_triad(const TydexAxes& a) {
  for (const Dir3* v : {&a.x, &a.y, &a.z}) EXPECT_NEAR(tydex_dot(*v, *v), 1.0, 1e-14);
  EXPECT_NEAR(tydex_dot(a.x, a.y), 0.0, 1e-14);
  EXPECT_NEAR(tydex_dot(a.y, a.z), 0.0, 1e-14);
  EXPECT_NEAR(tydex_dot(a.z, a.x), 0.0, 1e-14);
  expect_vec(tydex_cross(a.x, a.y), a.z, 1e-14, "x cross y = z");
}

// Rotation about ground y by angle (x towards z: an axle pitched nose up).
Dir3 pitched(const Dir3& v, double a) {
  return {std::cos(a) * v[0] - std::sin(a) * v[2], v[1], std::sin(a) * v[0] + std::cos(a) * v[2]};
}
// Rotation about ground x by angle (y towards z: an axle rolled, left wheel up).
Dir3 rolled(const Dir3& v, double a) {
  return {v[0], std::cos(a) * v[1] - std::sin(a) * v[2], std::sin(a) * v[1] + std::cos(a) * v[2]};
}

const Dir3 kUp{0, 0, 1};
const Dir3 kForce{1200.0, -350.0, 210000.0};  // a tire force on the machine, ground axes

}  // namespace

TEST(hauler_tydex, LevelAxleIsTheGroundFrame) {
  const TydexAxes a = tydex_c_axes({0, 1, 0}, kUp);
  expect_triad(a);
  expect_vec(a.x, {1, 0, 0}, 1e-15, "x");
  expect_vec(a.z, {0, 0, 1}, 1e-15, "z");
  expect_vec(tydex_c({0, 1, 0}, kUp, kForce), kForce, 1e-9, "F");
  // lengths of the inputs do not matter
  expect_vec(tydex_c({0, 3.5, 0}, {0, 0, 0.2}, kForce), kForce, 1e-9, "F scaled inputs");
}

// An axle pitched by 0.2 rad (the chassis nose up) keeps its spin axis: the TYDEX axes and the
// components do not change, while the axle body's own x axis would tilt with it and mix the
// vertical load into "Fx".
TEST(hauler_tydex, PitchedAxleKeepsTheAxes) {
  const double theta = 0.2;
  const Dir3 spin = pitched({0, 1, 0}, theta);  // = (0, 1, 0)
  const Dir3 F = tydex_c(spin, kUp, kForce);
  expect_vec(F, kForce, 1e-9, "pitched");
  const Dir3 axle_x = pitched({1, 0, 0}, theta);
  EXPECT_GT(std::abs(tydex_dot(kForce, axle_x) - F[0]), 1e4);  // what the body axes would give
}

// A rolled (cambered) axle, camber gamma: y = (0, cos g, sin g) along the spin axis, x stays
// forward along the road, z = x cross y = (0, -sin g, cos g) tilts with the wheel plane:
//   Fx = F.x, Fy = Fy cos g + Fz sin g, Fz = -Fy sin g + Fz cos g.
TEST(hauler_tydex, RolledAxleTiltsYAndZWithTheWheel) {
  const double g = 0.1;
  const Dir3 spin = rolled({0, 1, 0}, g);
  const TydexAxes a = tydex_c_axes(spin, kUp);
  expect_triad(a);
  expect_vec(a.x, {1, 0, 0}, 1e-15, "x");
  expect_vec(a.z, {0, -std::sin(g), std::cos(g)}, 1e-15, "z");
  const Dir3 F = tydex_c(spin, kUp, kForce);
  expect_vec(F,
             {kForce[0], kForce[1] * std::cos(g) + kForce[2] * std::sin(g),
              -kForce[1] * std::sin(g) + kForce[2] * std::cos(g)},
             1e-9, "rolled");
  // pitch on top of roll: spin axis = pitch(roll(y)); x is still parallel to the road
  const Dir3 spin2 = pitched(spin, 0.3);
  const TydexAxes b = tydex_c_axes(spin2, kUp);
  expect_triad(b);
  EXPECT_NEAR(tydex_dot(b.x, kUp), 0.0, 1e-15);
  EXPECT_NEAR(tydex_dot(b.x, spin2), 0.0, 1e-15);
}

// On a road sloped by alpha (uphill ahead), x runs along the slope; the machine's weight
// resolves into -W sin(alpha) along x and W cos(alpha) into the road.
TEST(hauler_tydex, SlopedRoadTurnsXAlongTheRoad) {
  const double al = 0.15, W = 1e5;
  const Dir3 normal{-std::sin(al), 0, std::cos(al)};
  const TydexAxes a = tydex_c_axes({0, 1, 0}, normal);
  expect_triad(a);
  expect_vec(a.x, {std::cos(al), 0, std::sin(al)}, 1e-15, "x");
  const Dir3 F = tydex_c({0, 1, 0}, normal, {0, 0, -W});
  expect_vec(F, {-W * std::sin(al), 0, -W * std::cos(al)}, 1e-9, "weight");
}

TEST(hauler_tydex, AWheelLyingFlatHasNoAxes) {
  EXPECT_THROW(tydex_c_axes({0, 0, 1}, kUp), std::invalid_argument);
  EXPECT_THROW(tydex_c_axes({0, 0, 0}, kUp), std::invalid_argument);
}
