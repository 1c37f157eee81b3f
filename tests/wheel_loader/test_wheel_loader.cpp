// The wheel-loader model driven directly (no bus): Newton-Euler on the bucket during the
// maneuver, static equilibrium of the linkage, the external wrench's path into the pins,
// and the traction limit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "wheel_loader.hpp"

using namespace wheel_loader;

namespace {

V3 add(V3 a, const V3& b) {
  for (int i = 0; i < 3; ++i) a[i] += b[i];
  return a;
}
V3 sub(V3 a, const V3& b) {
  for (int i = 0; i < 3; ++i) a[i] -= b[i];
  return a;
}
V3 scale(double s, V3 a) {
  for (auto& v : a) v *= s;
  return a;
}
V3 cross(const V3& a, const V3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const V3& a, const V3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const V3& a) { return std::sqrt(dot(a, a)); }
V3 mul(const std::array<V3, 3>& M, const V3& v) { return {dot(M[0], v), dot(M[1], v), dot(M[2], v)}; }

// A force acting at a point: its moment about `about`.
V3 moment(const V3& point, const V3& force, const V3& about) { return cross(sub(point, about), force); }

struct Balance {
  V3 force{}, moment{};  // sums of everything applied, moment about `about`
  V3 about{};
  void add_force(const V3& f, const V3& at) {
    force = ::add(force, f);
    moment = ::add(moment, ::moment(at, f, about));
  }
  void add_pin(const PinForce& p, double sign = 1) {
    add_force(scale(sign, p.force), p.point);
    moment = ::add(moment, scale(sign, p.moment));
  }
};

// Residuals of Newton-Euler for a body: (sum F - m a_cm, sum M_cm - I alpha - w x I w).
std::pair<V3, V3> newton_euler(const BodyDynamics& b, Balance sums, const V3& g) {
  sums.add_force(scale(b.mass, g), b.com);
  const V3 f = sub(sums.force, scale(b.mass, b.com_acceleration));
  const V3 Iw = mul(b.inertia, b.angular_velocity);
  const V3 m = sub(sums.moment, add(mul(b.inertia, b.angular_acceleration), cross(b.angular_velocity, Iw)));
  return {f, m};
}

Balance about(const V3& point) {
  Balance b;
  b.about = point;
  return b;
}

Parameters at_rest() {
  Parameters p;
  p.initial_speed = 0;
  p.maneuver.speed.knots = {{0, 0}};
  p.maneuver.lift.knots = {{0, 0.1}};   // boom a little up, bucket a little curled
  p.maneuver.tilt.knots = {{0, 0.12}};
  return p;
}

}  // namespace

// With no external force, the A and J reactions, gravity and the bucket's inertia satisfy
// Newton-Euler on the bucket at every inner step of a dynamic stretch of the maneuver (a
// tilt pulse while driving and lifting).
TEST(wheel_loader_model, BearingForcesBalanceBucketWeightAndInertia) {
  Parameters p;
  WheelLoader wl(p, 5.2);  // starts at rest at 5.2 s, then 1.2 m/s, during a tilt pulse
  double worst = 0, largest_inertial = 0;
  int checked = 0;
  wl.advance(5.6, [&] {
    const Dynamics d = wl.dynamics();
    Balance s = about(d.bucket.com);
    s.add_pin(d.a_pin);
    s.add_pin(d.j_pin);
    const auto [f, m] = newton_euler(d.bucket, s, d.gravity);
    const double scale_f = norm(d.a_pin.force) + norm(d.j_pin.force) + d.bucket.mass * 9.81;
    worst = std::max({worst, norm(f) / scale_f, norm(m) / (scale_f * 1.0)});
    largest_inertial = std::max(largest_inertial, d.bucket.mass * norm(d.bucket.com_acceleration));
    // a frictionless pin carries no moment about its own axis (y)
    EXPECT_LT(std::abs(d.a_pin.moment[1]), 1e-6 * scale_f);
    EXPECT_LT(std::abs(d.j_pin.moment[1]), 1e-6 * scale_f);
    ++checked;
  });
  std::printf("bucket Newton-Euler: worst relative residual %.2e over %d inner steps, "
              "largest m*a %.0f N\n", worst, checked, largest_inertial);
  EXPECT_EQ(checked, 4000);
  EXPECT_LT(worst, 1e-6);
  // not a quasi-static check: the inertial force is a real share of the load
  EXPECT_GT(largest_inertial, 500.0);
}

