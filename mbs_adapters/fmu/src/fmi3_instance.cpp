#include "fmi3_instance.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

namespace fmu {

const char* status_name(fmi3Status s) {
  switch (s) {
    case fmi3OK: return "fmi3OK";
    case fmi3Warning: return "fmi3Warning";
    case fmi3Discard: return "fmi3Discard";
    case fmi3Error: return "fmi3Error";
    case fmi3Fatal: return "fmi3Fatal";
  }
  return "unknown status";
}

Fmi3Library::Fmi3Library(const std::string& so_path, const std::string& fmu)
    : lib_(so_path, fmu, "x86_64-linux") {
  auto need = [&](auto*& fn, const char* name, bool required) { lib_.find(fn, name, required); };
  need(getVersion, "fmi3GetVersion", true);
  need(instantiate, "fmi3InstantiateCoSimulation", true);
  need(freeInstance, "fmi3FreeInstance", true);
  need(enterInitializationMode, "fmi3EnterInitializationMode", true);
  need(exitInitializationMode, "fmi3ExitInitializationMode", true);
  need(enterConfigurationMode, "fmi3EnterConfigurationMode", true);
  need(exitConfigurationMode, "fmi3ExitConfigurationMode", true);
  need(terminate, "fmi3Terminate", true);
  need(doStep, "fmi3DoStep", true);
  need(getFloat32, "fmi3GetFloat32", true);
  need(setFloat32, "fmi3SetFloat32", true);
  need(getFloat64, "fmi3GetFloat64", true);
  need(setFloat64, "fmi3SetFloat64", true);
  need(getInt8, "fmi3GetInt8", true);
  need(setInt8, "fmi3SetInt8", true);
  need(getUInt8, "fmi3GetUInt8", true);
  need(setUInt8, "fmi3SetUInt8", true);
  need(getInt16, "fmi3GetInt16", true);
  need(setInt16, "fmi3SetInt16", true);
  need(getUInt16, "fmi3GetUInt16", true);
  need(setUInt16, "fmi3SetUInt16", true);
  need(getInt32, "fmi3GetInt32", true);
  need(setInt32, "fmi3SetInt32", true);
  need(getUInt32, "fmi3GetUInt32", true);
  need(setUInt32, "fmi3SetUInt32", true);
  need(getInt64, "fmi3GetInt64", true);
  need(setInt64, "fmi3SetInt64", true);
  need(getUInt64, "fmi3GetUInt64", true);
  need(setUInt64, "fmi3SetUInt64", true);
  need(getBoolean, "fmi3GetBoolean", true);
  need(setBoolean, "fmi3SetBoolean", true);
  need(getString, "fmi3GetString", true);
  need(setString, "fmi3SetString", true);
  need(getBinary, "fmi3GetBinary", true);
  need(setBinary, "fmi3SetBinary", true);
  need(getFMUState, "fmi3GetFMUState", false);
  need(setFMUState, "fmi3SetFMUState", false);
  need(freeFMUState, "fmi3FreeFMUState", false);
  need(serializedFMUStateSize, "fmi3SerializedFMUStateSize", false);
  need(serializeFMUState, "fmi3SerializeFMUState", false);
  need(deserializeFMUState, "fmi3DeserializeFMUState", false);
  lib_.check_complete("not an FMI 3.0 co-simulation binary, or built with a function prefix");
  const std::string version = getVersion();
  if (version.rfind("3.", 0) != 0)
    throw FmuError("FMU '" + fmu + "': its binary reports fmi3GetVersion() = \"" + version + "\", expected \"3.x\"");
}


namespace {

void log_message(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
  if (env) static_cast<Fmi3Instance*>(env)->log(status, category, message ? message : "");
}

std::string to_hex(const fmi3Byte* data, std::size_t n) {
  static const char* digits = "0123456789abcdef";
  std::string s;
  for (std::size_t i = 0; i < n; ++i) {
    s += digits[data[i] >> 4];
    s += digits[data[i] & 15];
  }
  return s;
}

}  // namespace

Fmi3Instance::Fmi3Instance(Fmi3Library& lib, const ModelDescription& md, const std::string& fmu_label,
                           const std::string& instance_name, const std::string& resource_path, bool verbose,
                           std::function<void(const std::string&)> sink)
    : lib_(lib), label_(fmu_label), instance_name_(instance_name), verbose_(verbose), sink_(std::move(sink)) {
  c_ = lib_.instantiate(instance_name_.c_str(), md.guid.c_str(), resource_path.c_str(), false, true,
                        /*eventModeUsed=*/false, /*earlyReturnAllowed=*/false, nullptr, 0, this, log_message, nullptr);
  if (!c_) {
    std::string why;
    for (const auto& m : recent_) why += "\n  " + m;
    throw FmuError(who() + ": fmi3InstantiateCoSimulation failed (returned NULL)" +
                   (why.empty() ? std::string(" without a message") : ("; the FMU said:" + why)));
  }
}

Fmi3Instance::~Fmi3Instance() {
  if (!c_ || fatal_) return;
  if (state_ && !failed_ && lib_.freeFMUState) lib_.freeFMUState(c_, &state_);
  if (initialized_ && !failed_) lib_.terminate(c_);
  lib_.freeInstance(c_);
}

std::string Fmi3Instance::who() const { return "FMU '" + label_ + "' (instance '" + instance_name_ + "')"; }

void Fmi3Instance::log(fmi3Status status, const char* category, const std::string& message) {
  std::string line = who() + " [" + status_name(status) +
                     (category && *category ? std::string(", ") + category : std::string()) + "]: " + message;
  recent_.push_back(line);
  if (recent_.size() > 6) recent_.pop_front();
  if (status != fmi3OK || verbose_) sink_(line);
}

void Fmi3Instance::check(fmi3Status status, const char* function, const std::string& when) {
  if (status == fmi3OK || status == fmi3Warning) return;
  if (status == fmi3Fatal) fatal_ = true;
  else failed_ = true;
  std::string text = who() + ": " + function + (when.empty() ? "" : " " + when) + " returned " + status_name(status);
  if (status == fmi3Discard) text += " (the FMU could not complete the call)";
  std::string said;
  for (const auto& m : recent_) said += "\n  " + m;
  text += said.empty() ? std::string("; the FMU logged nothing") : "; the FMU's last messages:" + said;
  throw FmuError(text);
}

void Fmi3Instance::enter_configuration() {
  check(lib_.enterConfigurationMode(c_), "fmi3EnterConfigurationMode", "");
}

void Fmi3Instance::exit_configuration() {
  check(lib_.exitConfigurationMode(c_), "fmi3ExitConfigurationMode", "");
}

void Fmi3Instance::enter_initialization(double start, std::optional<double> tolerance, std::optional<double> stop) {
  check(lib_.enterInitializationMode(c_, tolerance.has_value(), tolerance.value_or(0.0), start, stop.has_value(),
                                     stop.value_or(0.0)),
        "fmi3EnterInitializationMode", "");
}

void Fmi3Instance::exit_initialization() {
  // Without event mode the instance is in Step Mode after this (FMI 3.0, 4.2.2).
  check(lib_.exitInitializationMode(c_), "fmi3ExitInitializationMode", "");
  initialized_ = true;
}

std::optional<double> Fmi3Instance::do_step(double t, double h) {
  if (failed_ || fatal_) throw FmuError(who() + ": failed earlier; it cannot step again");
  if (terminated_) throw FmuError(who() + ": ended itself (terminateSimulation) earlier; it takes no further step");
  char when[96];
  std::snprintf(when, sizeof when, "at t = %.9g s (step %.9g s)", t, h);
  fmi3Boolean event_needed = false, terminate = false, early = false;
  fmi3Float64 last = t + h;
  const fmi3Status status = lib_.doStep(c_, t, h, false, &event_needed, &terminate, &early, &last);
  if (status == fmi3Discard && !terminate) {
    failed_ = true;
    std::string said;
    for (const auto& m : recent_) said += "\n  " + m;
    throw FmuError(who() + ": fmi3DoStep " + when + " returned fmi3Discard without terminateSimulation: the FMU "
                   "could not complete the step; fmu_adapter does not retry with a smaller step" +
                   (said.empty() ? std::string("; the FMU logged nothing") : "; the FMU's last messages:" + said));
  }
  if (status != fmi3Discard) check(status, "fmi3DoStep", when);
  if (terminate) {
    // FMI 3.0, 4.2.4: the FMU asks to end the simulation; lastSuccessfulTime is where it is.
    if (!(last >= t - 1e-9 * std::max(1.0, std::abs(t)) && last <= t + h + 1e-9 * std::max(1.0, std::abs(t + h)))) {
      char text[160];
      std::snprintf(text, sizeof text, "lastSuccessfulTime = %.17g s, outside the step [%.17g, %.17g] s", last, t, t + h);
      throw FmuError(who() + ": fmi3DoStep " + when + " set terminateSimulation, but " + text);
    }
    terminated_ = true;
    return std::min(std::max(last, t), t + h);
  }
  if (early) {
    failed_ = true;
    throw FmuError(who() + ": fmi3DoStep " + when + " returned early (earlyReturn = true) although fmu_adapter "
                   "instantiated it with earlyReturnAllowed = false; the FMU breaks FMI 3.0, 4.2.1");
  }
  return std::nullopt;
}

namespace {

std::vector<unsigned char> from_hex(const std::string& text, const std::string& what) {
  auto nibble = [&](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    throw FmuError(what + ": '" + text + "' is not hex digits (a Binary value is written as pairs of hex digits)");
  };
  if (text.size() % 2) throw FmuError(what + ": '" + text + "' has an odd number of hex digits");
  std::vector<unsigned char> out;
  for (std::size_t i = 0; i < text.size(); i += 2) out.push_back(static_cast<unsigned char>(nibble(text[i]) * 16 + nibble(text[i + 1])));
  return out;
}

}  // namespace

void Fmi3Instance::set(const Variable& v, const Scalar& value, const std::string& when) {
  const fmi3ValueReference vr = v.value_reference;
  const std::string w = "of '" + v.name + "' " + when;
  const double x = value.number;
  switch (v.type) {
    case VarType::Float32: { const fmi3Float32 y = static_cast<float>(x); check(lib_.setFloat32(c_, &vr, 1, &y, 1), "fmi3SetFloat32", w); return; }
    case VarType::Real:
    case VarType::Float64: { const fmi3Float64 y = x; check(lib_.setFloat64(c_, &vr, 1, &y, 1), "fmi3SetFloat64", w); return; }
    case VarType::Int8: { const fmi3Int8 y = static_cast<fmi3Int8>(x); check(lib_.setInt8(c_, &vr, 1, &y, 1), "fmi3SetInt8", w); return; }
    case VarType::UInt8: { const fmi3UInt8 y = static_cast<fmi3UInt8>(x); check(lib_.setUInt8(c_, &vr, 1, &y, 1), "fmi3SetUInt8", w); return; }
    case VarType::Int16: { const fmi3Int16 y = static_cast<fmi3Int16>(x); check(lib_.setInt16(c_, &vr, 1, &y, 1), "fmi3SetInt16", w); return; }
    case VarType::UInt16: { const fmi3UInt16 y = static_cast<fmi3UInt16>(x); check(lib_.setUInt16(c_, &vr, 1, &y, 1), "fmi3SetUInt16", w); return; }
    case VarType::Integer:
    case VarType::Int32: { const fmi3Int32 y = static_cast<fmi3Int32>(x); check(lib_.setInt32(c_, &vr, 1, &y, 1), "fmi3SetInt32", w); return; }
    case VarType::UInt32: { const fmi3UInt32 y = static_cast<fmi3UInt32>(x); check(lib_.setUInt32(c_, &vr, 1, &y, 1), "fmi3SetUInt32", w); return; }
    case VarType::Enumeration:  // FMI 3.0: an Int64
    case VarType::Int64: {
      const fmi3Int64 y = value.int64 ? *value.int64 : static_cast<fmi3Int64>(x);
      check(lib_.setInt64(c_, &vr, 1, &y, 1), "fmi3SetInt64", w);
      return;
    }
    case VarType::UInt64: {
      const fmi3UInt64 y = value.uint64 ? *value.uint64 : static_cast<fmi3UInt64>(x);
      check(lib_.setUInt64(c_, &vr, 1, &y, 1), "fmi3SetUInt64", w);
      return;
    }
    case VarType::Boolean: { const fmi3Boolean y = x != 0; check(lib_.setBoolean(c_, &vr, 1, &y, 1), "fmi3SetBoolean", w); return; }
    case VarType::String: { const fmi3String y = value.text.c_str(); check(lib_.setString(c_, &vr, 1, &y, 1), "fmi3SetString", w); return; }
    case VarType::Binary: {
      const std::vector<unsigned char> bytes = from_hex(value.text, who() + ": '" + v.name + "'");
      const std::size_t size = bytes.size();
      const fmi3Binary y = bytes.data();
      check(lib_.setBinary(c_, &vr, 1, &size, &y, 1), "fmi3SetBinary", w);
      return;
    }
    case VarType::Clock:
      break;
  }
  throw FmuError(who() + ": '" + v.name + "' is a Clock; fmu_adapter does not set clocks");
}

double Fmi3Instance::get_number(const Variable& v, const std::string& when) {
  const fmi3ValueReference vr = v.value_reference;
  const std::string w = "of '" + v.name + "' " + when;
  switch (v.type) {
    case VarType::Float32: { fmi3Float32 y = 0; check(lib_.getFloat32(c_, &vr, 1, &y, 1), "fmi3GetFloat32", w); return y; }
    case VarType::Real:
    case VarType::Float64: { fmi3Float64 y = 0; check(lib_.getFloat64(c_, &vr, 1, &y, 1), "fmi3GetFloat64", w); return y; }
    case VarType::Int8: { fmi3Int8 y = 0; check(lib_.getInt8(c_, &vr, 1, &y, 1), "fmi3GetInt8", w); return y; }
    case VarType::UInt8: { fmi3UInt8 y = 0; check(lib_.getUInt8(c_, &vr, 1, &y, 1), "fmi3GetUInt8", w); return y; }
    case VarType::Int16: { fmi3Int16 y = 0; check(lib_.getInt16(c_, &vr, 1, &y, 1), "fmi3GetInt16", w); return y; }
    case VarType::UInt16: { fmi3UInt16 y = 0; check(lib_.getUInt16(c_, &vr, 1, &y, 1), "fmi3GetUInt16", w); return y; }
    case VarType::Integer:
    case VarType::Int32: { fmi3Int32 y = 0; check(lib_.getInt32(c_, &vr, 1, &y, 1), "fmi3GetInt32", w); return y; }
    case VarType::UInt32: { fmi3UInt32 y = 0; check(lib_.getUInt32(c_, &vr, 1, &y, 1), "fmi3GetUInt32", w); return y; }
    case VarType::Enumeration:
    case VarType::Int64: { fmi3Int64 y = 0; check(lib_.getInt64(c_, &vr, 1, &y, 1), "fmi3GetInt64", w); return static_cast<double>(y); }
    case VarType::UInt64: { fmi3UInt64 y = 0; check(lib_.getUInt64(c_, &vr, 1, &y, 1), "fmi3GetUInt64", w); return static_cast<double>(y); }
    case VarType::Boolean: { fmi3Boolean y = false; check(lib_.getBoolean(c_, &vr, 1, &y, 1), "fmi3GetBoolean", w); return y ? 1.0 : 0.0; }
    default:
      break;
  }
  throw FmuError(who() + ": '" + v.name + "' is a " + type_name(v.type) + " variable; it cannot be a number");
}

std::string Fmi3Instance::get_text(const Variable& v, const std::string& when) {
  const fmi3ValueReference vr = v.value_reference;
  const std::string w = "of '" + v.name + "' " + when;
  char buf[48];
  switch (v.type) {
    case VarType::String: {
      fmi3String y = nullptr;
      check(lib_.getString(c_, &vr, 1, &y, 1), "fmi3GetString", w);
      return y ? y : "";
    }
    case VarType::Binary: {
      std::size_t size = 0;
      fmi3Binary y = nullptr;
      check(lib_.getBinary(c_, &vr, 1, &size, &y, 1), "fmi3GetBinary", w);
      return y ? to_hex(y, size) : "";
    }
    case VarType::Int64:
    case VarType::Enumeration: {  // exactly, beyond 2^53 too
      fmi3Int64 y = 0;
      check(lib_.getInt64(c_, &vr, 1, &y, 1), "fmi3GetInt64", w);
      std::snprintf(buf, sizeof buf, "%lld", static_cast<long long>(y));
      return buf;
    }
    case VarType::UInt64: {
      fmi3UInt64 y = 0;
      check(lib_.getUInt64(c_, &vr, 1, &y, 1), "fmi3GetUInt64", w);
      std::snprintf(buf, sizeof buf, "%llu", static_cast<unsigned long long>(y));
      return buf;
    }
    default:
      std::snprintf(buf, sizeof buf, "%.17g", get_number(v, when));
      return buf;
  }
}

namespace {

template <typename T, typename Get>
std::vector<double> get_all(Get* get, fmi3Instance c, fmi3ValueReference vr, std::size_t n, fmi3Status* status) {
  std::unique_ptr<T[]> raw(new T[n]());  // not std::vector: vector<bool> has no data()
  *status = get(c, &vr, 1, raw.get(), n);
  return std::vector<double>(raw.get(), raw.get() + n);
}

template <typename T, typename Set>
fmi3Status set_all(Set* set, fmi3Instance c, fmi3ValueReference vr, const std::vector<double>& values) {
  std::unique_ptr<T[]> raw(new T[values.size()]());
  for (std::size_t i = 0; i < values.size(); ++i) raw[i] = static_cast<T>(values[i]);
  return set(c, &vr, 1, raw.get(), values.size());
}

}  // namespace

std::vector<double> Fmi3Instance::get_array(const Variable& v, std::size_t n, const std::string& when) {
  const fmi3ValueReference vr = v.value_reference;
  fmi3Status st = fmi3OK;
  std::vector<double> out;
  const char* fn = "";
  switch (v.type) {
    case VarType::Float32: out = get_all<fmi3Float32>(lib_.getFloat32, c_, vr, n, &st); fn = "fmi3GetFloat32"; break;
    case VarType::Real:
    case VarType::Float64: out = get_all<fmi3Float64>(lib_.getFloat64, c_, vr, n, &st); fn = "fmi3GetFloat64"; break;
    case VarType::Int8: out = get_all<fmi3Int8>(lib_.getInt8, c_, vr, n, &st); fn = "fmi3GetInt8"; break;
    case VarType::UInt8: out = get_all<fmi3UInt8>(lib_.getUInt8, c_, vr, n, &st); fn = "fmi3GetUInt8"; break;
    case VarType::Int16: out = get_all<fmi3Int16>(lib_.getInt16, c_, vr, n, &st); fn = "fmi3GetInt16"; break;
    case VarType::UInt16: out = get_all<fmi3UInt16>(lib_.getUInt16, c_, vr, n, &st); fn = "fmi3GetUInt16"; break;
    case VarType::Integer:
    case VarType::Int32: out = get_all<fmi3Int32>(lib_.getInt32, c_, vr, n, &st); fn = "fmi3GetInt32"; break;
    case VarType::UInt32: out = get_all<fmi3UInt32>(lib_.getUInt32, c_, vr, n, &st); fn = "fmi3GetUInt32"; break;
    case VarType::Enumeration:
    case VarType::Int64: out = get_all<fmi3Int64>(lib_.getInt64, c_, vr, n, &st); fn = "fmi3GetInt64"; break;
    case VarType::UInt64: out = get_all<fmi3UInt64>(lib_.getUInt64, c_, vr, n, &st); fn = "fmi3GetUInt64"; break;
    case VarType::Boolean: out = get_all<fmi3Boolean>(lib_.getBoolean, c_, vr, n, &st); fn = "fmi3GetBoolean"; break;
    default: throw FmuError(who() + ": '" + v.name + "' is a " + type_name(v.type) + " array; only numeric arrays are read");
  }
  check(st, fn, "of '" + v.name + "' (" + std::to_string(n) + " values) " + when);
  return out;
}

void Fmi3Instance::set_array(const Variable& v, const std::vector<double>& values, const std::string& when) {
  const fmi3ValueReference vr = v.value_reference;
  fmi3Status st = fmi3OK;
  const char* fn = "";
  switch (v.type) {
    case VarType::Float32: st = set_all<fmi3Float32>(lib_.setFloat32, c_, vr, values); fn = "fmi3SetFloat32"; break;
    case VarType::Real:
    case VarType::Float64: st = set_all<fmi3Float64>(lib_.setFloat64, c_, vr, values); fn = "fmi3SetFloat64"; break;
    case VarType::Int8: st = set_all<fmi3Int8>(lib_.setInt8, c_, vr, values); fn = "fmi3SetInt8"; break;
    case VarType::UInt8: st = set_all<fmi3UInt8>(lib_.setUInt8, c_, vr, values); fn = "fmi3SetUInt8"; break;
    case VarType::Int16: st = set_all<fmi3Int16>(lib_.setInt16, c_, vr, values); fn = "fmi3SetInt16"; break;
    case VarType::UInt16: st = set_all<fmi3UInt16>(lib_.setUInt16, c_, vr, values); fn = "fmi3SetUInt16"; break;
    case VarType::Integer:
    case VarType::Int32: st = set_all<fmi3Int32>(lib_.setInt32, c_, vr, values); fn = "fmi3SetInt32"; break;
    case VarType::UInt32: st = set_all<fmi3UInt32>(lib_.setUInt32, c_, vr, values); fn = "fmi3SetUInt32"; break;
    case VarType::Enumeration:
    case VarType::Int64: st = set_all<fmi3Int64>(lib_.setInt64, c_, vr, values); fn = "fmi3SetInt64"; break;
    case VarType::UInt64: st = set_all<fmi3UInt64>(lib_.setUInt64, c_, vr, values); fn = "fmi3SetUInt64"; break;
    case VarType::Boolean: st = set_all<fmi3Boolean>(lib_.setBoolean, c_, vr, values); fn = "fmi3SetBoolean"; break;
    default: throw FmuError(who() + ": '" + v.name + "' is a " + type_name(v.type) + " array; only numeric arrays are set");
  }
  check(st, fn, "of '" + v.name + "' (" + std::to_string(values.size()) + " values) " + when);
}

void Fmi3Instance::set_input_derivative(const Variable& v, int, double, const std::string&) {
  throw FmuError(who() + ": FMI 3.0 co-simulation has no input derivatives ('" + v.name + "')");
}

void Fmi3Instance::save_state() {
  if (!lib_.getFMUState) throw FmuError(who() + ": its binary has no fmi3GetFMUState");
  check(lib_.getFMUState(c_, &state_), "fmi3GetFMUState", "");
  if (!state_) throw FmuError(who() + ": fmi3GetFMUState returned fmi3OK but no state");
}

void Fmi3Instance::restore_state() {
  if (!state_) throw FmuError(who() + ": no FMU state saved to go back to");
  check(lib_.setFMUState(c_, state_), "fmi3SetFMUState", "");
}

std::string Fmi3Instance::serialize_state() {
  if (!lib_.has_serialize_functions()) throw FmuError(who() + ": its binary cannot serialize its state");
  fmi3FMUState s = nullptr;
  check(lib_.getFMUState(c_, &s), "fmi3GetFMUState", "(for a checkpoint)");
  if (!s) throw FmuError(who() + ": fmi3GetFMUState returned fmi3OK but no state");
  std::string bytes;
  try {
    std::size_t size = 0;
    check(lib_.serializedFMUStateSize(c_, s, &size), "fmi3SerializedFMUStateSize", "");
    bytes.assign(size, '\0');
    check(lib_.serializeFMUState(c_, s, reinterpret_cast<fmi3Byte*>(bytes.data()), size), "fmi3SerializeFMUState", "");
  } catch (...) {
    if (!failed_ && !fatal_) lib_.freeFMUState(c_, &s);
    throw;
  }
  check(lib_.freeFMUState(c_, &s), "fmi3FreeFMUState", "");
  return bytes;
}

void Fmi3Instance::deserialize_state(const std::string& bytes) {
  if (!lib_.has_serialize_functions()) throw FmuError(who() + ": its binary cannot deserialize a state");
  fmi3FMUState s = nullptr;
  check(lib_.deserializeFMUState(c_, reinterpret_cast<const fmi3Byte*>(bytes.data()), bytes.size(), &s),
        "fmi3DeserializeFMUState", "");
  if (!s) throw FmuError(who() + ": fmi3DeserializeFMUState returned fmi3OK but no state");
  const fmi3Status set = lib_.setFMUState(c_, s);
  lib_.freeFMUState(c_, &s);
  check(set, "fmi3SetFMUState", "(from a checkpoint)");
}

}  // namespace fmu
