#include "wheel_loader.hpp"

#include <Simbody.h>

#include "simbody_machine.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace wheel_loader {

using namespace SimTK;
using mbs::pin_axes;
using mbs::to_array;
using mbs::xz;

struct WheelLoaderImpl : mbs::Machine::Simbody {
  MobilizedBody::Planar frame;
  MobilizedBody::Pin boom, bucket, crank, link;
  Constraint::PointOnLine j_pin;
  // stations in body frames
  SimTK::Vec3 lift_frame, lift_boom, tilt_frame, tilt_crank;
  SimTK::Vec3 link_j;                 // J end of the link, link frame
  SimTK::Vec3 front_axle, rear_axle;  // frame
  double lift_design = 0, tilt_design = 0;  // design-pose cylinder lengths
  double total_mass = 0;
  bool drive_off = false;  // during the static solve
  // loop closure in the boom frame's x-z plane (design-pose coordinates, boom pivot origin)
  SimTK::Vec2 A_b, C_b, D0_b, J0_b;
  double branch = 1;  // side of line A-D on which J lies

  // Sets the pins from boom and bell-crank angles; link and bucket follow from the loop.
  void set_linkage(State& s, double boom_angle, double crank_angle) const;
  void solve_static(const Parameters& p, State& s);

  struct ForceState {
    double lift_force, tilt_force, lift_length, tilt_length;
    double drive_force, normal_load, normal_front, normal_rear;
  };
  ForceState force_state(const Parameters& p, const State& s) const;
};

namespace {

SimTK::Vec3 xz_minus(const Vec2& a, const Vec2& b) { return xz({a[0] - b[0], a[1] - b[1]}); }

MassProperties mass_properties(const wheel_loader::Body& b, const SimTK::Vec3& com) {
  return mbs::mass_properties(b.mass, com, b.inertia);
}

double cross2(const SimTK::Vec2& a, const SimTK::Vec2& b) { return a[0] * b[1] - a[1] * b[0]; }
double angle2(const SimTK::Vec2& a) { return std::atan2(a[1], a[0]); }
// turns x towards z by angle
SimTK::Vec2 rot2(double angle, const SimTK::Vec2& a) {
  const double c = std::cos(angle), s = std::sin(angle);
  return SimTK::Vec2(c * a[0] - s * a[1], s * a[0] + c * a[1]);
}

// Lift and tilt cylinders, tires and drive: everything the machine does to itself.
class MachineForces : public Force::Custom::Implementation {
 public:
  MachineForces(const Parameters& p, const WheelLoaderImpl& m) : p_(p), m_(m) {}
  void calcForce(const State& s, Vector_<SpatialVec>& body, Vector_<SimTK::Vec3>&,
                 Vector&) const override;
  Real calcPotentialEnergy(const State& s) const override;

 private:
  const Parameters& p_;
  const WheelLoaderImpl& m_;
};

struct CylinderState {
  double length, force;
};

CylinderState cylinder(const State& s, const MobilizedBody& frame, const SimTK::Vec3& at_frame,
                       const MobilizedBody& body, const SimTK::Vec3& at_body, const Cylinder& c,
                       double target, double target_rate) {
  const SimTK::Vec3 d = body.findStationLocationInGround(s, at_body) -
                        frame.findStationLocationInGround(s, at_frame);
  const SimTK::Vec3 dv = body.findStationVelocityInGround(s, at_body) -
                         frame.findStationVelocityInGround(s, at_frame);
  const double L = d.norm();
  const double rate = ~dv * d / L;
  return {L, c.stiffness * (target - L) + c.damping * (target_rate - rate)};
}

}  // namespace

