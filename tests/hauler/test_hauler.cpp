// The hauler model driven directly (no bus): static axle loads with a rigid payload against a
// hand calculation, with the body lowered and tipped by 30 degrees; the hydraulic bogie
// sharing load; the parking brake holding a horizontal push.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "hauler.hpp"

using namespace hauler;

namespace {

constexpr double kPi = 3.14159265358979323846;

Parameters with_payload(double tip_deg) {
  Parameters p;
  p.test_payload = Load{39000, {2.6, 1.1}, 1.0};
  // lowered until 1 s, tipped to tip_deg by 5 s, held
  p.tipping.profile.knots = {{0, 0}, {1, 0}, {5, tip_deg}};
  return p;
}

// The hand calculation. Sprung part (front unit, rear frame, dump body, payload; one rigid
// body in pitch, the articulation turns only about z and x) on three struts along the chassis
// z axis at chassis x = x_f, x_1, x_2 (all axle centres on chassis z = 0), chassis pitched by
// theta (nose up), body tipped by phi about the hinge. In chassis axes:
//   along z:        F_f + F_1 + F_2 = W cos(theta)
//   moment, origin: F_f x_f + F_1 x_1 + F_2 x_2 = sum W_i (x_i cos(theta) - z_i sin(theta))
//   hydraulic bogie (one circuit, one pressure, equal pistons): F_1 = F_2
// Each axle (unsprung mass m_a) carries its strut: N = m_a g + F / cos(theta).
struct Hand {
  double N[3];
  double sprung_weight;
};

Hand hand_calc(const Parameters& p, double theta, double phi) {
  const double g = p.gravity;
  auto in_chassis = [&](const Vec2& b) {  // body frame -> chassis, body tipped by phi
    return Vec2{p.hinge[0] + std::cos(phi) * b[0] - std::sin(phi) * b[1],
                p.hinge[1] + std::sin(phi) * b[0] + std::cos(phi) * b[1]};
  };
  struct Item {
    double m;
    Vec2 at;
  };
  const Item items[] = {{p.front_unit.mass, p.front_unit.com},
                        {p.rear_frame.mass, p.rear_frame.com},
                        {p.dump_body.mass, in_chassis(p.dump_body.com)},
                        {p.test_payload->mass, in_chassis(p.test_payload->com)}};
  double W = 0, M = 0;
  for (const Item& it : items) {
    W += it.m * g;
    M += it.m * g * (it.at[0] * std::cos(theta) - it.at[1] * std::sin(theta));
  }
  const double xf = p.front_axle.x, x1 = p.rear1_axle.x, x2 = p.rear2_axle.x;
  const double Fr = (M - W * std::cos(theta) * xf) / (x1 + x2 - 2 * xf);
  const double Ff = W * std::cos(theta) - 2 * Fr;
  Hand h;
  h.sprung_weight = W;
  h.N[kFront] = p.front_axle.mass * g + Ff / std::cos(theta);
  h.N[kRear1] = p.rear1_axle.mass * g + Fr / std::cos(theta);
  h.N[kRear2] = p.rear2_axle.mass * g + Fr / std::cos(theta);
  return h;
}

void expect_axle_loads(const Hauler& h, const char* when) {
  const Reports r = h.reports();
  const Hand hand = hand_calc(h.parameters(), r.pitch, r.body_angle);
  const Hand level = hand_calc(h.parameters(), 0, r.body_angle);
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    const double N = r.axle[i].fz;
    sum += N;
    std::printf("%s: %-5s Fz %9.1f N, hand %9.1f N (%+.4f %%; level-chassis hand %+.3f %%), Fx %+8.1f N, "
                "stroke %.4f m\n",
                when, kAxleNames[i], N, hand.N[i], 100 * (N / hand.N[i] - 1),
                100 * (N / level.N[i] - 1), r.axle[i].fx, r.axle[i].stroke);
    EXPECT_NEAR(N / hand.N[i], 1.0, 0.005) << when << " " << kAxleNames[i];
  }
  std::printf("%s: pitch %.5f rad, body %.3f deg, pressures %.3f / %.3f MPa, hoist %.1f kN\n", when,
              r.pitch, r.body_angle * 180 / kPi, r.front.pressure / 1e6, r.rear.pressure / 1e6,
              r.hoist_force / 1e3);
  // the tires carry the whole machine; the bogie shares evenly (no stroke limit reached)
  EXPECT_NEAR(sum / (h.total_mass() * h.parameters().gravity), 1.0, 1e-4) << when;
  EXPECT_NEAR(r.axle[kRear1].fz / r.axle[kRear2].fz, 1.0, 1e-3) << when;
  for (int i = 0; i < 3; ++i) {
    EXPECT_GT(r.axle[i].stroke, 0.0) << when;
    EXPECT_LT(r.axle[i].stroke, h.parameters().suspension.stroke) << when;
  }
}

}  // namespace

