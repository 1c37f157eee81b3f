// The Simbody side of the machine layer (machine.hpp): what a machine model builds into, and
// the tools every model uses. Include it only in sources compiled as Debian's Simbody was
// (soil_simbody_sources: C++17, without -DNDEBUG).
#pragma once

#include <Simbody.h>

#include <array>
#include <functional>
#include <memory>
#include <vector>

#include "machine.hpp"

namespace mbs {

// A machine model's Impl derives from this and adds its bodies (handles into `matter`), its
// force elements and whatever its forces need. The order the model adds force elements in is
// the order Simbody sums them: the coupling wrench (couple()) comes last.
struct Machine::Simbody {
  virtual ~Simbody() = default;

  SimTK::MultibodySystem system;
  SimTK::SimbodyMatterSubsystem matter{system};
  SimTK::GeneralForceSubsystem forces{system};
  const SimTK::MobilizedBody* coupled = nullptr;  // the body the soil acts on (couple())
  std::unique_ptr<SimTK::RungeKutta3Integrator> integrator;
  bool integrator_initialized = false;  // advance_fixed's record (set by Machine::advance)
  SimTK::State state, snapshot;

  // Adds the soil's wrench (machine.wrench_at(t)) on `body`, taken about its origin, as a force
  // element, and makes `body` the coupled one. `body` must outlive the system (a member of
  // the model's Impl).
  void couple(const Machine& machine, const SimTK::MobilizedBody& body);
  // The fixed-step explicit integrator every machine uses (Runge-Kutta 3, no interpolation);
  // constraint_tolerance 0 keeps Simbody's default.
  void make_integrator(double inner_step, double constraint_tolerance = 0);
};

// Advances `state` with fixed steps h to t_end, which must be a whole number of steps ahead
// (std::invalid_argument otherwise). The integrator starts afresh (the input may have changed,
// and a restored snapshot must repeat bit for bit); after_inner_step, when given, runs after
// every step with `state` at its end.
// The state is moved into the integrator and back, never copied.
void advance_fixed(SimTK::Integrator& integrator, SimTK::State& state, double h, double t_end,
                   const std::function<void()>& after_inner_step = {});
// The same with a warm restart: `initialized` is the caller's record that this integrator of
// `system` has been initialized (set after an advance that succeeded, cleared when one throws
// and by make_integrator). With it the integrator restarts without Integrator::initialize,
// doing only what initialize does that changes a bit (its forced projection) and leaving out
// what it repeats (realizations, set-up): the same bits (tests/wheel_loader,
// wheel_loader_advance_test). That holds for systems without measures, event handlers and
// auto-update discrete variables (initialize acts on those; the machines here have none): a
// model that adds one must extend the restart and hold it to advance_fixed_reference as that
// test does.
void advance_fixed(SimTK::Integrator& integrator, const SimTK::System& system, bool& initialized,
                   SimTK::State& state, double h, double t_end,
                   const std::function<void()>& after_inner_step = {});
// The same advance done plainly, the reference advance_fixed must equal bit for bit (tests and
// bench/mbs): the state copied into the integrator (Integrator::initialize) and copied back.
void advance_fixed_reference(SimTK::Integrator& integrator, SimTK::State& state, double h, double t_end,
                             const std::function<void()>& after_inner_step = {});

inline SimTK::Vec3 to_simtk(const V3& a) { return SimTK::Vec3(a[0], a[1], a[2]); }
inline V3 to_array(const SimTK::Vec3& a) { return {a[0], a[1], a[2]}; }
// A point [x, z] of a planar model's x-z plane, in 3D.
inline SimTK::Vec3 xz(const std::array<double, 2>& v) { return SimTK::Vec3(v[0], 0, v[1]); }
// Pins and the planar joint turn about their mobilizer frames' z; this rotation puts that z
// along ground -y, so body frames stay parallel to ground at zero angles and positive angles
// turn x towards z.
inline SimTK::Rotation pin_axes() { return SimTK::Rotation(SimTK::Pi / 2, SimTK::XAxis); }
// A rigid body's mass properties about its frame origin: mass, centre of mass (body frame)
// and principal moments about the centre of mass along the body axes.
SimTK::MassProperties mass_properties(double mass, const SimTK::Vec3& com, const V3& central);

// The origin, orientation and velocities of `body` in ground (the state realized to Velocity).
cosim::Kinematics kinematics(const SimTK::MobilizedBody& body, const SimTK::State& state);

// Newton's method for a static equilibrium, residual(y) = 0: a finite-difference Jacobian
// (column j with step fd_step[j]), an LU solve, the step scaled down as a whole until no
// unknown moves more than max_step[j] (a trust region), then halved up to 30 times until the
// residual's largest component falls (backtracking). Stops when that is at most `tolerance`,
// after max_iterations, or when no step lowers it (the round-off floor). residual() may set
// the model's state; it is called at the returned y last. Returns the residual there.
struct NewtonSettings {
  int max_iterations = 50;
  double tolerance = 1e-11;
  std::vector<double> fd_step;   // one per unknown
  std::vector<double> max_step;  // one per unknown
};
SimTK::Vector solve_newton(const std::function<SimTK::Vector(const SimTK::Vector&)>& residual,
                           SimTK::Vector& y, const NewtonSettings& settings);

}  // namespace mbs