WheelLoaderImpl::ForceState WheelLoaderImpl::force_state(const Parameters& p,
                                                             const State& s) const {
  const double t = s.getTime();
  const auto& m = p.maneuver;
  ForceState f{};
  const auto lift = cylinder(s, frame, lift_frame, boom, lift_boom, p.lift_cylinder,
                             lift_design + m.lift.value(t, m.smooth), m.lift.rate(t, m.smooth));
  const auto tilt = cylinder(s, frame, tilt_frame, crank, tilt_crank, p.tilt_cylinder,
                             tilt_design + m.tilt.value(t, m.smooth), m.tilt.rate(t, m.smooth));
  f.lift_force = lift.force;
  f.lift_length = lift.length;
  f.tilt_force = tilt.force;
  f.tilt_length = tilt.length;
  double N[2];
  const SimTK::Vec3* axles[2] = {&front_axle, &rear_axle};
  for (int i = 0; i < 2; ++i) {
    const double z = frame.findStationLocationInGround(s, *axles[i])[2];
    const double vz = frame.findStationVelocityInGround(s, *axles[i])[2];
    const double pen = p.tire_radius - z;
    N[i] = pen > 0 ? std::max(0.0, p.axle_stiffness * pen - p.axle_damping * vz) : 0.0;
  }
  f.normal_front = N[0];
  f.normal_rear = N[1];
  f.normal_load = N[0] + N[1];
  const double v = frame.findStationVelocityInGround(s, front_axle)[0];
  const double wanted = p.speed_gain * total_mass * (m.speed.value(t, m.smooth) - v);
  const double limit = p.traction_coefficient * f.normal_load;
  f.drive_force = drive_off ? 0.0 : std::clamp(wanted, -limit, limit);
  return f;
}

namespace {

void MachineForces::calcForce(const State& s, Vector_<SpatialVec>& body, Vector_<SimTK::Vec3>&,
                              Vector&) const {
  const auto& P = m_;
  const auto f = P.force_state(p_, s);
  // cylinders push the body pin away from the frame pin with a positive force
  auto push = [&](const MobilizedBody& b, const SimTK::Vec3& at_b, const SimTK::Vec3& at_frame,
                  double force) {
    const SimTK::Vec3 d = b.findStationLocationInGround(s, at_b) -
                          P.frame.findStationLocationInGround(s, at_frame);
    const SimTK::Vec3 F = force * d / d.norm();
    b.applyForceToBodyPoint(s, at_b, F, body);
    P.frame.applyForceToBodyPoint(s, at_frame, -F, body);
  };
  push(P.boom, P.lift_boom, P.lift_frame, f.lift_force);
  push(P.crank, P.tilt_crank, P.tilt_frame, f.tilt_force);
  // axle loads act up through the axle centre; traction at the contact point below it,
  // shared in proportion to the axle loads
  const double N[2] = {f.normal_front, f.normal_rear};
  const SimTK::Vec3* axles[2] = {&P.front_axle, &P.rear_axle};
  for (int i = 0; i < 2; ++i) {
    if (N[i] <= 0) continue;
    P.frame.applyForceToBodyPoint(s, *axles[i], SimTK::Vec3(0, 0, N[i]), body);
    SimTK::Vec3 contact = P.frame.findStationLocationInGround(s, *axles[i]);
    contact[2] = 0;
    const double traction = f.drive_force * N[i] / f.normal_load;
    P.frame.applyForceToBodyPoint(s, P.frame.findStationAtGroundPoint(s, contact),
                                  SimTK::Vec3(traction, 0, 0), body);
  }
}

Real MachineForces::calcPotentialEnergy(const State& s) const {
  const auto& P = m_;
  const auto f = P.force_state(p_, s);
  const double t = s.getTime();
  const auto& m = p_.maneuver;
  const double dl = f.lift_length - P.lift_design - m.lift.value(t, m.smooth);
  const double dt = f.tilt_length - P.tilt_design - m.tilt.value(t, m.smooth);
  double e = 0.5 * p_.lift_cylinder.stiffness * dl * dl + 0.5 * p_.tilt_cylinder.stiffness * dt * dt;
  for (const SimTK::Vec3* a : {&P.front_axle, &P.rear_axle}) {
    const double pen = p_.tire_radius - P.frame.findStationLocationInGround(s, *a)[2];
    if (pen > 0) e += 0.5 * p_.axle_stiffness * pen * pen;
  }
  return e;
}

}  // namespace

