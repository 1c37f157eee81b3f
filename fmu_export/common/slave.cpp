#include "slave.hpp"

#include <cmath>

namespace fmu_export {
namespace {

const char* mode_name(Mode m) {
  switch (m) {
    case Mode::Instantiated: return "instantiated (before fmi2EnterInitializationMode)";
    case Mode::Initialization: return "in initialization mode";
    case Mode::Step: return "stepping (after fmi2ExitInitializationMode)";
    case Mode::Terminated: return "terminated";
    case Mode::Error: return "in error (after an earlier fmi2Error; only fmi2Reset, fmi2Terminate and fmi2FreeInstance help)";
  }
  return "?";
}

std::string quoted(const std::string& s) { return "'" + s + "'"; }

}  // namespace

std::int64_t whole_ns(double seconds, const std::string& what, const std::string& hint) {
  const double ns = seconds * 1e9;
  if (!std::isfinite(ns) || std::abs(ns) > 9e18 || std::abs(ns - std::llround(ns)) > 1e-3)
    throw FmuError(what + " = " + std::to_string(seconds) + " s is not a whole number of nanoseconds" + hint);
  return std::llround(ns);
}

std::int64_t step_ns(double t, double h, std::int64_t at_ns, std::int64_t inner_ns) {
  const std::int64_t t_ns = whole_ns(t, "fmi2DoStep: currentCommunicationPoint");
  if (t_ns != at_ns)
    throw FmuError("fmi2DoStep: currentCommunicationPoint is " + std::to_string(t_ns) +
                   " ns, but the FMU is at " + std::to_string(at_ns) + " ns");
  const std::int64_t h_ns = whole_ns(h, "fmi2DoStep: communicationStepSize");
  if (inner_ns > 0 && (h_ns <= 0 || h_ns % inner_ns != 0))
    throw FmuError("fmi2DoStep: communicationStepSize " + std::to_string(h_ns) +
                   " ns is not a multiple of the inner step " + std::to_string(inner_ns) +
                   " ns (parameter 'inner_step')");
  return h_ns;
}

// The base part of a saved FMU state.
struct BaseState : SavedState {
  std::map<std::pair<int, fmi2ValueReference>, double> reals;
  std::map<std::pair<int, fmi2ValueReference>, int> integers;
  std::map<std::pair<int, fmi2ValueReference>, std::string> strings;
  std::map<fmi2ValueReference, std::array<double, kMaxInputDerivativeOrder>> derivatives;
  double t = 0;
  Mode mode = Mode::Step;
  std::shared_ptr<const void> model;
};

Slave::Slave(const Description& d, std::string instance_name, const fmi2CallbackFunctions& callbacks,
             bool logging_on)
    : d_(d), instance_(std::move(instance_name)), callbacks_(callbacks), logging_(logging_on) {
  for (const auto& v : d_.variables) slots_[{static_cast<int>(v.type), v.vr}] = Slot{&v, 0, 0, {}};
  load_start_values();
}

void Slave::load_start_values() {
  for (auto& [key, s] : slots_) {
    s.real = s.var->type == Type::Real ? s.var->start : 0;
    s.integer = s.var->type == Type::Integer ? static_cast<int>(s.var->start) : 0;
    s.string = s.var->start_string;
  }
  derivatives_.clear();
}

void Slave::log(fmi2Status status, const char* category, const std::string& message) const {
  if (!callbacks_.logger) return;
  if (!logging_ && status != fmi2Error && status != fmi2Fatal) return;
  // The logger takes a printf format: a '%' in the text must not be read as a conversion.
  std::string escaped;
  for (char c : message) {
    escaped += c;
    if (c == '%') escaped += '%';
  }
  callbacks_.logger(callbacks_.componentEnvironment, instance_.c_str(), status, category,
                    escaped.c_str());
}

Slave::Slot& Slave::slot(Type type, fmi2ValueReference vr, const char* function) {
  auto it = slots_.find({static_cast<int>(type), vr});
  if (it == slots_.end()) {
    const char* t = type == Type::Real ? "Real" : type == Type::Integer ? "Integer" : "String";
    throw FmuError(std::string(function) + ": " + d_.model_identifier + " has no " + t +
                   " variable with value reference " + std::to_string(vr) +
                   " (see its modelDescription.xml)");
  }
  return it->second;
}

Slave::Slot& Slave::slot(const std::string& name) {
  for (auto& [key, s] : slots_)
    if (s.var->name == name) return s;
  throw std::logic_error("no variable named " + name);
}

const Slave::Slot& Slave::slot(const std::string& name) const {
  return const_cast<Slave*>(this)->slot(name);
}

double& Slave::real(const std::string& name) { return slot(name).real; }
double Slave::real(const std::string& name) const { return slot(name).real; }
int Slave::integer(const std::string& name) const { return slot(name).integer; }
const std::string& Slave::string(const std::string& name) const { return slot(name).string; }

void Slave::check_settable(const Variable& v, const char* function) const {
  if (v.causality == Causality::Output)
    throw FmuError(std::string(function) + ": " + quoted(v.name) +
                   " is an output of the FMU; outputs cannot be set");
  if (mode_ == Mode::Terminated || mode_ == Mode::Error)
    throw FmuError(std::string(function) + ": cannot set " + quoted(v.name) + " while the FMU is " +
                   mode_name(mode_));
  if (v.causality == Causality::Parameter && v.variability == Variability::Fixed &&
      mode_ == Mode::Step)
    throw FmuError(std::string(function) + ": parameter " + quoted(v.name) +
                   " is fixed: set it before fmi2ExitInitializationMode");
}

void Slave::set_real(fmi2ValueReference vr, double value) {
  Slot& s = slot(Type::Real, vr, "fmi2SetReal");
  check_settable(*s.var, "fmi2SetReal");
  if (!std::isfinite(value))
    throw FmuError("fmi2SetReal: " + quoted(s.var->name) + " must be a finite number");
  s.real = value;
}

void Slave::set_integer(fmi2ValueReference vr, int value) {
  Slot& s = slot(Type::Integer, vr, "fmi2SetInteger");
  check_settable(*s.var, "fmi2SetInteger");
  s.integer = value;
}

void Slave::set_string(fmi2ValueReference vr, const std::string& value) {
  Slot& s = slot(Type::String, vr, "fmi2SetString");
  check_settable(*s.var, "fmi2SetString");
  s.string = value;
}

void Slave::set_input_derivative(fmi2ValueReference vr, int order, double value) {
  Slot& s = slot(Type::Real, vr, "fmi2SetRealInputDerivatives");
  if (!d_.can_interpolate_inputs)
    throw FmuError("fmi2SetRealInputDerivatives: " + d_.model_identifier +
                   " does not interpolate inputs (canInterpolateInputs=\"false\")");
  if (s.var->causality != Causality::Input)
    throw FmuError("fmi2SetRealInputDerivatives: " + quoted(s.var->name) + " is not an input");
  if (order < 1 || order > kMaxInputDerivativeOrder)
    throw FmuError("fmi2SetRealInputDerivatives: order " + std::to_string(order) + " for " +
                   quoted(s.var->name) + "; this FMU takes orders 1 to " +
                   std::to_string(kMaxInputDerivativeOrder));
  if (mode_ != Mode::Step && mode_ != Mode::Initialization)
    throw FmuError("fmi2SetRealInputDerivatives: the FMU is " + std::string(mode_name(mode_)));
  if (!std::isfinite(value))
    throw FmuError("fmi2SetRealInputDerivatives: derivative of " + quoted(s.var->name) +
                   " must be a finite number");
  derivatives_[vr][order - 1] = value;
}

double Slave::input_derivative(const std::string& name, int order) const {
  const Slot& s = slot(name);
  auto it = derivatives_.find(s.var->vr);
  return it == derivatives_.end() ? 0.0 : it->second[order - 1];
}

int Slave::input_derivative_order() const {
  int order = 0;
  for (const auto& [vr, d] : derivatives_)
    for (int k = 0; k < kMaxInputDerivativeOrder; ++k)
      if (d[k] != 0) order = std::max(order, k + 1);
  return order;
}

double Slave::get_real(fmi2ValueReference vr) {
  Slot& s = slot(Type::Real, vr, "fmi2GetReal");
  if (s.var->causality == Causality::Output && mode_ != Mode::Error) update_outputs();
  return s.real;
}

int Slave::get_integer(fmi2ValueReference vr) { return slot(Type::Integer, vr, "fmi2GetInteger").integer; }

const std::string& Slave::get_string(fmi2ValueReference vr) {
  return slot(Type::String, vr, "fmi2GetString").string;
}

void Slave::setup_experiment(double start, std::optional<double> stop) {
  if (mode_ != Mode::Instantiated)
    throw FmuError("fmi2SetupExperiment: must come before fmi2EnterInitializationMode; the FMU is " +
                   std::string(mode_name(mode_)));
  if (!std::isfinite(start) || (stop && !(std::isfinite(*stop) && *stop > start)))
    throw FmuError("fmi2SetupExperiment: start time must be finite and the stop time after it");
  start_ = t_ = start;
  stop_ = stop;
}

void Slave::enter_initialization() {
  if (mode_ != Mode::Instantiated)
    throw FmuError("fmi2EnterInitializationMode: the FMU is " + std::string(mode_name(mode_)));
  mode_ = Mode::Initialization;
}

void Slave::exit_initialization() {
  if (mode_ != Mode::Initialization)
    throw FmuError("fmi2ExitInitializationMode: the FMU is " + std::string(mode_name(mode_)) +
                   ", not in initialization mode");
  t_ = start_;
  initialize();
  derivatives_.clear();
  mode_ = Mode::Step;
}

void Slave::do_step(double t, double h) {
  if (mode_ != Mode::Step)
    throw SequenceError("fmi2DoStep: the FMU is " + std::string(mode_name(mode_)));
  if (!std::isfinite(t) || !std::isfinite(h) || h <= 0)
    throw SequenceError("fmi2DoStep: communicationStepSize must be a positive finite number (got " +
                   std::to_string(h) + ")");
  if (std::abs(t - t_) > 1e-9 * std::max(1.0, std::abs(t_))) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "fmi2DoStep: currentCommunicationPoint %.17g, but the FMU is at t = %.17g "
                  "(a master that goes back must first restore an FMU state)", t, t_);
    throw SequenceError(buf);
  }
  if (stop_ && t + h > *stop_ * (1 + 1e-12) + 1e-12) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "fmi2DoStep: the step to t = %.17g goes past the stop time %.17g of fmi2SetupExperiment", t + h, *stop_);
    throw SequenceError(buf);
  }
  step(t, h);
  // Input derivatives hold for one step; the next needs its own (else the inputs are held).
  derivatives_.clear();
  t_ = t + h;
}

