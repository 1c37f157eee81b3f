#include "fmi2_instance.hpp"

#include <dlfcn.h>

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <algorithm>
#include <sstream>

namespace fmu {

const char* status_name(fmi2Status s) {
  switch (s) {
    case fmi2OK: return "fmi2OK";
    case fmi2Warning: return "fmi2Warning";
    case fmi2Discard: return "fmi2Discard";
    case fmi2Error: return "fmi2Error";
    case fmi2Fatal: return "fmi2Fatal";
    case fmi2Pending: return "fmi2Pending";
  }
  return "unknown status";
}

Fmi2Library::Fmi2Library(const std::string& so_path, const std::string& fmu)
    : lib_(so_path, fmu, "linux64 (x86_64)") {
  auto need = [&](auto*& fn, const char* name, bool required) { lib_.find(fn, name, required); };
  need(getTypesPlatform, "fmi2GetTypesPlatform", true);
  need(getVersion, "fmi2GetVersion", true);
  need(setDebugLogging, "fmi2SetDebugLogging", true);
  need(instantiate, "fmi2Instantiate", true);
  need(freeInstance, "fmi2FreeInstance", true);
  need(setupExperiment, "fmi2SetupExperiment", true);
  need(enterInitializationMode, "fmi2EnterInitializationMode", true);
  need(exitInitializationMode, "fmi2ExitInitializationMode", true);
  need(terminate, "fmi2Terminate", true);
  need(getReal, "fmi2GetReal", true);
  need(getInteger, "fmi2GetInteger", true);
  need(getBoolean, "fmi2GetBoolean", true);
  need(getString, "fmi2GetString", true);
  need(setReal, "fmi2SetReal", true);
  need(setInteger, "fmi2SetInteger", true);
  need(setBoolean, "fmi2SetBoolean", true);
  need(setString, "fmi2SetString", true);
  need(doStep, "fmi2DoStep", true);
  need(getFMUstate, "fmi2GetFMUstate", false);
  need(setFMUstate, "fmi2SetFMUstate", false);
  need(freeFMUstate, "fmi2FreeFMUstate", false);
  need(getStatus, "fmi2GetStatus", false);
  need(getRealStatus, "fmi2GetRealStatus", false);
  need(setRealInputDerivatives, "fmi2SetRealInputDerivatives", false);
  need(getBooleanStatus, "fmi2GetBooleanStatus", false);
  need(serializedFMUstateSize, "fmi2SerializedFMUstateSize", false);
  need(serializeFMUstate, "fmi2SerializeFMUstate", false);
  need(deSerializeFMUstate, "fmi2DeSerializeFMUstate", false);
  lib_.check_complete("not an FMI 2.0 co-simulation binary, or built with a function prefix");
  const std::string version = getVersion();
  if (version != "2.0")
    throw FmuError("FMU '" + fmu + "': its binary reports fmi2GetVersion() = \"" + version +
                   "\", expected \"2.0\"");
  const std::string platform = getTypesPlatform();
  if (platform != COSIM_FMI2_TYPES_PLATFORM)
    throw FmuError("FMU '" + fmu + "': its binary uses types platform \"" + platform +
                   "\", fmu_adapter supports \"" COSIM_FMI2_TYPES_PLATFORM "\"");
}


namespace {

// The FMU's logger callback: `message` is a printf format with the variadic arguments.
void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
            fmi2String category, fmi2String message, ...) {
  char buf[2048];
  va_list args;
  va_start(args, message);
  if (message) std::vsnprintf(buf, sizeof buf, message, args);
  else buf[0] = '\0';
  va_end(args);
  if (env) static_cast<Fmi2Instance*>(env)->log(status, category, buf);
  else std::fprintf(stderr, "FMU instance '%s': %s\n", instance ? instance : "?", buf);
}

void* allocate(size_t n, size_t size) { return std::calloc(n, size); }

}  // namespace

