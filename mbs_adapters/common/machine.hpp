// The machine layer the Simbody machine models share (the wheel loader, the hauler, the next
// one): a multibody system advanced with a fixed inner step, one body coupled to the soil (its
// kinematics go out, the soil's wrench comes in and acts on it), one snapshot slot, any number
// of saved states and checkpoint files of the whole state.
//
// A machine is a model file and a parameter file: a class deriving from Machine that builds
// its bodies and forces into a Machine::Simbody (simbody_machine.hpp: the system, the state,
// the integrator, the coupling wrench, a static-equilibrium solver) and says which body is
// coupled; its bus adapter derives from MachineAdapter (machine_adapter.hpp) and names
// its scalar outputs.
//
// Simbody 3.7's headers do not compile as C++20 (ambiguous reversed operator==) and Debian
// builds Simbody without -DNDEBUG: they stay inside the sources listed in soil_simbody_sources;
// this header is plain C++.
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <string>
#include <utility>

#include "cosim/quantities.hpp"

namespace mbs {

using V3 = std::array<double, 3>;
double norm(const V3& x);

// The coupling quantities (cosim/quantities.hpp: plain C++, no bus). The soil's wrench on the
// coupled body: force and torque in ground, the torque about `point` (ground).
using Wrench = cosim::Wrench;
using WrenchInput = std::function<Wrench(double t)>;

class Machine {
 public:
  struct Simbody;  // simbody_machine.hpp

  virtual ~Machine();
  Machine(const Machine&) = delete;
  Machine& operator=(const Machine&) = delete;

  // The external wrench on the coupled body as a function of time; empty means none.
  void set_wrench(WrenchInput input);
  // Evaluated wrench at time t (zero if none).
  Wrench wrench_at(double t) const { return wrench_ ? wrench_(t) : Wrench{}; }
  // Advances with fixed inner steps to t_end (a whole number of inner steps ahead; anything
  // else is refused with std::invalid_argument); after_inner_step, when given, runs after
  // every inner step with the state at its end.
  void advance(double t_end, const std::function<void()>& after_inner_step = {});
  // The same advance by the plain path advance() must equal bit for bit (tests, bench/mbs):
  // simbody_machine.hpp, advance_fixed_reference.
  void advance_reference(double t_end, const std::function<void()>& after_inner_step = {});

  double time() const;
  double inner_step() const { return inner_step_; }
  // The coupled body's frame origin, its orientation body -> ground and its velocities, all
  // in ground.
  cosim::Kinematics coupled_body() const;
  // A point given in the coupled body's frame, in ground.
  V3 coupled_point(const V3& in_body) const;
  // Largest |udot| (generalized accelerations) at the current state: ~0 at rest.
  double max_acceleration() const;

  // One snapshot slot: the whole Simbody state.
  void save_snapshot();
  void restore_snapshot();
  // Checkpoints: the Simbody state's time, q, u and z to a file and back, exactly (the
  // integrator starts afresh at every advance, so nothing else carries over). load_state
  // throws std::runtime_error for a file of another model or layout.
  void save_state(const std::string& path) const;
  void load_state(const std::string& path);
  // Any number of saved states (an FMU's fmi2GetFMUstate): a copy of the whole Simbody state,
  // opaque here.
  std::shared_ptr<const void> copy_state() const;
  void set_state(const std::shared_ptr<const void>& saved);

 protected:
  // name: the model's tag in checkpoint files; inner_step [s]; sim: the model's own Simbody
  // part (a struct deriving from Machine::Simbody), empty until the model builds into it.
  Machine(std::string name, double inner_step, std::unique_ptr<Simbody> sim);
  Simbody& sim() { return *sim_; }
  const Simbody& sim() const { return *sim_; }

 private:
  std::string name_;
  double inner_step_;
  std::unique_ptr<Simbody> sim_;
  WrenchInput wrench_;
};

// A machine of its parameters (ParametersT, with an inner_step in s) and its Simbody part
// (ImplT, deriving from Machine::Simbody, defined in the model's source file).
template <class ParametersT, class ImplT>
class MachineOf : public Machine {
 public:
  const ParametersT& parameters() const { return p_; }

 protected:
  MachineOf(std::string name, const ParametersT& p, std::unique_ptr<Simbody> sim)
      : Machine(std::move(name), p.inner_step, std::move(sim)), p_(p) {}
  ImplT& impl() { return static_cast<ImplT&>(sim()); }
  const ImplT& impl() const { return static_cast<const ImplT&>(sim()); }

  ParametersT p_;
};

}  // namespace mbs