// The same with an external wrench (force, torque about a point away from the bucket origin):
// the pins, gravity and the wrench balance the bucket's inertia.
TEST(wheel_loader_model, BearingForcesBalanceWithExternalWrench) {
  Parameters p;
  WheelLoader wl(p, 5.2);
  wl.set_wrench([](double t) {
    Wrench w;
    w.force = {-6e4 - 1e4 * std::sin(20 * t), 2e3, 3e4};
    w.torque = {1e3, -2e4 * std::cos(15 * t), 5e2};
    w.point = {9.0, 0.3, 0.2};
    return w;
  });
  double worst = 0;
  wl.advance(5.4, [&] {
    const Dynamics d = wl.dynamics();
    Balance s = about(d.bucket.com);
    s.add_pin(d.a_pin);
    s.add_pin(d.j_pin);
    s.add_force(d.external.force, d.external.point);
    s.moment = add(s.moment, d.external.torque);
    const auto [f, m] = newton_euler(d.bucket, s, d.gravity);
    const double scale_f = norm(d.a_pin.force) + norm(d.j_pin.force) + norm(d.external.force);
    worst = std::max({worst, norm(f) / scale_f, norm(m) / scale_f});
  });
  std::printf("bucket Newton-Euler with a wrench: worst relative residual %.2e\n", worst);
  EXPECT_LT(worst, 1e-6);
}

