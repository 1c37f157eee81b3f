#include "machine.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "simbody_machine.hpp"
#include "simbody_state_file.hpp"

namespace mbs {

using namespace SimTK;

double norm(const V3& x) { return std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]); }

namespace {

class CouplingWrench : public Force::Custom::Implementation {
 public:
  CouplingWrench(const Machine& machine, const MobilizedBody& body) : machine_(machine), body_(body) {}
  void calcForce(const State& s, Vector_<SpatialVec>& forces, Vector_<SimTK::Vec3>&,
                 Vector&) const override {
    const Wrench w = machine_.wrench_at(s.getTime()).shifted_to(to_array(body_.getBodyOriginLocation(s)));
    body_.applyBodyForce(s, SpatialVec(to_simtk(w.torque), to_simtk(w.force)), forces);
  }
  Real calcPotentialEnergy(const State&) const override { return 0; }

 private:
  const Machine& machine_;
  const MobilizedBody& body_;
};

}  // namespace

void Machine::Simbody::couple(const Machine& machine, const MobilizedBody& body) {
  coupled = &body;
  Force::Custom(forces, new CouplingWrench(machine, body));
}

void Machine::Simbody::make_integrator(double inner_step, double constraint_tolerance) {
  integrator = std::make_unique<RungeKutta3Integrator>(system);
  integrator->setFixedStepSize(inner_step);
  integrator->setAllowInterpolation(false);
  if (constraint_tolerance > 0) integrator->setConstraintTolerance(constraint_tolerance);
  integrator_initialized = false;
}

namespace {

void check_whole_steps(double t0, double h, double t_end, long& n) {
  n = std::lround((t_end - t0) / h);
  if (n < 1 || std::abs(t0 + n * h - t_end) > 1e-9 * std::max(1.0, std::abs(t_end)))
    throw std::invalid_argument("advance: " + std::to_string(t_end - t0) +
                                " s is not a whole number of inner steps of " + std::to_string(h) + " s");
}

// Moves the caller's state into the integrator for the advance and back out at its end, also
// when Simbody throws (the state is then the integrator's: the last inner step it completed).
class StateLoan {
 public:
  StateLoan(Integrator& integ, State& s) : integ_(integ), s_(s) { integ_.updAdvancedState() = std::move(s_); }
  ~StateLoan() { s_ = std::move(integ_.updAdvancedState()); }
  StateLoan(const StateLoan&) = delete;
  StateLoan& operator=(const StateLoan&) = delete;

 private:
  Integrator& integ_;
  State& s_;
};

// What Integrator::initialize (Simbody 3.7, IntegratorRep::initialize) does to a state, done to
// the integrator's own advanced state, less what is left the same for an integrator that was
// initialized before with this system and settings: the model and instance realizations
// (done), the copy (the state is already there), the event-trigger and tolerance set-up
// (unchanged), the initialization events (none: no measures, no event handlers) and its second
// realization after the auto-update discrete variables (none). What stays: the projection onto
// the constraint manifold that initialize forces (full Newton, the integrator's constraint
// tolerance; it moves q and u by round-off at every restart, so it must stay for the same
// bits) and the restart of the step sequence (reinitialize: the next stepTo begins a
// continuous interval, realizes the derivatives with the input now in force and saves the
// step's start as initialize would have).
void restart(Integrator& integ, const System& system) {
  State& s = integ.updAdvancedState();
  system.realizeModel(s);
  ProjectOptions options(integ.getConstraintToleranceInUse());
  options.setOption(ProjectOptions::ForceProjection);
  options.setOption(ProjectOptions::ForceFullNewton);
  Vector no_error_estimate;
  ProjectResults results;
  system.realize(s, Stage::Time);
  system.prescribeQ(s);
  system.realize(s, Stage::Position);
  system.projectQ(s, no_error_estimate, options, results);
  system.prescribeU(s);
  system.realize(s, Stage::Velocity);
  results.clear();
  system.projectU(s, no_error_estimate, options, results);
  integ.reinitialize(Stage::Time, false);
}

void advance(Integrator& integ, State& s, double h, double t_end,
             const std::function<void()>& after_inner_step, const System* system, bool* initialized) {
  const double t0 = s.getTime();
  long n = 0;
  check_whole_steps(t0, h, t_end, n);
  // No copy of the state: it is moved into the integrator and back out at the end.
  StateLoan loan(integ, s);
  if (initialized && *initialized) {
    *initialized = false;  // until this advance succeeds
    restart(integ, *system);
  } else {
    // Integrator::initialize on the integrator's own state: a State assigned to itself is
    // left as it is, and the cache it brings is valid for its t, q and u (set_wrench
    // invalidated what depends on the input).
    integ.initialize(integ.getAdvancedState());
  }
  for (long k = 1; k <= n; ++k) {
    const double tk = k == n ? t_end : t0 + k * h;
    while (integ.getTime() < tk) integ.stepTo(tk);
    if (after_inner_step) {
      // the callback reads the machine's state: lend it back for the call
      s = std::move(integ.updAdvancedState());
      try {
        after_inner_step();
      } catch (...) {
        integ.updAdvancedState() = std::move(s);
        throw;
      }
      integ.updAdvancedState() = std::move(s);
    }
  }
  if (initialized) *initialized = true;
}

}  // namespace

void advance_fixed(Integrator& integ, State& s, double h, double t_end,
                   const std::function<void()>& after_inner_step) {
  advance(integ, s, h, t_end, after_inner_step, nullptr, nullptr);
}