void Slave::terminate() {
  if (mode_ != Mode::Step && mode_ != Mode::Error)
    throw FmuError("fmi2Terminate: the FMU is " + std::string(mode_name(mode_)));
  on_terminate();
  mode_ = Mode::Terminated;
}

void Slave::reset() {
  if (mode_ != Mode::Instantiated && mode_ != Mode::Terminated) on_terminate();
  load_start_values();
  start_ = t_ = 0;
  stop_.reset();
  mode_ = Mode::Instantiated;
}

std::unique_ptr<SavedState> Slave::save() {
  if (!d_.can_get_and_set_state)
    throw FmuError("fmi2GetFMUstate: " + d_.model_identifier +
                   " cannot save its state (canGetAndSetFMUstate=\"false\")");
  if (mode_ != Mode::Step)
    throw FmuError("fmi2GetFMUstate: the FMU is " + std::string(mode_name(mode_)) +
                   "; states are saved between steps");
  auto s = std::make_unique<BaseState>();
  for (const auto& [key, slot] : slots_) {
    s->reals[key] = slot.real;
    s->integers[key] = slot.integer;
    s->strings[key] = slot.string;
  }
  s->derivatives = derivatives_;
  s->t = t_;
  s->mode = mode_;
  s->model = save_model();
  return s;
}

void Slave::restore(const SavedState& saved) {
  if (!d_.can_get_and_set_state)
    throw FmuError("fmi2SetFMUstate: " + d_.model_identifier + " cannot restore a state");
  const auto* s = dynamic_cast<const BaseState*>(&saved);
  if (!s) throw FmuError("fmi2SetFMUstate: not a state of this FMU");
  if (mode_ != Mode::Step)
    throw FmuError("fmi2SetFMUstate: the FMU is " + std::string(mode_name(mode_)));
  restore_model(s->model);  // first: it may refuse, and then nothing has changed
  for (auto& [key, slot] : slots_) {
    slot.real = s->reals.at(key);
    slot.integer = s->integers.at(key);
    slot.string = s->strings.at(key);
  }
  derivatives_ = s->derivatives;
  t_ = s->t;
}

}  // namespace fmu_export