WheelLoader::WheelLoader(const Parameters& p, double t_start)
    : MachineOf("wheel_loader", p, std::make_unique<WheelLoaderImpl>()) {
  WheelLoaderImpl& P = impl();
  const Rotation R = pin_axes();
  Force::UniformGravity(P.forces, P.matter, SimTK::Vec3(0, 0, -p_.gravity));

  // Body frames: frame at the front axle centre, boom at its pivot, bell crank at its pivot,
  // tilt link at its bell-crank pin, bucket at the A-pin; all parallel to ground at design.
  const Vec2 J{p.a_pin[0] + p.j_pin[0], p.a_pin[1] + p.j_pin[1]};
  const Vec2& D = p.crank_link_pin;
  const Vec2 link_com{0.5 * (D[0] + J[0]), 0.5 * (D[1] + J[1])};
  if (std::hypot(J[0] - D[0], J[1] - D[1]) < 1e-3)
    throw std::invalid_argument(
        "bucket.j_pin coincides with bell_crank.link_pin: the tilt link has no length");

  P.frame = MobilizedBody::Planar(P.matter.Ground(), Transform(R, SimTK::Vec3(0)),
                                  SimTK::Body::Rigid(mass_properties(p.frame, xz(p.frame.com))),
                                  Transform(R, SimTK::Vec3(0)));
  P.boom = MobilizedBody::Pin(
      P.frame, Transform(R, xz(p.boom_pivot)),
      SimTK::Body::Rigid(mass_properties(p.boom, xz_minus(p.boom.com, p.boom_pivot))),
      Transform(R, SimTK::Vec3(0)));
  P.bucket = MobilizedBody::Pin(P.boom, Transform(R, xz_minus(p.a_pin, p.boom_pivot)),
                                SimTK::Body::Rigid(mass_properties(p.bucket, xz(p.bucket.com))),
                                Transform(R, SimTK::Vec3(0)));
  P.crank = MobilizedBody::Pin(
      P.boom, Transform(R, xz_minus(p.crank_pivot, p.boom_pivot)),
      SimTK::Body::Rigid(mass_properties(p.bell_crank, xz_minus(p.bell_crank.com, p.crank_pivot))),
      Transform(R, SimTK::Vec3(0)));
  P.link = MobilizedBody::Pin(
      P.crank, Transform(R, xz_minus(D, p.crank_pivot)),
      SimTK::Body::Rigid(mass_properties(p.tilt_link, xz_minus(link_com, D))),
      Transform(R, SimTK::Vec3(0)));
  P.link_j = xz_minus(J, D);
  P.j_pin = Constraint::PointOnLine(P.bucket, UnitVec3(YAxis), xz(p.j_pin), P.link, P.link_j);

  P.lift_frame = xz(p.lift_cylinder.frame_pin);
  P.lift_boom = xz_minus(p.lift_boom_pin, p.boom_pivot);
  P.tilt_frame = xz(p.tilt_cylinder.frame_pin);
  P.tilt_crank = xz_minus(p.crank_cylinder_pin, p.crank_pivot);
  P.front_axle = SimTK::Vec3(0);
  P.rear_axle = SimTK::Vec3(-p.wheelbase, 0, 0);
  P.lift_design = (xz(p.lift_boom_pin) - P.lift_frame).norm();
  P.tilt_design = (xz(p.crank_cylinder_pin) - P.tilt_frame).norm();
  P.total_mass = p.frame.mass + p.boom.mass + p.bell_crank.mass + p.tilt_link.mass + p.bucket.mass;

  Force::Custom(P.forces, new MachineForces(p_, P));
  P.couple(*this, P.bucket);

  State& s = P.state;
  s = P.system.realizeTopology();
  s.setTime(t_start);
  // Start near the static tire deflection, then minimize the potential energy (gravity,
  // tires, cylinders at their t_start targets): a machine at rest, loops closed.
  P.frame.setQ(s, SimTK::Vec3(0, p.initial_position,
                              p.tire_radius - P.total_mass * p.gravity / (2 * p.axle_stiffness)));
  P.system.realize(s, Stage::Position);
  P.A_b = SimTK::Vec2(p.a_pin[0] - p.boom_pivot[0], p.a_pin[1] - p.boom_pivot[1]);
  P.C_b = SimTK::Vec2(p.crank_pivot[0] - p.boom_pivot[0], p.crank_pivot[1] - p.boom_pivot[1]);
  P.D0_b = SimTK::Vec2(D[0] - p.boom_pivot[0], D[1] - p.boom_pivot[1]);
  P.J0_b = SimTK::Vec2(J[0] - p.boom_pivot[0], J[1] - p.boom_pivot[1]);
  P.branch = cross2(P.D0_b - P.A_b, P.J0_b - P.A_b) >= 0 ? 1 : -1;
  P.solve_static(p_, s);
  SimTK::Vec3 q = P.frame.getQ(s);
  q[1] = p.initial_position;
  P.frame.setQ(s, q);
  P.frame.setU(s, SimTK::Vec3(0, p.initial_speed, 0));
  P.system.realize(s, Stage::Acceleration);

  P.make_integrator(p.inner_step, 1e-10);
}

