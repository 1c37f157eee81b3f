#include "hauler.hpp"

#include <Simbody.h>

#include "simbody_machine.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "tydex.hpp"

namespace hauler {

using namespace SimTK;
using mbs::mass_properties;
using mbs::pin_axes;  // positive angles turn x towards z: chassis nose up, body front up
using mbs::to_array;
using mbs::xz;

namespace {

const double kDeg = Pi / 180;

// A slider moves along its mobilizer frames' x; this rotation puts that x along the parent's z.
Rotation slider_axes() { return Rotation(-Pi / 2, YAxis); }

// The dump body with the rigid test payload, if any, as one rigid body (body frame).
MassProperties body_mass_properties(const Parameters& p) {
  const SimTK::Vec3 cb = xz(p.dump_body.com);
  const Inertia Ib = Inertia(SimTK::Vec3(p.dump_body.inertia[0], p.dump_body.inertia[1],
                                         p.dump_body.inertia[2]))
                         .shiftFromMassCenter(cb, p.dump_body.mass);
  if (!p.test_payload) return MassProperties(p.dump_body.mass, cb, Ib);
  const Load& l = *p.test_payload;
  const SimTK::Vec3 cl = xz(l.com);
  const double r2 = l.gyration_radius * l.gyration_radius;
  const Inertia Il = Inertia(SimTK::Vec3(l.mass * r2)).shiftFromMassCenter(cl, l.mass);
  const double m = p.dump_body.mass + l.mass;
  return MassProperties(m, (p.dump_body.mass * cb + l.mass * cl) / m, Ib + Il);
}

double gas_pressure(const Circuit& c, double gas_volume) {
  // bounded away from a collapsed gas volume so a wild state stays finite (the end stops keep
  // real states far from it)
  const double v = std::max(gas_volume, 0.02 * c.accumulator_volume);
  return c.precharge * std::pow(c.accumulator_volume / v, c.polytropic);
}

// ---------------------------------------------------------------------------------------
// Hydro-pneumatic struts and their circuits.

struct StrutGeom {
  MobilizedBody upper, lower;       // chassis and axle (the rig: mass and ground)
  SimTK::Vec3 at_upper, at_lower;   // stations on the strut line
};

struct CircuitGeom {
  const Circuit* circuit = nullptr;
  std::vector<StrutGeom> struts;
};

struct StrutEval {
  double stroke = 0, rate = 0, force = 0, end_stop = 0;
  SimTK::Vec3 axis{0};  // the upper body's z in ground: the strut's line
};

struct CircuitEval {
  double gas_volume = 0, pressure = 0, oil = 0, ride = 0, ride_filtered = 0, flow = 0;
  std::vector<StrutEval> struts;
};

// Strut i of a circuit: stroke s = ride_stroke + axis . (upper point - lower point), so s =
// ride_stroke where the two stations coincide; rate = axis . (their velocity difference).
// Force along the line, + pushing apart: gas p A, orifice -c2 v|v| - c1 v, end stops
// k (0 - s) - d v below 0 and -(k (s - stroke) + d v) beyond the stroke (never pulling into
// the stop). Gas volume of the circuit: V_acc - oil + A sum(s_i).
class StrutForces : public Force::Custom::Implementation {
 public:
  StrutForces(const Suspension& s, const GeneralForceSubsystem& forces, std::vector<CircuitGeom> c)
      : s_(s), forces_(forces), circuits_(std::move(c)) {}

  void realizeTopology(State& state) const override {
    z_.clear();
    for (std::size_t i = 0; i < circuits_.size(); ++i)
      z_.push_back(forces_.allocateZ(state, Vector(2, 0.0)));  // [oil, filtered ride height]
  }

  double oil(const State& s, int c) const { return forces_.getZ(s)[z_[c]]; }
  double ride_filtered(const State& s, int c) const { return forces_.getZ(s)[z_[c] + 1]; }
  void set_oil(State& s, int c, double v) const { forces_.updZ(s)[z_[c]] = v; }
  void set_ride_filtered(State& s, int c, double v) const { forces_.updZ(s)[z_[c] + 1] = v; }
  int size() const { return static_cast<int>(circuits_.size()); }