void advance_fixed(Integrator& integ, const System& system, bool& initialized, State& s, double h,
                   double t_end, const std::function<void()>& after_inner_step) {
  advance(integ, s, h, t_end, after_inner_step, &system, &initialized);
}

void advance_fixed_reference(Integrator& integ, State& s, double h, double t_end,
                             const std::function<void()>& after_inner_step) {
  const double t0 = s.getTime();
  long n = 0;
  check_whole_steps(t0, h, t_end, n);
  integ.initialize(s);
  for (long k = 1; k <= n; ++k) {
    const double tk = k == n ? t_end : t0 + k * h;
    while (integ.getTime() < tk) integ.stepTo(tk);
    if (after_inner_step) {
      s = integ.getState();
      after_inner_step();
    }
  }
  s = integ.getState();
}

MassProperties mass_properties(double mass, const SimTK::Vec3& com, const V3& central) {
  const Inertia I(SimTK::Vec3(central[0], central[1], central[2]));
  return MassProperties(mass, com, I.shiftFromMassCenter(com, mass));
}

cosim::Kinematics kinematics(const MobilizedBody& b, const State& s) {
  cosim::Kinematics k;
  k.position = to_array(b.getBodyOriginLocation(s));
  const Quaternion q = b.getBodyRotation(s).convertRotationToQuaternion();
  k.orientation = {q[0], q[1], q[2], q[3]};
  k.velocity = to_array(b.getBodyOriginVelocity(s));
  k.angular_velocity = to_array(b.getBodyAngularVelocity(s));
  return k;
}

SimTK::Vector solve_newton(const std::function<SimTK::Vector(const SimTK::Vector&)>& residual,
                           SimTK::Vector& y, const NewtonSettings& settings) {
  const int n = y.size();
  if (static_cast<int>(settings.fd_step.size()) != n || static_cast<int>(settings.max_step.size()) != n)
    throw std::logic_error("solve_newton: one finite-difference step and one step limit per unknown");
  SimTK::Vector r = residual(y);
  for (int it = 0; it < settings.max_iterations && r.normInf() > settings.tolerance; ++it) {
    Matrix J(r.size(), n);
    for (int j = 0; j < n; ++j) {
      SimTK::Vector yp = y;
      yp[j] += settings.fd_step[j];
      const SimTK::Vector rp = residual(yp);
      for (int i = 0; i < r.size(); ++i) J(i, j) = (rp[i] - r[i]) / settings.fd_step[j];
    }
    SimTK::Vector dy;
    const SimTK::Vector rhs = -r;
    FactorLU(J).solve(rhs, dy);
    double cap = 1;
    for (int j = 0; j < n; ++j) cap = std::max(cap, std::abs(dy[j]) / settings.max_step[j]);
    dy /= cap;
    double step = 1;
    bool improved = false;
    for (int k = 0; k < 30 && !improved; ++k, step *= 0.5) {
      const SimTK::Vector rn = residual(y + step * dy);
      if (rn.normInf() < r.normInf()) {
        y += step * dy;
        r = rn;
        improved = true;
      }
    }
    if (!improved) break;  // at the round-off floor
  }
  residual(y);
  return r;
}

// ---------------------------------------------------------------------------------------
// Machine

Machine::Machine(std::string name, double inner_step, std::unique_ptr<Simbody> sim)
    : name_(std::move(name)), inner_step_(inner_step), sim_(std::move(sim)) {}

Machine::~Machine() = default;

void Machine::set_wrench(WrenchInput input) {
  wrench_ = std::move(input);
  // forces, reactions and accelerations cached for the current state used the old input
  sim_->state.invalidateAllCacheAtOrAbove(Stage::Dynamics);
}

void Machine::advance(double t_end, const std::function<void()>& after_inner_step) {
  advance_fixed(*sim_->integrator, sim_->system, sim_->integrator_initialized, sim_->state, inner_step_,
                t_end, after_inner_step);
}

void Machine::advance_reference(double t_end, const std::function<void()>& after_inner_step) {
  advance_fixed_reference(*sim_->integrator, sim_->state, inner_step_, t_end, after_inner_step);
}

double Machine::time() const { return sim_->state.getTime(); }

cosim::Kinematics Machine::coupled_body() const {
  sim_->system.realize(sim_->state, Stage::Velocity);
  return kinematics(*sim_->coupled, sim_->state);
}

V3 Machine::coupled_point(const V3& in_body) const {
  sim_->system.realize(sim_->state, Stage::Position);
  return to_array(sim_->coupled->findStationLocationInGround(sim_->state, to_simtk(in_body)));
}

double Machine::max_acceleration() const {
  sim_->system.realize(sim_->state, Stage::Acceleration);
  return sim_->state.getUDot().normInf();
}

void Machine::save_snapshot() { sim_->snapshot = sim_->state; }
void Machine::restore_snapshot() { sim_->state = sim_->snapshot; }

void Machine::save_state(const std::string& path) const { save_simbody_state(path, name_, sim_->state); }

void Machine::load_state(const std::string& path) {
  load_simbody_state(path, name_, sim_->state);
  sim_->snapshot = sim_->state;
}

std::shared_ptr<const void> Machine::copy_state() const { return std::make_shared<const State>(sim_->state); }

void Machine::set_state(const std::shared_ptr<const void>& saved) {
  sim_->state = *static_cast<const State*>(saved.get());
}

}  // namespace mbs