void WheelLoaderImpl::set_linkage(State& s, double boom_angle, double crank_angle) const {
  const SimTK::Vec2 D_b = C_b + rot2(crank_angle, D0_b - C_b);
  const double rA = (J0_b - A_b).norm(), rD = (J0_b - D0_b).norm();
  const SimTK::Vec2 AD = D_b - A_b;
  const double d = AD.norm();
  const double a = (rA * rA - rD * rD + d * d) / (2 * d);
  const double h2 = rA * rA - a * a;
  if (!(h2 >= 0))
    throw std::invalid_argument(
        "the Z-bar linkage cannot close at boom angle " + std::to_string(boom_angle) +
        " rad and bell-crank angle " + std::to_string(crank_angle) +
        " rad: check the pin positions and the maneuver's cylinder extensions");
  const SimTK::Vec2 J = A_b + (a / d) * AD + (branch * std::sqrt(h2) / d) * SimTK::Vec2(-AD[1], AD[0]);
  boom.setOneQ(s, 0, boom_angle);
  crank.setOneQ(s, 0, crank_angle);
  bucket.setOneQ(s, 0, angle2(J - A_b) - angle2(J0_b - A_b));
  link.setOneQ(s, 0, angle2(J - D_b) - angle2(J0_b - D0_b) - crank_angle);
}