// Machine at rest, cylinders held: every body of the linkage is in static equilibrium, and
// the cylinder forces follow from statics computed here from the pin positions alone.
TEST(wheel_loader_model, LinkageStaticEquilibrium) {
  Parameters p = at_rest();
  p.tilt_link.mass = 0.01;  // a (nearly) massless link is a two-force member
  p.tilt_link.inertia = {1e-4, 1e-4, 1e-4};
  WheelLoader wl(p);
  std::printf("static state: largest generalized acceleration %.2e\n", wl.max_acceleration());
  ASSERT_LT(wl.max_acceleration(), 1e-8);
  const Dynamics d = wl.dynamics();
  const V3 g = d.gravity;
  const double W = (d.boom.mass + d.crank.mass + d.bucket.mass) * 9.81;
  double worst = 0;
  auto check = [&](const char* name, const Balance& s, const BodyDynamics& b) {
    Balance t = s;
    t.add_force(scale(b.mass, g), b.com);
    const double r = std::max(norm(t.force), norm(t.moment) / 3.0) / W;
    std::printf("  %-10s |sum F| %.2e N  |sum M| %.2e N m\n", name, norm(t.force), norm(t.moment));
    worst = std::max(worst, r);
  };
  {
    Balance s = about(d.boom.origin);
    s.add_pin(d.boom_pivot);
    s.add_pin(d.a_pin, -1);
    s.add_pin(d.crank_pivot, -1);
    s.add_force(d.lift_on_boom.force, d.lift_on_boom.point);
    check("boom", s, d.boom);
  }
  {
    Balance s = about(d.crank.origin);
    s.add_pin(d.crank_pivot);
    s.add_pin(d.link_pin, -1);
    s.add_force(d.tilt_on_crank.force, d.tilt_on_crank.point);
    check("bell crank", s, d.crank);
  }
  {
    Balance s = about(d.link.origin);
    s.add_pin(d.link_pin);
    s.add_pin(d.j_pin, -1);
    check("tilt link", s, d.link);
  }
  {
    Balance s = about(d.bucket.origin);
    s.add_pin(d.a_pin);
    s.add_pin(d.j_pin);
    check("bucket", s, d.bucket);
  }
  EXPECT_LT(worst, 1e-7);

  // The tilt link as a two-force member: the force it puts on the bucket lies along it.
  const V3 link_dir = scale(1 / norm(sub(d.j_pin.point, d.link_pin.point)), sub(d.j_pin.point, d.link_pin.point));
  const V3 Fj = d.j_pin.force;
  EXPECT_LT(norm(cross(link_dir, Fj)), 1e-5 * norm(Fj));

  // Independent statics from the positions: bucket moments about A give the link force,
  // bell-crank moments about its pivot give the tilt cylinder force, moments of the whole
  // boom group about the boom pivot give the lift cylinder force (y components, planar).
  const double Wb = d.bucket.mass * 9.81, Wc = d.crank.mass * 9.81, Wboom = d.boom.mass * 9.81;
  const V3 down{0, 0, -1};
  const V3 A = d.a_pin.point;
  // bucket: M_A(weight) + M_A(S link_dir at J) = 0, S the link force on the bucket along +link_dir
  const double S = -moment(d.bucket.com, scale(Wb, down), A)[1] / moment(d.j_pin.point, link_dir, A)[1];
  EXPECT_NEAR(dot(Fj, link_dir), S, 1e-6 * std::abs(S));
  // bell crank about its pivot C: link pulls the crank at D with -S link_dir
  const V3 C = d.crank_pivot.point;
  const V3 tilt_dir = scale(1 / norm(sub(d.tilt_on_crank.point, d.tilt_frame_pin)),
                            sub(d.tilt_on_crank.point, d.tilt_frame_pin));
  const double tilt = -(moment(d.link_pin.point, scale(-S, link_dir), C)[1] +
                        moment(d.crank.com, scale(Wc, down), C)[1]) /
                      moment(d.tilt_on_crank.point, tilt_dir, C)[1];
  const double tilt_model = dot(d.tilt_on_crank.force, tilt_dir);
  EXPECT_NEAR(tilt_model, tilt, 1e-6 * std::abs(tilt));
  // boom group about the boom pivot P: weights + tilt cylinder on the crank + lift cylinder
  const V3 P = d.boom_pivot.point;
  const V3 lift_dir = scale(1 / norm(sub(d.lift_on_boom.point, d.lift_frame_pin)),
                            sub(d.lift_on_boom.point, d.lift_frame_pin));
  const double others = moment(d.boom.com, scale(Wboom, down), P)[1] +
                        moment(d.crank.com, scale(Wc, down), P)[1] +
                        moment(d.bucket.com, scale(Wb, down), P)[1] +
                        moment(d.link.com, scale(d.link.mass * 9.81, down), P)[1] +
                        moment(d.tilt_on_crank.point, scale(tilt, tilt_dir), P)[1];
  const double lift = -others / moment(d.lift_on_boom.point, lift_dir, P)[1];
  const double lift_model = dot(d.lift_on_boom.force, lift_dir);
  EXPECT_NEAR(lift_model, lift, 1e-6 * std::abs(lift));
  std::printf("static: lift %.1f N (statics %.1f), tilt %.1f N (statics %.1f), link %.1f N\n",
              lift_model, lift, tilt_model, tilt, S);
  // the reports carry the same numbers, with their documented signs (cylinders push)
  const Reports r = wl.reports();
  EXPECT_DOUBLE_EQ(r.lift_force, lift_model);
  EXPECT_DOUBLE_EQ(r.tilt_force, tilt_model);
  EXPECT_GT(r.lift_force, 0);
  EXPECT_GT(r.tilt_force, 0);
  // the machine carries its whole weight on the axles
  EXPECT_NEAR(r.normal_load, wl.total_mass() * 9.81, 1e-6 * wl.total_mass() * 9.81);
}