  CircuitEval evaluate(const State& st, int ci) const {
    const CircuitGeom& g = circuits_[ci];
    const Circuit& c = *g.circuit;
    CircuitEval e;
    double sum = 0;
    for (const StrutGeom& sg : g.struts) {
      StrutEval se;
      se.axis = sg.upper.getBodyRotation(st).z().asVec3();
      const SimTK::Vec3 d = sg.upper.findStationLocationInGround(st, sg.at_upper) -
                            sg.lower.findStationLocationInGround(st, sg.at_lower);
      const SimTK::Vec3 dv = sg.upper.findStationVelocityInGround(st, sg.at_upper) -
                             sg.lower.findStationVelocityInGround(st, sg.at_lower);
      se.stroke = s_.ride_stroke + ~se.axis * d;
      se.rate = ~se.axis * dv;
      sum += se.stroke;
      e.struts.push_back(se);
    }
    e.oil = oil(st, ci);
    e.gas_volume = c.accumulator_volume - e.oil + c.piston_area * sum;
    e.pressure = gas_pressure(c, e.gas_volume);
    e.ride = sum / static_cast<double>(g.struts.size());
    e.ride_filtered = ride_filtered(st, ci);
    if (s_.level_control && c.level_rate > 0) {
      const double err = e.ride_filtered - s_.ride_stroke;
      e.flow = err < -s_.dead_band ? c.level_rate : err > s_.dead_band ? -c.level_rate : 0.0;
    }
    for (StrutEval& se : e.struts) {
      const double v = se.rate;
      double stop = 0;
      if (se.stroke < 0) stop = std::max(0.0, -s_.end_stop_stiffness * se.stroke - s_.end_stop_damping * v);
      else if (se.stroke > s_.stroke)
        stop = std::min(0.0, -s_.end_stop_stiffness * (se.stroke - s_.stroke) - s_.end_stop_damping * v);
      se.end_stop = stop;
      se.force = e.pressure * c.piston_area - c.damping_quadratic * v * std::abs(v) -
                 c.damping_linear * v + stop;
    }
    return e;
  }

  void calcForce(const State& st, Vector_<SpatialVec>& body, Vector_<SimTK::Vec3>&,
                 Vector&) const override {
    for (int ci = 0; ci < size(); ++ci) {
      const CircuitEval e = evaluate(st, ci);
      for (std::size_t j = 0; j < e.struts.size(); ++j) {
        const StrutGeom& sg = circuits_[ci].struts[j];
        const SimTK::Vec3 F = e.struts[j].force * e.struts[j].axis;
        sg.upper.applyForceToBodyPoint(st, sg.at_upper, F, body);
        sg.lower.applyForceToBodyPoint(st, sg.at_lower, -F, body);
      }
    }
  }

  void realizeAcceleration(const State& st) const override {
    Vector& zdot = forces_.updZDot(st);
    for (int ci = 0; ci < size(); ++ci) {
      const CircuitEval e = evaluate(st, ci);
      zdot[z_[ci]] = e.flow;
      zdot[z_[ci] + 1] = (e.ride - e.ride_filtered) / s_.time_constant;
    }
  }

  Real calcPotentialEnergy(const State&) const override { return 0; }

 private:
  const Suspension& s_;
  const GeneralForceSubsystem& forces_;
  std::vector<CircuitGeom> circuits_;
  mutable std::vector<ZIndex> z_;
};

}  // namespace

// ---------------------------------------------------------------------------------------
// The hauler.

struct HaulerImpl : mbs::Machine::Simbody {
  MobilizedBody::Planar chassis;  // the front unit
  MobilizedBody::Weld rear;       // the rear frame
  MobilizedBody::Slider axle[3];
  MobilizedBody::Pin body;
  const StrutForces* struts = nullptr;
  SimTK::Vec3 hoist_frame, hoist_body;  // rear frame (chassis coordinates), body frame
  double total_mass = 0;
  bool static_solve = false;
  bool with_static_load = false;  // during the solve: static_load on the body
  double anchor_x[3] = {0, 0, 0}, anchor_pitch = 0;