// Static equilibrium by Newton's method on the independent coordinates (frame pitch and
// height, boom and bell-crank angles) with the machine at rest and the drive off: their
// accelerations vanish. Finite-difference Jacobian; the loop closes exactly in set_linkage.
void WheelLoaderImpl::solve_static(const Parameters& p, State& s) {
  drive_off = true;
  SimTK::Vector y(4);
  y[0] = frame.getQ(s)[0];
  y[1] = std::min(frame.getQ(s)[2], p.tire_radius - 0.5 * total_mass * p.gravity / (2 * p.axle_stiffness));
  y[2] = boom.getQ(s);
  y[3] = crank.getQ(s);
  const double x = frame.getQ(s)[1];
  s.updU() = 0;
  auto residual = [&](const SimTK::Vector& v) {
    frame.setQ(s, SimTK::Vec3(v[0], x, v[1]));
    set_linkage(s, v[2], v[3]);
    system.realize(s, Stage::Acceleration);
    SimTK::Vector r(4);
    r[0] = frame.getUDot(s)[0];
    r[1] = frame.getUDot(s)[2];
    r[2] = boom.getUDot(s);
    r[3] = crank.getUDot(s);
    return r;
  };
  // First the kinematics: boom and bell-crank angles that give the cylinders their target
  // lengths (a good start for the stiff cylinders).
  {
    const double t = s.getTime();
    const auto& m = p.maneuver;
    const double Lt[2] = {lift_design + m.lift.value(t, m.smooth), tilt_design + m.tilt.value(t, m.smooth)};
    auto lengths = [&](double b, double c) {
      frame.setQ(s, SimTK::Vec3(y[0], x, y[1]));
      set_linkage(s, b, c);
      system.realize(s, Stage::Position);
      auto len = [&](const MobilizedBody& body, const SimTK::Vec3& at_b, const SimTK::Vec3& at_f) {
        return (body.findStationLocationInGround(s, at_b) - frame.findStationLocationInGround(s, at_f)).norm();
      };
      return SimTK::Vec2(len(boom, lift_boom, lift_frame) - Lt[0], len(crank, tilt_crank, tilt_frame) - Lt[1]);
    };
    for (int it = 0; it < 50; ++it) {
      const SimTK::Vec2 e = lengths(y[2], y[3]);
      if (std::max(std::abs(e[0]), std::abs(e[1])) < 1e-12) break;
      const SimTK::Vec2 eb = lengths(y[2] + 1e-7, y[3]), ec = lengths(y[2], y[3] + 1e-7);
      const double a = (eb[0] - e[0]) / 1e-7, b = (ec[0] - e[0]) / 1e-7;
      const double c = (eb[1] - e[1]) / 1e-7, d = (ec[1] - e[1]) / 1e-7;
      const double det = a * d - b * c;
      double db = -(d * e[0] - b * e[1]) / det, dc = -(-c * e[0] + a * e[1]) / det;
      const double cap = std::max({std::abs(db), std::abs(dc), 0.1}) / 0.1;
      y[2] += db / cap;
      y[3] += dc / cap;
    }
  }
  // the height step stays inside the tire deflection (the tire force has a kink at contact);
  // a trust region: at most 0.05 rad and 0.05 m per iteration
  const double deflection = total_mass * p.gravity / (2 * p.axle_stiffness);
  const SimTK::Vector r =
      mbs::solve_newton(residual, y, {50, 1e-11, {1e-7, std::min(1e-7, 0.1 * deflection), 1e-7, 1e-7},
                                      {0.05, 0.05, 0.05, 0.05}});
  drive_off = false;
  if (r.normInf() > 1e-6)
    throw std::runtime_error("wheel loader: no static equilibrium found at t_start (residual " +
                             std::to_string(r.normInf()) +
                             " rad/s2): check masses, stiffnesses and the maneuver at t_start");
}

double WheelLoader::total_mass() const { return impl().total_mass; }

void WheelLoader::resolve_static() { impl().solve_static(p_, impl().state); }

V3 WheelLoader::cutting_edge() const { return coupled_point({p_.shape.edge_x, 0, p_.shape.floor_z}); }

namespace {

// Force (and moment about its own J point) that the PointOnLine puts on the bucket.
SimTK::Vec3 j_force_on_bucket(const WheelLoaderImpl& P, const State& s) {
  const Vector_<SpatialVec> cf = P.j_pin.getConstrainedBodyForcesAsVector(s);
  for (ConstrainedBodyIndex i(0); i < cf.size(); ++i)
    if (int(P.j_pin.getMobilizedBodyFromConstrainedBody(i).getMobilizedBodyIndex()) ==
        int(P.bucket.getMobilizedBodyIndex()))
      return -cf[i][1];  // constraint forces carry the opposite sign of applied forces
  throw std::logic_error("J-pin constraint does not act on the bucket");
}

}  // namespace

Reports WheelLoader::reports() const {
  const WheelLoaderImpl& P = impl();
  const State& s = P.state;
  P.system.realize(s, Stage::Acceleration);
  Reports r;
  const Rotation& R_GB = P.bucket.getBodyRotation(s);
  const SimTK::Vec3 a = ~R_GB * P.bucket.findMobilizerReactionOnBodyAtMInGround(s)[1];
  r.a_long = a[0];
  r.a_vert = a[2];
  const SimTK::Vec3 j = ~R_GB * j_force_on_bucket(P, s);
  r.j_long = j[0];
  r.j_vert = j[2];
  const auto f = P.force_state(p_, s);
  r.lift_force = f.lift_force;
  r.tilt_force = f.tilt_force;
  r.lift_length = f.lift_length;
  r.tilt_length = f.tilt_length;
  r.drive_force = f.drive_force;
  r.normal_load = f.normal_load;
  r.normal_front = f.normal_front;
  r.normal_rear = f.normal_rear;
  r.speed = P.frame.findStationVelocityInGround(s, P.front_axle)[0];
  r.x_machine = P.frame.findStationLocationInGround(s, P.front_axle)[0];
  r.heave = P.frame.findStationLocationInGround(s, P.front_axle)[2];
  r.pitch = P.frame.getQ(s)[0];
  r.boom_angle = P.boom.getAngle(s);
  const SimTK::Vec3 x_axis = R_GB.x();
  r.bucket_pitch = std::atan2(x_axis[2], x_axis[0]);
  return r;
}