// A known wrench changes the pin forces as statics says. Stiff tires and cylinders keep the
// pose the same with and without it, so the differences are the wrench's alone.
TEST(wheel_loader_model, ExternalWrenchGoesWhereItShould) {
  Parameters p = at_rest();
  p.axle_stiffness = 1e12;
  p.lift_cylinder.stiffness = 1e12;
  p.tilt_cylinder.stiffness = 1e12;
  WheelLoader base(p);
  const Dynamics d0 = base.dynamics();
  const V3 A = d0.a_pin.point;

  // (1) a vertical force through the A-pin goes entirely into the A-pin
  const V3 F{0, 0, -8e4};
  WheelLoader with_force(p);
  with_force.set_wrench([&](double) { return Wrench{F, {0, 0, 0}, A}; });
  // re-solve statics with the wrench in place
  with_force.resolve_static();
  const Dynamics d1 = with_force.dynamics();
  EXPECT_LT(norm(sub(d1.a_pin.point, A)), 1e-6);
  const V3 dA = sub(d1.a_pin.force, d0.a_pin.force);
  const V3 dJ = sub(d1.j_pin.force, d0.j_pin.force);
  std::printf("vertical force at A: dA = (%.3f %.3f %.3f) N, |dJ| = %.3e N\n", dA[0], dA[1], dA[2], norm(dJ));
  EXPECT_LT(norm(add(dA, F)), 1e-6 * norm(F));
  EXPECT_LT(norm(dJ), 1e-6 * norm(F));

  // (2) a pure torque about y is carried by the tilt link alone (the A-pin has no moment
  // capacity about its axis): the change in J force along the link times its arm about A
  const V3 T{0, 2e4, 0};
  WheelLoader with_torque(p);
  with_torque.set_wrench([&](double) { return Wrench{{0, 0, 0}, T, {5, 0, 5}}; });
  with_torque.resolve_static();
  const Dynamics d2 = with_torque.dynamics();
  const V3 dJ2 = sub(d2.j_pin.force, d0.j_pin.force);
  const V3 dA2 = sub(d2.a_pin.force, d0.a_pin.force);
  const V3 m = moment(d2.j_pin.point, dJ2, A);
  EXPECT_NEAR(m[1], -T[1], 1e-6 * T[1]);
  EXPECT_LT(norm(add(dA2, dJ2)), 1e-6 * norm(dJ2));  // a couple: the pins' changes cancel

  // (3) a force about a reference point r equals the same force about the origin plus the
  // transferred moment (r - origin) x F: identical reactions
  const V3 F3{-5e4, 0, 2e4};
  const V3 r{8.0, 0.0, 1.5};
  const V3 T3{0, 1e4, 0};
  WheelLoader at_r(p), at_origin(p);
  at_r.set_wrench([&](double) { return Wrench{F3, T3, r}; });
  at_origin.set_wrench([&](double) { return Wrench{F3, add(T3, cross(sub(r, A), F3)), A}; });
  at_r.resolve_static();
  at_origin.resolve_static();
  const Reports ra = at_r.reports(), rb = at_origin.reports();
  EXPECT_NEAR(ra.a_long, rb.a_long, 1e-6 * norm(F3));
  EXPECT_NEAR(ra.a_vert, rb.a_vert, 1e-6 * norm(F3));
  EXPECT_NEAR(ra.j_long, rb.j_long, 1e-6 * norm(F3));
  EXPECT_NEAR(ra.j_vert, rb.j_vert, 1e-6 * norm(F3));
  // and it matters: the same force about the origin without the transfer differs
  WheelLoader naive(p);
  naive.set_wrench([&](double) { return Wrench{F3, T3, A}; });
  naive.resolve_static();
  EXPECT_GT(std::abs(naive.reports().j_long - ra.j_long), 1e3);
}

// Traction limit: the drive force never exceeds mu * normal load; a resistance above it
// stops the machine (and pushes it back), one below it only slows it, to the speed the
// controller's gain predicts.
TEST(wheel_loader_model, TractionLimitStallsTheMachine) {
  Parameters p;
  p.maneuver.speed.knots = {{0, 1.2}};
  p.maneuver.lift.knots = {{0, 0}};
  p.maneuver.tilt.knots = {{0, 0}};
  for (double resistance : {1.0e5, 2.5e5}) {
    WheelLoader wl(p);
    const V3 A = wl.bucket().position;
    wl.set_wrench([&](double) { return Wrench{{-resistance, 0, 0}, {0, 0, 0}, A}; });
    double worst_ratio = 0, min_speed = 1e9;
    wl.advance(1.5, [&] {
      const Reports r = wl.reports();
      worst_ratio = std::max(worst_ratio, std::abs(r.drive_force) / (p.traction_coefficient * r.normal_load));
      min_speed = std::min(min_speed, r.speed);
    });
    const Reports r = wl.reports();
    const double limit = p.traction_coefficient * r.normal_load;
    std::printf("resistance %.0f N: speed %.3f m/s, drive %.0f N, limit %.0f N\n", resistance,
                r.speed, r.drive_force, limit);
    EXPECT_LE(worst_ratio, 1.0 + 1e-12);
    if (resistance > limit) {
      EXPECT_NEAR(r.drive_force, limit, 1e-9 * limit);  // saturated
      EXPECT_LT(min_speed, 0.0);                        // stalled and pushed back
    } else {
      // steady state of the speed controller: gain * M * (v_target - v) = resistance
      const double v = 1.2 - resistance / (p.speed_gain * wl.total_mass());
      EXPECT_NEAR(r.speed, v, 0.01 * v);
      EXPECT_NEAR(r.drive_force, resistance, 0.01 * resistance);
    }
  }
}