Fmi2Instance::Fmi2Instance(Fmi2Library& lib, const ModelDescription& md, const std::string& fmu_label,
                           const std::string& instance_name, const std::string& resources_uri,
                           bool verbose, std::function<void(const std::string&)> sink)
    : lib_(lib), label_(fmu_label), instance_name_(instance_name), verbose_(verbose), sink_(std::move(sink)) {
  callbacks_.logger = logger;
  callbacks_.allocateMemory = allocate;
  callbacks_.freeMemory = std::free;
  callbacks_.stepFinished = nullptr;
  callbacks_.componentEnvironment = this;
  // loggingOn: without it some FMUs keep their error messages to themselves; fmi2OK messages
  // are shown only when verbose.
  c_ = lib_.instantiate(instance_name_.c_str(), fmi2CoSimulation, md.guid.c_str(),
                        resources_uri.c_str(), &callbacks_, fmi2False, fmi2True);
  if (!c_) {
    std::string why;
    for (const auto& m : recent_) why += "\n  " + m;
    throw FmuError(who() + ": fmi2Instantiate failed (returned NULL)" +
                   (why.empty() ? std::string(" without a message") : ("; the FMU said:" + why)));
  }
}

Fmi2Instance::~Fmi2Instance() {
  if (!c_ || fatal_) return;
  if (state_ && !failed_ && lib_.freeFMUstate) lib_.freeFMUstate(c_, &state_);
  if (initialized_ && !failed_) lib_.terminate(c_);
  lib_.freeInstance(c_);
}

std::string Fmi2Instance::who() const {
  return "FMU '" + label_ + "' (instance '" + instance_name_ + "')";
}

void Fmi2Instance::log(fmi2Status status, const char* category, const std::string& message) {
  std::string line = who() + " [" + status_name(status) +
                     (category && *category ? std::string(", ") + category : std::string()) + "]: " + message;
  recent_.push_back(line);
  if (recent_.size() > 6) recent_.pop_front();
  if (status != fmi2OK || verbose_) sink_(line);
}

void Fmi2Instance::check(fmi2Status status, const char* function, const std::string& when) {
  if (status == fmi2OK || status == fmi2Warning) return;
  if (status == fmi2Fatal) fatal_ = true;
  else failed_ = true;
  std::string text = who() + ": " + function + " " + when + " returned " + status_name(status);
  if (status == fmi2Discard)
    text += " (the FMU could not complete the call; fmu_adapter does not retry with a smaller step)";
  else if (status == fmi2Pending)
    text += " (asynchronous doStep is not supported)";
  std::string said;
  for (const auto& m : recent_) said += "\n  " + m;
  text += said.empty() ? std::string("; the FMU logged nothing") : "; the FMU's last messages:" + said;
  throw FmuError(text);
}

void Fmi2Instance::enter_initialization(double start, std::optional<double> tolerance,
                                        std::optional<double> stop) {
  check(lib_.setupExperiment(c_, tolerance ? fmi2True : fmi2False, tolerance.value_or(0.0), start,
                             stop ? fmi2True : fmi2False, stop.value_or(0.0)),
        "fmi2SetupExperiment", "");
  check(lib_.enterInitializationMode(c_), "fmi2EnterInitializationMode", "");
}

std::string Fmi2Instance::get_text(const Variable& v, const std::string& when) {
  if (v.type != VarType::String) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", get_number(v, when));
    return buf;
  }
  const fmi2ValueReference vr = v.value_reference;
  fmi2String x = nullptr;
  check(lib_.getString(c_, &vr, 1, &x), "fmi2GetString", "of '" + v.name + "' " + when);
  return x ? x : "";
}

void Fmi2Instance::exit_initialization() {
  check(lib_.exitInitializationMode(c_), "fmi2ExitInitializationMode", "");
  initialized_ = true;
}