Dynamics WheelLoader::dynamics() const {
  const WheelLoaderImpl& P = impl();
  const State& s = P.state;
  P.system.realize(s, Stage::Acceleration);
  auto body = [&](const MobilizedBody& b) {
    BodyDynamics d;
    const MassProperties& mp = b.getBodyMassProperties(s);
    const Rotation& R = b.getBodyRotation(s);
    d.mass = mp.getMass();
    d.origin = to_array(b.getBodyOriginLocation(s));
    d.com = to_array(b.findStationLocationInGround(s, mp.getMassCenter()));
    d.com_acceleration = to_array(b.findStationAccelerationInGround(s, mp.getMassCenter()));
    d.angular_velocity = to_array(b.getBodyAngularVelocity(s));
    d.angular_acceleration = to_array(b.getBodyAngularAcceleration(s));
    const Mat33 I = R * mp.calcCentralInertia().toMat33() * ~R;
    for (int i = 0; i < 3; ++i) d.inertia[i] = {I(i, 0), I(i, 1), I(i, 2)};
    return d;
  };
  auto reaction = [&](const MobilizedBody& b) {
    const SpatialVec r = b.findMobilizerReactionOnBodyAtMInGround(s);
    const SimTK::Vec3 at = b.getBodyOriginLocation(s);  // M is at the body origin here
    return PinForce{to_array(at), to_array(r[1]), to_array(r[0])};
  };
  Dynamics d;
  d.frame = body(P.frame);
  d.boom = body(P.boom);
  d.crank = body(P.crank);
  d.link = body(P.link);
  d.bucket = body(P.bucket);
  d.boom_pivot = reaction(P.boom);
  d.a_pin = reaction(P.bucket);
  d.crank_pivot = reaction(P.crank);
  d.link_pin = reaction(P.link);
  {
    const SimTK::Vec3 at = P.link.findStationLocationInGround(s, P.link_j);
    const Vector_<SpatialVec> cf = P.j_pin.getConstrainedBodyForcesAsVector(s);
    const SimTK::Vec3 F = j_force_on_bucket(P, s);
    // the spatial force is about the bucket origin; move its moment to the J point
    SimTK::Vec3 M(0);
    for (ConstrainedBodyIndex i(0); i < cf.size(); ++i)
      if (int(P.j_pin.getMobilizedBodyFromConstrainedBody(i).getMobilizedBodyIndex()) ==
          int(P.bucket.getMobilizedBodyIndex()))
        M = -cf[i][0] - (at - P.bucket.getBodyOriginLocation(s)) % F;
    d.j_pin = PinForce{to_array(at), to_array(F), to_array(M)};
  }
  const auto f = P.force_state(p_, s);
  auto cyl = [&](const MobilizedBody& b, const SimTK::Vec3& at_b, const SimTK::Vec3& at_frame,
                 double force, V3& frame_end) {
    const SimTK::Vec3 pb = b.findStationLocationInGround(s, at_b);
    const SimTK::Vec3 pf = P.frame.findStationLocationInGround(s, at_frame);
    frame_end = to_array(pf);
    return PinForce{to_array(pb), to_array(force * (pb - pf) / (pb - pf).norm()), {0, 0, 0}};
  };
  d.lift_on_boom = cyl(P.boom, P.lift_boom, P.lift_frame, f.lift_force, d.lift_frame_pin);
  d.tilt_on_crank = cyl(P.crank, P.tilt_crank, P.tilt_frame, f.tilt_force, d.tilt_frame_pin);
  d.external = wrench_at(s.getTime());
  d.gravity = {0, 0, -p_.gravity};
  return d;
}

}  // namespace wheel_loader