// Statics do not depend on the integrator's step: 5e-4 s (stable, see the adapter test for
// the default) keeps the test fast.
TEST(hauler_model, StaticAxleLoadsMatchTheHandCalculationLoweredAndTipped) {
  Parameters p = with_payload(30);
  p.inner_step = 5e-4;
  Hauler h(p);
  EXPECT_LT(h.max_acceleration(), 1e-6);
  expect_axle_loads(h, "t=0 lowered");
  const Reports r0 = h.reports();
  h.advance(1.0);
  EXPECT_LT(h.max_acceleration(), 1e-3);
  expect_axle_loads(h, "t=1 lowered");
  h.advance(14.0);  // tipped by 5 s; the front strut extends, the level control drains it (to ~8.5 s)
  const Reports r1 = h.reports();
  std::printf("max |udot| at 14 s: %.2e\n", h.max_acceleration());
  EXPECT_NEAR(r1.body_angle, 30 * kPi / 180, 0.2 * kPi / 180);
  EXPECT_LT(h.max_acceleration(), 1e-3);
  expect_axle_loads(h, "t=14 tipped 30 deg");
  // the payload's centre of mass moves back over the hinge: the front axle loses what the
  // hand calculation says it loses
  const Hand a = hand_calc(p, r0.pitch, r0.body_angle), b = hand_calc(p, r1.pitch, r1.body_angle);
  const double dN = r1.axle[kFront].fz - r0.axle[kFront].fz;
  std::printf("front axle: %.1f -> %.1f N (hand change %.1f N)\n", r0.axle[kFront].fz,
              r1.axle[kFront].fz, b.N[kFront] - a.N[kFront]);
  EXPECT_LT(dN, -50e3);
  EXPECT_NEAR(dN / (b.N[kFront] - a.N[kFront]), 1.0, 0.01);
}

// A steady horizontal push on the body (the soil sliding out pulls the body backwards) is
// held by the parking brake: the tires' longitudinal forces (TYDEX C, on the machine) sum to
// the push's opposite and the machine creeps no more than the brake spring allows.
TEST(hauler_model, ParkingBrakeHoldsAHorizontalPush) {
  Parameters p = with_payload(0);
  p.inner_step = 5e-4;
  Hauler h(p);
  const V3 origin = h.body().position;
  const double push = -60e3;  // N, backwards
  // ramped in over 1 s (a step would ring the machine on its brake springs for seconds)
  h.set_wrench([&](double t) {
    const double s = std::min(t, 1.0);
    return Wrench{{push * s * s * (3 - 2 * s), 0, 0}, {0, 0, 0}, origin};
  });
  h.advance(6.0);
  const Reports r = h.reports();
  double fx = 0;
  for (const auto& a : r.axle) fx += a.fx;
  std::printf("push %.0f N: tire Fx %.1f / %.1f / %.1f N, sum %.1f N, machine moved %.4f m\n", push,
              r.axle[0].fx, r.axle[1].fx, r.axle[2].fx, fx, r.x_machine);
  EXPECT_NEAR(fx, -push, 5e-3 * std::abs(push));
  for (const auto& a : r.axle) EXPECT_GT(a.fx, 0);
  EXPECT_LT(std::abs(r.x_machine), 3 * std::abs(push) / (3 * p.brake.stiffness));
}

// Three ways to put 39 t at (2.6, 1.1) in the body give one static state: the rigid payload,
// the static start's assumed soil load (static_load), and the soil's weight as a body wrench
// with resolve_static (the DEM side's ways to start levelled and at rest under its payload).
TEST(hauler_model, StaticLoadWrenchAndRigidPayloadAgree) {
  const Parameters rigid = with_payload(0);
  Parameters assumed = rigid;
  assumed.test_payload.reset();
  assumed.static_load = Load{39000, {2.6, 1.1}, 1.0};
  Parameters empty = assumed;
  empty.static_load = Load{};
  Hauler a(rigid), b(assumed), c(empty);
  // the wrench's point is a ground point: the body settles lower and less nose-down under the
  // load, so the point is moved with the body and the statics solved again until it stays
  V3 point = c.coupled_point({2.6, 0, 1.1});
  c.set_wrench([&](double) { return Wrench{{0, 0, -39000 * 9.81}, {0, 0, 0}, point}; });
  for (int i = 0; i < 4; ++i) {
    c.resolve_static();
    point = c.coupled_point({2.6, 0, 1.1});
  }
  const Reports ra = a.reports(), rb = b.reports(), rc = c.reports();
  for (int i = 0; i < 3; ++i) {
    std::printf("%-5s Fz: rigid %.1f, static_load %.1f, wrench %.1f N; stroke %.4f %.4f %.4f m\n",
                kAxleNames[i], ra.axle[i].fz, rb.axle[i].fz, rc.axle[i].fz, ra.axle[i].stroke,
                rb.axle[i].stroke, rc.axle[i].stroke);
    EXPECT_NEAR(rb.axle[i].fz / ra.axle[i].fz, 1.0, 1e-9) << kAxleNames[i];
    EXPECT_NEAR(rc.axle[i].fz / ra.axle[i].fz, 1.0, 1e-6) << kAxleNames[i];
    EXPECT_NEAR(rc.axle[i].stroke, ra.axle[i].stroke, 1e-6) << kAxleNames[i];
  }
  EXPECT_NEAR(rb.rear.oil, ra.rear.oil, 1e-12);
  EXPECT_LT(c.max_acceleration(), 1e-6);
  // at rest it stays (brake anchored where it stands, level control inside its band)
  c.advance(0.5);
  EXPECT_LT(c.max_acceleration(), 1e-4);
}