std::optional<double> Fmi2Instance::do_step(double t, double h) {
  if (failed_ || fatal_) throw FmuError(who() + ": failed earlier; it cannot step again");
  if (terminated_) throw FmuError(who() + ": ended itself (fmi2Terminated) earlier; it takes no further step");
  char when[96];
  std::snprintf(when, sizeof when, "at t = %.9g s (step %.9g s)", t, h);
  const fmi2Status status = lib_.doStep(c_, t, h, fmi2False);
  if (status == fmi2Discard) {
    // FMI 2.0, 4.2.3: the FMU could not complete the step. If it asks to end the simulation
    // (a Modelica terminate(), a stop condition), fmi2Terminated is true and the run ends at
    // fmi2LastSuccessfulTime; otherwise it is a failure (no retry with a smaller step).
    fmi2Boolean ended = fmi2False;
    std::string why;
    if (!lib_.getBooleanStatus) why = "its binary has no fmi2GetBooleanStatus to ask whether it ended itself";
    else if (const fmi2Status s = lib_.getBooleanStatus(c_, fmi2Terminated, &ended); s != fmi2OK && s != fmi2Warning)
      why = std::string("fmi2GetBooleanStatus(fmi2Terminated) returned ") + status_name(s);
    if (why.empty() && ended) {
      fmi2Real last = t;
      if (!lib_.getRealStatus)
        throw FmuError(who() + ": fmi2DoStep " + when + " returned fmi2Discard with fmi2Terminated, but its "
                       "binary has no fmi2GetRealStatus to say the time it reached");
      if (const fmi2Status s = lib_.getRealStatus(c_, fmi2LastSuccessfulTime, &last); s != fmi2OK && s != fmi2Warning)
        throw FmuError(who() + ": fmi2DoStep " + when + " returned fmi2Discard with fmi2Terminated, but "
                       "fmi2GetRealStatus(fmi2LastSuccessfulTime) returned " + status_name(s));
      if (!(last >= t - 1e-9 * std::max(1.0, std::abs(t)) && last <= t + h + 1e-9 * std::max(1.0, std::abs(t + h)))) {
        char text[160];
        std::snprintf(text, sizeof text, "fmi2GetRealStatus(fmi2LastSuccessfulTime) = %.17g s, outside the step [%.17g, %.17g] s",
                      last, t, t + h);
        throw FmuError(who() + ": fmi2DoStep " + when + " returned fmi2Discard with fmi2Terminated, but " + text);
      }
      terminated_ = true;
      return std::min(std::max(last, t), t + h);
    }
    failed_ = true;
    std::string said;
    for (const auto& m : recent_) said += "\n  " + m;
    throw FmuError(who() + ": fmi2DoStep " + when + " returned fmi2Discard: the FMU could not complete the step " +
                   "and did not ask to end the simulation (" +
                   (why.empty() ? std::string("fmi2GetBooleanStatus(fmi2Terminated) is false") : why) +
                   "); fmu_adapter does not retry with a smaller step" +
                   (said.empty() ? std::string("; the FMU logged nothing") : "; the FMU's last messages:" + said));
  }
  check(status, "fmi2DoStep", when);
  return std::nullopt;
}

std::string Fmi2Instance::serialize_state() {
  if (!lib_.has_serialize_functions()) throw FmuError(who() + ": its binary cannot serialize its state");
  fmi2FMUstate s = nullptr;
  check(lib_.getFMUstate(c_, &s), "fmi2GetFMUstate", "(for a checkpoint)");
  if (!s) throw FmuError(who() + ": fmi2GetFMUstate returned fmi2OK but no state");
  std::string bytes;
  try {
    size_t size = 0;
    check(lib_.serializedFMUstateSize(c_, s, &size), "fmi2SerializedFMUstateSize", "");
    bytes.assign(size, '\0');
    check(lib_.serializeFMUstate(c_, s, bytes.data(), size), "fmi2SerializeFMUstate", "");
  } catch (...) {
    if (!failed_ && !fatal_) lib_.freeFMUstate(c_, &s);
    throw;
  }
  check(lib_.freeFMUstate(c_, &s), "fmi2FreeFMUstate", "");
  return bytes;
}