  struct Tire {
    double N = 0, Fx = 0, deflection = 0;
    SimTK::Vec3 centre{0};
  };
  struct ForceState {
    Tire tire[3];
    double hoist_length = 0, hoist_rate = 0, hoist_target = 0, hoist_target_rate = 0, hoist_force = 0;
  };
  ForceState force_state(const Parameters& p, const Hauler& h, const State& s) const;
  void solve_static(const Parameters& p, const Hauler& h, State& s, bool static_load);
};

namespace {

class MachineForces : public Force::Custom::Implementation {
 public:
  MachineForces(const Parameters& p, const Hauler& h, const HaulerImpl& m) : p_(p), h_(h), m_(m) {}
  void calcForce(const State& s, Vector_<SpatialVec>& body, Vector_<SimTK::Vec3>&,
                 Vector&) const override {
    const auto f = m_.force_state(p_, h_, s);
    for (int i = 0; i < 3; ++i) {
      const auto& t = f.tire[i];
      if (t.N <= 0) continue;
      m_.axle[i].applyForceToBodyPoint(s, SimTK::Vec3(0), SimTK::Vec3(0, 0, t.N), body);
      if (t.Fx != 0) {
        const SimTK::Vec3 contact(t.centre[0], t.centre[1], 0);
        m_.axle[i].applyForceToBodyPoint(s, m_.axle[i].findStationAtGroundPoint(s, contact),
                                         SimTK::Vec3(t.Fx, 0, 0), body);
      }
    }
    // the hoist pushes the body pin away from the frame pin with a positive force
    const SimTK::Vec3 b = m_.body.findStationLocationInGround(s, m_.hoist_body);
    const SimTK::Vec3 a = m_.rear.findStationLocationInGround(s, m_.hoist_frame);
    const SimTK::Vec3 F = f.hoist_force * (b - a) / (b - a).norm();
    m_.body.applyForceToBodyPoint(s, m_.hoist_body, F, body);
    m_.rear.applyForceToBodyPoint(s, m_.hoist_frame, -F, body);
    // the static start's assumed soil load: its weight on a body point
    if (m_.static_solve && m_.with_static_load && p_.static_load.mass > 0)
      m_.body.applyForceToBodyPoint(s, xz(p_.static_load.com),
                                    SimTK::Vec3(0, 0, -p_.static_load.mass * p_.gravity), body);
  }
  Real calcPotentialEnergy(const State&) const override { return 0; }

