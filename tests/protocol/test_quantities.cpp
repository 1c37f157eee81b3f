// Typed coupling quantities: the flat layouts, the torque shift against a closed form, power
// invariant under the shift, round trips through Value, tangent coordinates and the wire types,
// and values of the wrong size refused.
#include <cosim/quantities.hpp>
#include <cosim/signal_wire.hpp>
#include <gtest/gtest.h>

#include <random>

using namespace cosim;

namespace {

Kinematics sample_kinematics() {
  return {{1, 2, 3}, quat_normalized({0.9, 0.1, -0.3, 0.2}), {0.4, -0.5, 0.6}, {0.7, -0.8, 0.9}};
}

double dot3(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

}  // namespace

TEST(Quantities, ValueLayoutsAreTheDocumentedOnes) {
  const Kinematics k{{1, 2, 3}, {4, 5, 6, 7}, {8, 9, 10}, {11, 12, 13}};
  EXPECT_EQ(k.to_value(), (Value{1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13}));
  EXPECT_EQ(Kinematics::component_names(),
            (std::vector<std::string>{"px", "py", "pz", "qw", "qx", "qy", "qz", "vx", "vy", "vz",
                                      "wx", "wy", "wz"}));
  const Wrench w{{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
  EXPECT_EQ(w.to_value(), (Value{1, 2, 3, 4, 5, 6, 7, 8, 9}));
  EXPECT_EQ(Wrench::component_names(),
            (std::vector<std::string>{"fx", "fy", "fz", "tx", "ty", "tz", "rx", "ry", "rz"}));
  EXPECT_EQ(value_size(SignalKind::Kinematics), Kinematics::kSize);
  EXPECT_EQ(value_size(SignalKind::Wrench), Wrench::kSize);
  EXPECT_EQ(tangent_size(SignalKind::Kinematics), Kinematics::kTangentSize);
}

TEST(Quantities, RoundTripThroughValueIsExact) {
  const Kinematics k = sample_kinematics();
  EXPECT_EQ(Kinematics::from_value(k.to_value()).to_value(), k.to_value());
  const Wrench w{{-1.5, 2.25, 1e5}, {0.125, -3, 7}, {0.1, 0.2, 0.3}};
  EXPECT_EQ(Wrench::from_value(w.to_value()).to_value(), w.to_value());
}

TEST(Quantities, RoundTripThroughTheWireTypesIsExact) {
  const Kinematics k = sample_kinematics();
  const kinematics_t km = to_wire(k);
  EXPECT_EQ(km.linear_velocity[2], k.velocity[2]);
  EXPECT_EQ(km.orientation[0], k.orientation[0]);
  EXPECT_EQ(from_wire(km).to_value(), k.to_value());
  const Wrench w{{-1.5, 2.25, 1e5}, {0.125, -3, 7}, {0.1, 0.2, 0.3}};
  const wrench_t wm = to_wire(w);
  EXPECT_EQ(wm.reference_point[1], w.point[1]);
  EXPECT_EQ(wm.torque[0], w.torque[0]);
  EXPECT_EQ(from_wire(wm).to_value(), w.to_value());
  // and whole signal sets, as participants send them
  Signals s;
  s["k"] = {SignalKind::Kinematics, k.to_value()};
  s["w"] = {SignalKind::Wrench, w.to_value()};
  s["x"] = {SignalKind::Scalar, {4.5}};
  const Signals back = from_message(to_message(s), "test");
  for (const auto& [name, signal] : s) EXPECT_EQ(back.at(name).value, signal.value) << name;
}

TEST(Quantities, TangentCoordinatesRoundTripAndDifference) {
  const Kinematics k = sample_kinematics();
  const Quat ref = quat_normalized({1, 0.2, 0.1, -0.1});
  const auto t = k.to_tangent(ref);
  ASSERT_EQ(static_cast<int>(t.size()), Kinematics::kTangentSize);
  const Kinematics back = Kinematics::from_tangent(t, ref);
  for (int i = 0; i < Kinematics::kSize; ++i)
    EXPECT_NEAR(back.to_value()[i], k.to_value()[i], 1e-14) << i;
  // A body turned by r about its own axes and moved by dp differs from the original by them.
  Kinematics moved = k;
  const Vec3 r{0.01, -0.02, 0.03};
  moved.orientation = quat_multiply(k.orientation, quat_exp(r));
  moved.position[1] += 0.5;
  moved.angular_velocity[2] -= 2;
  const auto d = moved.difference(k);
  const std::vector<double> want{0, 0.5, 0, r[0], r[1], r[2], 0, 0, 0, 0, 0, -2};
  ASSERT_EQ(d.size(), want.size());
  for (std::size_t i = 0; i < d.size(); ++i) EXPECT_NEAR(d[i], want[i], 1e-14) << i;
  for (double x : k.difference(k)) EXPECT_NEAR(x, 0.0, 1e-15);
}

TEST(Quantities, ShiftMatchesTheClosedForm) {
  // torque about o = torque about r + (r - o) x f; r - o = (1, -1, -2), (r - o) x f = (1, -5, 3)
  const Wrench w{{1, 2, 3}, {0.5, -1, 2}, {1, 0, 0}};
  const Wrench s = w.shifted_to({0, 1, 2});
  EXPECT_EQ(s.to_value(), (Value{1, 2, 3, 1.5, -6, 5, 0, 1, 2}));
  // shifting back gives the original (exact here: small integers and halves)
  EXPECT_EQ(s.shifted_to(w.point).to_value(), w.to_value());
  // a pure couple does not change
  const Wrench couple{{0, 0, 0}, {3, -4, 5}, {1, 1, 1}};
  EXPECT_EQ(couple.shifted_to({-7, 8, 9}).torque, couple.torque);
}

TEST(Quantities, PowerMatchesTheClosedFormAndIsInvariantUnderShift) {
  // Pure translation: f . v. Pure rotation about the wrench's point: t . w.
  Kinematics translating;
  translating.velocity = {1, -2, 0.5};
  const Wrench w{{3, 4, -2}, {1, 1, 1}, {5, 6, 7}};
  EXPECT_EQ(w.power(translating), dot3(w.force, translating.velocity));
  Kinematics spinning;
  spinning.position = w.point;
  spinning.angular_velocity = {0.3, -0.2, 0.1};
  EXPECT_DOUBLE_EQ(w.power(spinning), dot3(w.torque, spinning.angular_velocity));
  // The point of a body spinning about z at 2 rad/s, 3 m from the axis along x, moves at 6 m/s
  // along y.
  Kinematics k;
  k.angular_velocity = {0, 0, 2};
  EXPECT_EQ(k.velocity_at({3, 0, 0}), (Vec3{0, 6, 0}));

  std::mt19937 gen(11);
  std::uniform_real_distribution<double> u(-2, 2);
  for (int trial = 0; trial < 100; ++trial) {
    const Kinematics m{{u(gen), u(gen), u(gen)},
                       quat_normalized({u(gen), u(gen), u(gen), u(gen)}),
                       {u(gen), u(gen), u(gen)},
                       {u(gen), u(gen), u(gen)}};
    const Wrench f{{u(gen), u(gen), u(gen)}, {u(gen), u(gen), u(gen)}, {u(gen), u(gen), u(gen)}};
    const double p = f.power(m);
    for (const Vec3& o : {Vec3{0, 0, 0}, m.position, Vec3{u(gen), u(gen), u(gen)}})
      EXPECT_NEAR(f.shifted_to(o).power(m), p, 1e-12 * (1 + std::abs(p))) << trial;
  }
}

// The message of what `from_value` raises for `n` zeros, or "" if it accepts them.
template <class Quantity>
std::string refusal(std::size_t n) {
  try {
    Quantity::from_value(Value(n, 0.0));
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Quantities, ValuesOfTheWrongSizeAreRefusedNamingTheLayout) {
  for (std::size_t n : {0u, 12u, 14u}) {
    const std::string m = refusal<Kinematics>(n);
    EXPECT_NE(m.find("expected 13"), std::string::npos) << n << ": " << m;
    EXPECT_NE(m.find("[px py pz qw qx qy qz vx vy vz wx wy wz]"), std::string::npos) << m;
  }
  for (std::size_t n : {0u, 8u, 10u}) {
    const std::string m = refusal<Wrench>(n);
    EXPECT_NE(m.find("expected 9"), std::string::npos) << n << ": " << m;
    EXPECT_NE(m.find("[fx fy fz tx ty tz rx ry rz]"), std::string::npos) << m;
  }
  EXPECT_THROW(Kinematics::from_tangent(std::vector<double>(13, 0.0), {1, 0, 0, 0}),
               std::invalid_argument);
  // what the bus refuses: a wrench value of the wrong size
  EXPECT_THROW(validate_value(SignalKind::Wrench, Value(8, 0.0), "test"), ProtocolError);
}