void Fmi2Instance::deserialize_state(const std::string& bytes) {
  if (!lib_.has_serialize_functions()) throw FmuError(who() + ": its binary cannot deserialize a state");
  fmi2FMUstate s = nullptr;
  check(lib_.deSerializeFMUstate(c_, bytes.data(), bytes.size(), &s), "fmi2DeSerializeFMUstate", "");
  if (!s) throw FmuError(who() + ": fmi2DeSerializeFMUstate returned fmi2OK but no state");
  const fmi2Status set = lib_.setFMUstate(c_, s);
  lib_.freeFMUstate(c_, &s);
  check(set, "fmi2SetFMUstate", "(from a checkpoint)");
}

void Fmi2Instance::set(const Variable& v, const Scalar& value, const std::string& when) {
  const fmi2ValueReference vr = v.value_reference;
  const std::string w = "of '" + v.name + "' " + when;
  switch (v.type) {
    case VarType::Real: {
      const fmi2Real x = value.number;
      check(lib_.setReal(c_, &vr, 1, &x), "fmi2SetReal", w);
      break;
    }
    case VarType::Integer:
    case VarType::Enumeration: {
      const fmi2Integer x = static_cast<fmi2Integer>(value.number);
      check(lib_.setInteger(c_, &vr, 1, &x), "fmi2SetInteger", w);
      break;
    }
    case VarType::Boolean: {
      const fmi2Boolean x = value.number != 0 ? fmi2True : fmi2False;
      check(lib_.setBoolean(c_, &vr, 1, &x), "fmi2SetBoolean", w);
      break;
    }
    case VarType::String: {
      const fmi2String x = value.text.c_str();
      check(lib_.setString(c_, &vr, 1, &x), "fmi2SetString", w);
      break;
    }
    default:
      throw FmuError(who() + ": '" + v.name + "' has FMI 3.0 type " + type_name(v.type) + " in an FMI 2.0 FMU");
  }
}

double Fmi2Instance::get_number(const Variable& v, const std::string& when) {
  const fmi2ValueReference vr = v.value_reference;
  const std::string w = "of '" + v.name + "' " + when;
  switch (v.type) {
    case VarType::Real: {
      fmi2Real x = 0;
      check(lib_.getReal(c_, &vr, 1, &x), "fmi2GetReal", w);
      return x;
    }
    case VarType::Integer:
    case VarType::Enumeration: {
      fmi2Integer x = 0;
      check(lib_.getInteger(c_, &vr, 1, &x), "fmi2GetInteger", w);
      return x;
    }
    case VarType::Boolean: {
      fmi2Boolean x = 0;
      check(lib_.getBoolean(c_, &vr, 1, &x), "fmi2GetBoolean", w);
      return x ? 1.0 : 0.0;
    }
    default:
      break;
  }
  throw FmuError(who() + ": '" + v.name + "' is a " + type_name(v.type) + " variable; it cannot be a number");
}

void Fmi2Instance::get_numbers(const std::vector<const Variable*>& vars, std::vector<double>& out,
                               const std::string& when) {
  out.resize(vars.size());
  for (std::size_t i = 0; i < vars.size(); ++i) out[i] = get_number(*vars[i], when);
}

void Fmi2Instance::set_input_derivative(const Variable& v, int order, double value, const std::string& when) {
  const fmi2ValueReference vr = v.value_reference;
  const fmi2Integer o = order;
  check(lib_.setRealInputDerivatives(c_, &vr, 1, &o, &value), "fmi2SetRealInputDerivatives",
        "of '" + v.name + "' (order " + std::to_string(order) + ") " + when);
}

void Fmi2Instance::save_state() {
  if (!lib_.getFMUstate) throw FmuError(who() + ": its binary has no fmi2GetFMUstate");
  // With a state from before, fmi2GetFMUstate updates it in place (FMI 2.0, 2.1.8).
  check(lib_.getFMUstate(c_, &state_), "fmi2GetFMUstate", "");
  if (!state_) throw FmuError(who() + ": fmi2GetFMUstate returned fmi2OK but no state");
}

void Fmi2Instance::restore_state() {
  if (!state_) throw FmuError(who() + ": no FMU state saved to go back to");
  check(lib_.setFMUstate(c_, state_), "fmi2SetFMUstate", "");
}

}  // namespace fmu