 private:
  const Parameters& p_;
  const Hauler& h_;
  const HaulerImpl& m_;
};

}  // namespace

HaulerImpl::ForceState HaulerImpl::force_state(const Parameters& p, const Hauler& h,
                                                   const State& s) const {
  ForceState f;
  const double pitch = chassis.getQ(s)[0];
  const double pitch_rate = chassis.getU(s)[0];
  for (int i = 0; i < 3; ++i) {
    Tire& t = f.tire[i];
    t.centre = axle[i].getBodyOriginLocation(s);
    const SimTK::Vec3 v = axle[i].getBodyOriginVelocity(s);
    t.deflection = p.tires.unloaded_radius - t.centre[2];
    t.N = t.deflection > 0 ? std::max(0.0, p.tires.stiffness * t.deflection - p.tires.damping * v[2]) : 0.0;
    if (p.brake.applied && !static_solve && t.N > 0) {
      // the locked wheel's contact point: centre motion plus the axle's pitch times the lever
      const double slip = t.centre[0] - anchor_x[i] + p.brake.rolling_radius * (pitch - anchor_pitch);
      const double slip_rate = v[0] + p.brake.rolling_radius * pitch_rate;
      const double cap = p.brake.friction * t.N;
      t.Fx = std::clamp(-p.brake.stiffness * slip - p.brake.damping * slip_rate, -cap, cap);
    }
  }
  const SimTK::Vec3 b = body.findStationLocationInGround(s, hoist_body);
  const SimTK::Vec3 a = rear.findStationLocationInGround(s, hoist_frame);
  const SimTK::Vec3 d = b - a;
  const SimTK::Vec3 dv = body.findStationVelocityInGround(s, hoist_body) -
                         rear.findStationVelocityInGround(s, hoist_frame);
  f.hoist_length = d.norm();
  f.hoist_rate = ~dv * d / f.hoist_length;
  const double t = s.getTime();
  const Tipping& tp = p.tipping;
  if (tp.by_length) {
    f.hoist_target = tp.profile.value(t, tp.smooth);
    f.hoist_target_rate = tp.profile.rate(t, tp.smooth);
  } else {
    const double phi = tp.profile.value(t, tp.smooth) * kDeg;
    const double dphi = tp.profile.rate(t, tp.smooth) * kDeg;
    f.hoist_target = h.hoist_length_at(phi);
    f.hoist_target_rate = (h.hoist_length_at(phi + 1e-6) - h.hoist_length_at(phi - 1e-6)) / 2e-6 * dphi;
  }
  f.hoist_force = p.hoist.stiffness * (f.hoist_target - f.hoist_length) +
                  p.hoist.damping * (f.hoist_target_rate - f.hoist_rate);
  return f;
}

double Hauler::hoist_length_at(double phi) const {
  const Vec2& bp = p_.hoist.body_pin;
  const double c = std::cos(phi), s = std::sin(phi);
  const double bx = p_.hinge[0] + c * bp[0] - s * bp[1];
  const double bz = p_.hinge[1] + s * bp[0] + c * bp[1];
  return std::hypot(bx - p_.hoist.frame_pin[0], bz - p_.hoist.frame_pin[1]);
}

double Hauler::target_angle(double t) const {
  const Tipping& tp = p_.tipping;
  if (!tp.by_length) return tp.profile.value(t, tp.smooth) * kDeg;
  // invert the (monotone, checked in the constructor) length of the body angle
  const double L = tp.profile.value(t, tp.smooth);
  double lo = 0, hi = 80 * kDeg;
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    (hoist_length_at(mid) < L ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

Hauler::Hauler(const Parameters& p, double t_start)
    : MachineOf("hauler", p, std::make_unique<HaulerImpl>()) {
  HaulerImpl& P = impl();
  const Rotation R = pin_axes();
  // the hoist must lengthen as the body tips, and be a real cylinder at every angle
  {
    double last = hoist_length_at(0);
    if (last < 0.2)
      throw std::invalid_argument("hoist: frame_pin and body_pin are " + std::to_string(last) +
                                  " m apart with the body lowered (at least 0.2 m)");
    for (int deg = 1; deg <= 80; ++deg) {
      const double L = hoist_length_at(deg * kDeg);
      if (!(L > last))
        throw std::invalid_argument(
            "hoist: the cylinder does not lengthen monotonically as the body tips (at " +
            std::to_string(deg) + " deg): move hoist.frame_pin forward/below or hoist.body_pin "
            "ahead of the hinge");
      last = L;
    }
    if (p.tipping.by_length)
      for (std::size_t i = 0; i < p.tipping.profile.knots.size(); ++i) {
        const double L = p.tipping.profile.knots[i][1];
        if (L < hoist_length_at(0) - 1e-9 || L > hoist_length_at(80 * kDeg))
          throw std::invalid_argument("tipping.length." + std::to_string(i) + ": " + std::to_string(L) +
                                      " m is outside the hoist's range " +
                                      std::to_string(hoist_length_at(0)) + " (lowered) .. " +
                                      std::to_string(hoist_length_at(80 * kDeg)) + " m (80 deg)");
      }
  }
  Force::UniformGravity(P.forces, P.matter, SimTK::Vec3(0, 0, -p_.gravity));

  P.chassis = MobilizedBody::Planar(
      P.matter.Ground(), Transform(R, SimTK::Vec3(0)),
      SimTK::Body::Rigid(mass_properties(p.front_unit.mass, xz(p.front_unit.com), p.front_unit.inertia)),
      Transform(R, SimTK::Vec3(0)));
  P.rear = MobilizedBody::Weld(
      P.chassis, Transform(),
      SimTK::Body::Rigid(mass_properties(p.rear_frame.mass, xz(p.rear_frame.com), p.rear_frame.inertia)),
      Transform());
  const Rotation S = slider_axes();
  for (int i = 0; i < 3; ++i) {
    const Axle& a = p.axle(i);
    MobilizedBody& parent = i == kFront ? static_cast<MobilizedBody&>(P.chassis)
                                        : static_cast<MobilizedBody&>(P.rear);
    P.axle[i] = MobilizedBody::Slider(
        parent, Transform(S, SimTK::Vec3(a.x, 0, 0)),
        SimTK::Body::Rigid(mass_properties(a.mass, SimTK::Vec3(0), a.inertia)),
        Transform(S, SimTK::Vec3(0)));
  }
  P.body = MobilizedBody::Pin(P.rear, Transform(R, xz(p.hinge)),
                              SimTK::Body::Rigid(body_mass_properties(p)), Transform(R, SimTK::Vec3(0)));
  P.hoist_frame = xz(p.hoist.frame_pin);
  P.hoist_body = xz(p.hoist.body_pin);
  P.total_mass = p.front_unit.mass + p.rear_frame.mass + p.dump_body.mass + p.front_axle.mass +
                 p.rear1_axle.mass + p.rear2_axle.mass + (p.test_payload ? p.test_payload->mass : 0.0);

  auto strut = [&](int i) {
    const MobilizedBody& upper = i == kFront ? static_cast<const MobilizedBody&>(P.chassis)
                                             : static_cast<const MobilizedBody&>(P.rear);
    return StrutGeom{upper, P.axle[i], SimTK::Vec3(p.axle(i).x, 0, 0), SimTK::Vec3(0)};
  };
  std::vector<CircuitGeom> circuits{{&p_.suspension.front, {strut(kFront)}},
                                    {&p_.suspension.rear, {strut(kRear1), strut(kRear2)}}};
  auto* struts = new StrutForces(p_.suspension, P.forces, std::move(circuits));
  P.struts = struts;
  Force::Custom(P.forces, struts);
  Force::Custom(P.forces, new MachineForces(p_, *this, P));
  P.couple(*this, P.body);

  State& s = P.state;
  s = P.system.realizeTopology();
  s.setTime(t_start);
  P.solve_static(p_, *this, s, true);

  P.make_integrator(p.inner_step);
}

// Static equilibrium by Newton's method on chassis pitch and height, the three axle slides,
// the body angle and the two circuits' oil, with the brake off and the machine at rest:
// the six generalized accelerations vanish and each circuit's ride height is at ride_stroke
// (the front strut's slide is 0, the rear struts' mean slide is 0). Finite-difference
// Jacobian with a trust region and backtracking.
void HaulerImpl::solve_static(const Parameters& p, const Hauler& h, State& s, bool static_load) {
  static_solve = true;
  with_static_load = static_load;
  const auto& sus = p.suspension;
  const double t = s.getTime();
  s.updU() = 0;
  system.realize(s, Stage::Position);
  // a start: tires deflected under a third of the machine each, struts at ride height, the
  // oil for that load by the gas law
  const double W = (total_mass + (static_load ? p.static_load.mass : 0.0)) * p.gravity;
  const double deflection = W / (3 * p.tires.stiffness);
  auto oil_for = [&](const Circuit& c, int n, double force) {
    return StrutRig::oil_for(c, force, sus.ride_stroke) + (n - 1) * c.piston_area * sus.ride_stroke;
  };
  SimTK::Vector y(8, 0.0);
  y[1] = p.tires.unloaded_radius - deflection;
  y[5] = h.target_angle(t);
  y[6] = oil_for(sus.front, 1, W / 3);
  y[7] = oil_for(sus.rear, 2, W / 3);
  auto residual = [&](const SimTK::Vector& v) {
    chassis.setQ(s, SimTK::Vec3(v[0], p.initial_position, v[1]));
    for (int i = 0; i < 3; ++i) axle[i].setOneQ(s, 0, v[2 + i]);
    body.setOneQ(s, 0, v[5]);
    struts->set_oil(s, 0, v[6]);
    struts->set_oil(s, 1, v[7]);
    system.realize(s, Stage::Acceleration);
    SimTK::Vector r(8);
    r[0] = chassis.getUDot(s)[0];
    r[1] = chassis.getUDot(s)[2];
    for (int i = 0; i < 3; ++i) r[2 + i] = axle[i].getOneUDot(s, 0);
    r[5] = body.getOneUDot(s, 0);
    r[6] = v[2];
    r[7] = 0.5 * (v[3] + v[4]);
    return r;
  };
  const SimTK::Vector r = mbs::solve_newton(
      residual, y, {80, 1e-11, {1e-7, 1e-7, 1e-7, 1e-7, 1e-7, 1e-7, 1e-10, 1e-10},
                    {0.05, 0.05, 0.05, 0.05, 0.05, 0.05, 2e-3, 2e-3}});
  static_solve = false;
  if (!(r.normInf() < 1e-6))
    throw std::runtime_error("hauler: no static equilibrium found at t_start (residual " +
                             std::to_string(r.normInf()) +
                             "): check masses, stiffnesses, the circuits' precharge and the tipping "
                             "profile at t_start");
  for (int c = 0; c < 2; ++c) struts->set_ride_filtered(s, c, struts->evaluate(s, c).ride);
  for (int i = 0; i < 3; ++i) anchor_x[i] = axle[i].getBodyOriginLocation(s)[0];
  anchor_pitch = chassis.getQ(s)[0];
  system.realize(s, Stage::Acceleration);
}

double Hauler::total_mass() const { return impl().total_mass; }

void Hauler::resolve_static() { impl().solve_static(p_, *this, impl().state, false); }

Reports Hauler::reports() const {
  const HaulerImpl& P = impl();
  const State& s = P.state;
  P.system.realize(s, Stage::Acceleration);
  Reports r;
  const auto f = P.force_state(p_, *this, s);
  const CircuitEval ce[2] = {P.struts->evaluate(s, 0), P.struts->evaluate(s, 1)};
  const StrutEval* se[3] = {&ce[0].struts[0], &ce[1].struts[0], &ce[1].struts[1]};
  for (int i = 0; i < 3; ++i) {
    AxleReport& a = r.axle[i];
    const SimTK::Vec3 spin = P.axle[i].getBodyRotation(s).y().asVec3();
    const Dir3 F = tydex_c(to_array(spin), {0, 0, 1}, {f.tire[i].Fx, 0, f.tire[i].N});
    a.fx = F[0];
    a.fy = F[1];
    a.fz = F[2];
    a.stroke = se[i]->stroke;
    a.stroke_rate = se[i]->rate;
    a.strut_force = se[i]->force;
    a.end_stop = se[i]->end_stop;
    a.deflection = f.tire[i].deflection;
    a.centre = to_array(f.tire[i].centre);
  }
  for (int c = 0; c < 2; ++c) {
    CircuitReport& cr = c == 0 ? r.front : r.rear;
    cr.pressure = ce[c].pressure;
    cr.gas_volume = ce[c].gas_volume;
    cr.oil = ce[c].oil;
    cr.ride = ce[c].ride;
    cr.ride_filtered = ce[c].ride_filtered;
    cr.flow = ce[c].flow;
  }
  r.hoist_force = f.hoist_force;
  r.hoist_length = f.hoist_length;
  r.hoist_target = f.hoist_target;
  r.body_angle = P.body.getOneQ(s, 0);
  r.pitch = P.chassis.getQ(s)[0];
  r.heave = P.chassis.getBodyOriginLocation(s)[2];
  r.x_machine = P.chassis.getBodyOriginLocation(s)[0];
  r.speed = P.chassis.getBodyOriginVelocity(s)[0];
  r.kinetic_energy = P.system.calcKineticEnergy(s);
  return r;
}

// ---------------------------------------------------------------------------------------
// The strut rig.

struct StrutRig::Impl : mbs::Machine::Simbody {
  Suspension suspension;
  Circuit circuit;
  MobilizedBody::Slider mass;
  const StrutForces* strut = nullptr;
  std::function<double(double)> load;
  double h = 2e-4;
};

namespace {
class RigLoad : public Force::Custom::Implementation {
 public:
  explicit RigLoad(const StrutRig::Impl& r) : r_(r) {}
  void calcForce(const State& s, Vector_<SpatialVec>& body, Vector_<SimTK::Vec3>&,
                 Vector&) const override {
    if (r_.load)
      r_.mass.applyForceToBodyPoint(s, SimTK::Vec3(0), SimTK::Vec3(0, 0, -r_.load(s.getTime())), body);
  }
  Real calcPotentialEnergy(const State&) const override { return 0; }

 private:
  const StrutRig::Impl& r_;
};
}  // namespace

double StrutRig::oil_for(const Circuit& c, double force, double stroke) {
  const double p = force / c.piston_area;
  const double gas = c.accumulator_volume * std::pow(c.precharge / p, 1 / c.polytropic);
  return c.accumulator_volume - gas + c.piston_area * stroke;
}

StrutRig::StrutRig(const Suspension& suspension, const Circuit& circuit, double mass, double gravity,
                   double oil, double inner_step)
    : impl_(new Impl) {
  Impl& R = *impl_;
  R.suspension = suspension;
  R.circuit = circuit;
  R.h = inner_step;
  Force::UniformGravity(R.forces, R.matter, SimTK::Vec3(0, 0, -gravity));
  R.mass = MobilizedBody::Slider(R.matter.Ground(), Transform(slider_axes(), SimTK::Vec3(0)),
                                 SimTK::Body::Rigid(MassProperties(mass, SimTK::Vec3(0), Inertia(1))),
                                 Transform(slider_axes(), SimTK::Vec3(0)));
  std::vector<CircuitGeom> circuits{
      {&R.circuit, {StrutGeom{R.mass, R.matter.Ground(), SimTK::Vec3(0), SimTK::Vec3(0)}}}};
  auto* strut = new StrutForces(R.suspension, R.forces, std::move(circuits));
  R.strut = strut;
  Force::Custom(R.forces, strut);
  Force::Custom(R.forces, new RigLoad(R));
  State& s = R.state;
  s = R.system.realizeTopology();
  R.system.realize(s, Stage::Position);
  strut->set_oil(s, 0, oil);
  // equilibrium under the weight: the static strut force falls with the stroke; bisect
  const double W = mass * gravity;
  auto excess = [&](double stroke) {
    R.mass.setOneQ(s, 0, stroke - suspension.ride_stroke);
    R.system.realize(s, Stage::Velocity);
    return strut->evaluate(s, 0).struts[0].force - W;
  };
  double lo = -0.5, hi = suspension.stroke + 0.5;
  if (!(excess(lo) > 0 && excess(hi) < 0))
    throw std::invalid_argument("StrutRig: no equilibrium within the stroke +-0.5 m");
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (excess(mid) > 0 ? lo : hi) = mid;
  }
  excess(0.5 * (lo + hi));
  strut->set_ride_filtered(s, 0, strut->evaluate(s, 0).ride);
  R.system.realize(s, Stage::Acceleration);
  R.make_integrator(inner_step);
}

StrutRig::~StrutRig() = default;

void StrutRig::set_load(std::function<double(double)> load) {
  impl_->load = std::move(load);
  impl_->state.invalidateAllCacheAtOrAbove(Stage::Dynamics);
}

double StrutRig::time() const { return impl_->state.getTime(); }

void StrutRig::advance(double t_end) { mbs::advance_fixed(*impl_->integrator, impl_->state, impl_->h, t_end); }

RigState StrutRig::state() const {
  const Impl& R = *impl_;
  R.system.realize(R.state, Stage::Acceleration);
  const CircuitEval e = R.strut->evaluate(R.state, 0);
  RigState r;
  r.stroke = e.struts[0].stroke;
  r.stroke_rate = e.struts[0].rate;
  r.pressure = e.pressure;
  r.oil = e.oil;
  r.ride_filtered = e.ride_filtered;
  r.flow = e.flow;
  r.strut_force = e.struts[0].force;
  r.end_stop = e.struts[0].end_stop;
  return r;
}

}  // namespace hauler
