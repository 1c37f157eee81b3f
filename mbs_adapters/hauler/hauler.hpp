// The articulated-hauler multibody model (Simbody), a machine of the machine layer
// (mbs_adapters/common/machine.hpp) with the dump body as its coupled body. It knows nothing of
// the bus: a test drives it directly, the adapter (hauler_adapter.hpp) maps it onto signals.
//
// Planar in the x-z plane (x forward, y left, z up, road z = 0), with full 3D outputs:
//   ground -Planar(x, z, pitch)-> front unit -Weld-> rear frame -Pin(hinge)-> dump body
//   front unit -Slider(chassis z)-> front axle
//   rear frame -Slider(chassis z)-> rear1 axle, rear2 axle
// (the articulation joint turns about the vertical and the longitudinal axis: in the x-z plane
// the front unit and the rear frame move as one).
// Forces: gravity; per axle a radial tire spring-damper to the road and the parking brake's
// regularised friction at the contact patch; per axle a hydro-pneumatic strut (gas spring of
// its circuit, orifice damping, end stops), the front strut on its own circuit, rear1 and
// rear2 on one shared circuit (the hydraulic bogie), each circuit with a slow ride-height
// control that fills or drains oil; the hoist cylinder (rear frame -> body) as a position
// servo following the tipping profile; the external body wrench at the state's time.
// Each circuit carries two continuous states (Simbody z): its oil volume and the low-passed
// ride height the level control acts on.
//
// Simbody stays inside hauler.cpp (built as C++17); this header is plain C++.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "machine.hpp"
#include "parameters.hpp"

namespace hauler {

using mbs::V3;
// The external wrench on the dump body: force and torque in ground, the torque about `point`.
using mbs::Wrench;
using mbs::WrenchInput;

constexpr int kFront = 0, kRear1 = 1, kRear2 = 2;
constexpr const char* kAxleNames[3] = {"front", "rear1", "rear2"};

struct AxleReport {
  // tire force ON THE MACHINE in the wheel's TYDEX C axes [N] (fy is 0 in the plane)
  double fx = 0, fy = 0, fz = 0;
  double stroke = 0;        // strut stroke [m]: 0 fully compressed, suspension.stroke extended
  double stroke_rate = 0;   // [m/s], + extending
  double strut_force = 0;   // along the strut, + pushing chassis and axle apart [N]
  double end_stop = 0;      // the end stops' part of strut_force [N]
  double deflection = 0;    // tire: unloaded radius - wheel centre height [m]
  V3 centre{};              // wheel centre, ground [m]
};

struct CircuitReport {
  double pressure = 0;      // gas (= oil, no drop across the orifice at rest) [Pa]
  double gas_volume = 0;    // [m3]
  double oil = 0;           // oil volume added since "stroke 0 with an empty accumulator" [m3]
  double ride = 0;          // mean stroke of its struts [m]
  double ride_filtered = 0; // what the level control sees [m]
  double flow = 0;          // level control: + filling, - draining [m3/s]
};

struct Reports {
  AxleReport axle[3];
  CircuitReport front, rear;
  double hoist_force = 0;    // N, + pushing (raising)
  double hoist_length = 0;   // m, pin to pin
  double hoist_target = 0;   // m
  double body_angle = 0;     // rad, body relative to the chassis, + tipped (front up)
  double pitch = 0;          // rad, chassis, + nose up
  double heave = 0;          // chassis origin height above the road [m]
  double x_machine = 0;      // chassis origin x [m]
  double speed = 0;          // chassis origin dx/dt [m/s]
  double kinetic_energy = 0; // J
};

struct HaulerImpl;  // the Simbody system (hauler.cpp)

class Hauler final : public mbs::MachineOf<Parameters, HaulerImpl> {
 public:
  // Builds the model and puts it at rest in static equilibrium at time t_start: tires and
  // struts loaded, the body at its tipping target, static_load on the body, and each circuit's
  // oil set so its ride height is at ride_stroke (the level control has finished). The brake
  // anchors are where the wheels then stand.
  explicit Hauler(const Parameters& p, double t_start = 0);

  // The body frame origin (hinge axis, centre plane), its orientation body -> ground and its
  // velocities, all in ground.
  cosim::Kinematics body() const { return coupled_body(); }
  Reports reports() const;
  double total_mass() const;
  // Target body angle [rad] and hoist length [m] of the tipping profile at time t.
  double target_angle(double t) const;
  double hoist_length_at(double body_angle) const;

  // Static equilibrium again at the current time, with the current wrench input instead of
  // static_load, and, like the constructor, each circuit's oil solved for ride height and the
  // brake anchored where the wheels then stand.
  void resolve_static();
};

// One strut and its circuit alone, on a test rig: a sprung mass on a vertical slider, carried
// by the same strut law the hauler uses (gas spring, orifice, end stops, level control), under
// gravity and an extra downward load. Stroke 0 = fully compressed; the mass moves with the
// stroke (z = stroke).
struct RigState {
  double stroke = 0, stroke_rate = 0, pressure = 0, oil = 0, ride_filtered = 0, flow = 0;
  double strut_force = 0, end_stop = 0;
};

class StrutRig {
 public:
  // Starts at rest in equilibrium under the mass's weight alone with `oil` in the circuit (the
  // stroke follows from the gas law; it may be in an end stop).
  StrutRig(const Suspension& suspension, const Circuit& circuit, double mass, double gravity,
           double oil, double inner_step = 2e-4);
  ~StrutRig();
  StrutRig(const StrutRig&) = delete;
  StrutRig& operator=(const StrutRig&) = delete;
  // Extra downward force on the mass [N] as a function of time.
  void set_load(std::function<double(double)> load);
  void advance(double t_end);
  double time() const;
  RigState state() const;
  // The oil that puts the rig at `stroke` under `force` (the gas law, inverted).
  static double oil_for(const Circuit& c, double force, double stroke);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace hauler
