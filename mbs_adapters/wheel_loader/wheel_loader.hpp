// The wheel-loader multibody model (Simbody), a machine of the machine layer
// (mbs_adapters/common/machine.hpp) with the bucket as its coupled body. It knows nothing of the
// bus: a test drives it directly, the adapter (wheel_loader_adapter.hpp) maps it onto
// signals.
//
// Planar in the x-z plane (x forward, y left, z up, ground z = 0), with full 3D outputs:
//   ground -Planar(x, z, pitch)-> frame -Pin-> boom -Pin(A)-> bucket
//                                               boom -Pin-> bell crank -Pin-> tilt link
//   tilt link -> bucket: PointOnLine at the J-pin (closes the Z-bar loop, 2 equations)
// Forces: gravity; one vertical spring-damper per axle against the ground; a traction-limited
// drive force at the tire contacts; lift (frame->boom) and tilt (frame->bell crank) cylinders
// as stiff position/rate feedback forces along their lines following the maneuver; the
// external bucket wrench, evaluated at the state's time.
// Pin angles are positive about -y (x turns towards z): boom up, bucket curled back.
//
// Simbody stays inside wheel_loader.cpp (built as C++17); this header is plain C++.
#pragma once

#include <array>
#include <string>

#include "machine.hpp"
#include "parameters.hpp"

namespace wheel_loader {

using mbs::V3;
// The external wrench on the bucket: force and torque in ground, the torque about `point`.
using mbs::Wrench;
using mbs::WrenchInput;

// Section forces are the forces ON THE BUCKET from the boom (A) and from the tilt link (J),
// in the bucket frame: long = x (towards the cutting edge), vert = z (up from the floor).
struct Reports {
  double a_long = 0, a_vert = 0, j_long = 0, j_vert = 0;
  double lift_force = 0, tilt_force = 0;    // N, positive pushing (cylinder in compression)
  double lift_length = 0, tilt_length = 0;  // m
  double speed = 0, x_machine = 0;          // front axle centre: dx/dt and x in ground
  double drive_force = 0, normal_load = 0;  // N: traction at the tires, sum of axle loads
  double normal_front = 0, normal_rear = 0;
  double boom_angle = 0, bucket_pitch = 0;  // rad: boom from its design pose; bucket x in ground
  double pitch = 0, heave = 0;              // frame pitch [rad], front axle centre height [m]
};

// Everything a Newton-Euler check needs, in ground, at the current state.
struct BodyDynamics {
  double mass = 0;
  V3 origin{}, com{}, com_acceleration{}, angular_velocity{}, angular_acceleration{};
  std::array<V3, 3> inertia{};  // about the centre of mass, ground axes
};
struct PinForce {
  V3 point{};   // ground
  V3 force{};   // on the body it belongs to
  V3 moment{};  // about `point`
};
struct Dynamics {
  BodyDynamics frame, boom, crank, link, bucket;
  PinForce boom_pivot;   // on the boom, from the frame
  PinForce a_pin;        // on the bucket, from the boom
  PinForce crank_pivot;  // on the bell crank, from the boom
  PinForce link_pin;     // on the tilt link, from the bell crank
  PinForce j_pin;        // on the bucket, from the tilt link
  PinForce lift_on_boom, tilt_on_crank;  // cylinder forces at their body pins
  V3 lift_frame_pin{}, tilt_frame_pin{};  // the cylinders' frame ends
  Wrench external;       // as applied at the current time
  V3 gravity{};
};

struct WheelLoaderImpl;  // the Simbody system (wheel_loader.cpp)

class WheelLoader final : public mbs::MachineOf<Parameters, WheelLoaderImpl> {
 public:
  // Builds the model and puts it at rest in static equilibrium (tires and cylinders loaded,
  // cylinders at their t_start targets) at time t_start, then gives it initial_speed.
  explicit WheelLoader(const Parameters& p, double t_start = 0);

  // The bucket frame origin (A-pin centre), its orientation bucket -> ground and velocities,
  // all in ground.
  cosim::Kinematics bucket() const { return coupled_body(); }
  Reports reports() const;
  // The cutting edge's tip in ground: the bucket-frame point [edge_x, 0, floor_z].
  V3 cutting_edge() const;
  Dynamics dynamics() const;
  double total_mass() const;

  // Puts the machine at rest in static equilibrium at the current time and x position, with
  // the current wrench input applied (the constructor does this without one).
  void resolve_static();
};

}  // namespace wheel_loader
