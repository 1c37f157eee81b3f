// The FMI 2.0 co-simulation functions every FMU of this project exports (C linkage, default
// visibility; everything else in the shared library is hidden, cmake/Fmu.cmake). Each
// function checks its arguments, calls the Slave, and turns an FmuError into a message
// through the environment's logger and fmi2Error.
#include <cosim_fmi2.h>

#include <cstring>
#include <exception>
#include <new>

#include "slave.hpp"

#define FMI2_EXPORT extern "C" __attribute__((visibility("default")))

using fmu_export::FmuError;
using fmu_export::Mode;
using fmu_export::Slave;

namespace {

Slave* slave_of(fmi2Component c) { return static_cast<Slave*>(c); }

// Runs `f` for the instance; errors become fmi2Error with the reason in the log. Errors in
// initialization and in a step leave the instance in error (the standard's undefined state),
// the others (a wrong value reference, a call out of sequence) do not.
template <class F>
fmi2Status guarded(fmi2Component c, const char* function, bool breaks_instance, F&& f) {
  Slave* s = slave_of(c);
  if (!s) return fmi2Error;
  try {
    return f(*s);
  } catch (const fmu_export::SequenceError& e) {
    s->log(fmi2Error, "logStatusError", e.what());
    return fmi2Error;
  } catch (const FmuError& e) {
    s->log(fmi2Error, "logStatusError", e.what());
  } catch (const std::bad_alloc&) {
    s->log(fmi2Fatal, "logStatusError", std::string(function) + ": out of memory");
    s->set_mode(Mode::Error);
    return fmi2Fatal;
  } catch (const std::exception& e) {
    s->log(fmi2Error, "logStatusError", std::string(function) + ": " + e.what());
  }
  if (breaks_instance) s->set_mode(Mode::Error);
  return fmi2Error;
}

template <class T>
fmi2Status check_arrays(Slave& s, const char* function, const fmi2ValueReference vr[], size_t nvr, T values) {
  if (nvr > 0 && (!vr || !values)) {
    s.log(fmi2Error, "logStatusError", std::string(function) + ": null array for " + std::to_string(nvr) + " value(s)");
    return fmi2Error;
  }
  return fmi2OK;
}

}  // namespace

FMI2_EXPORT const char* fmi2GetTypesPlatform(void) { return COSIM_FMI2_TYPES_PLATFORM; }
FMI2_EXPORT const char* fmi2GetVersion(void) { return COSIM_FMI2_VERSION; }

FMI2_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                          fmi2String fmuResourceLocation,
                                          const fmi2CallbackFunctions* functions, fmi2Boolean visible,
                                          fmi2Boolean loggingOn) {
  if (!functions) return nullptr;
  const auto& d = fmu_export::description();
  const std::string name = instanceName ? instanceName : "";
  auto refuse = [&](const std::string& why) -> fmi2Component {
    if (functions->logger)
      functions->logger(functions->componentEnvironment, name.c_str(), fmi2Error, "logStatusError",
                        "%s", why.c_str());
    return nullptr;
  };
  if (name.empty()) return refuse("fmi2Instantiate: " + d.model_identifier + ": the instance name is empty");
  if (fmuType != fmi2CoSimulation)
    return refuse("fmi2Instantiate: " + d.model_identifier +
                  " is a co-simulation FMU only; model exchange is not supported");
  if (!fmuGUID || d.guid() != fmuGUID)
    return refuse("fmi2Instantiate: GUID " + std::string(fmuGUID ? fmuGUID : "(null)") +
                  " does not match this binary's " + d.guid() +
                  ": the modelDescription.xml and binaries/linux64/" + d.model_identifier +
                  ".so come from different builds; rebuild the FMU");
  try {
    return fmu_export::make_slave(name, *functions, loggingOn == fmi2True).release();
  } catch (const std::exception& e) {
    return refuse(std::string("fmi2Instantiate: ") + e.what());
  }
}

FMI2_EXPORT void fmi2FreeInstance(fmi2Component c) {
  Slave* s = slave_of(c);
  if (!s) return;
  if (s->mode() == Mode::Step || s->mode() == Mode::Error) {
    try {
      s->terminate();
    } catch (const std::exception& e) {
      s->log(fmi2Warning, "logStatusWarning", std::string("fmi2FreeInstance: ") + e.what());
    }
  }
  delete s;
}

FMI2_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t, const fmi2String[]) {
  return guarded(c, "fmi2SetDebugLogging", false, [&](Slave& s) {
    s.set_logging(loggingOn == fmi2True);
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real,
                                           fmi2Real startTime, fmi2Boolean stopTimeDefined,
                                           fmi2Real stopTime) {
  return guarded(c, "fmi2SetupExperiment", false, [&](Slave& s) {
    s.setup_experiment(startTime, stopTimeDefined == fmi2True ? std::optional<double>(stopTime) : std::nullopt);
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
  return guarded(c, "fmi2EnterInitializationMode", false, [&](Slave& s) {
    s.enter_initialization();
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
  return guarded(c, "fmi2ExitInitializationMode", true, [&](Slave& s) {
    s.exit_initialization();
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
  return guarded(c, "fmi2Terminate", false, [&](Slave& s) {
    s.terminate();
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2Reset(fmi2Component c) {
  return guarded(c, "fmi2Reset", false, [&](Slave& s) {
    s.reset();
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
  return guarded(c, "fmi2GetReal", false, [&](Slave& s) {
    if (check_arrays(s, "fmi2GetReal", vr, nvr, value) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) value[i] = s.get_real(vr[i]);
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
  return guarded(c, "fmi2GetInteger", false, [&](Slave& s) {
    if (check_arrays(s, "fmi2GetInteger", vr, nvr, value) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) value[i] = s.get_integer(vr[i]);
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean[]) {
  return guarded(c, "fmi2GetBoolean", false, [&](Slave& s) {
    if (nvr == 0) return fmi2OK;
    throw FmuError("fmi2GetBoolean: " + s.description().model_identifier + " has no Boolean variables (value reference " + std::to_string(vr ? vr[0] : 0) + ")");
    return fmi2Error;
  });
}

FMI2_EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
  return guarded(c, "fmi2GetString", false, [&](Slave& s) {
    if (check_arrays(s, "fmi2GetString", vr, nvr, value) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) value[i] = s.get_string(vr[i]).c_str();
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
  return guarded(c, "fmi2SetReal", false, [&](Slave& s) {
    if (check_arrays(s, "fmi2SetReal", vr, nvr, value) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) s.set_real(vr[i], value[i]);
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
  return guarded(c, "fmi2SetInteger", false, [&](Slave& s) {
    if (check_arrays(s, "fmi2SetInteger", vr, nvr, value) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) s.set_integer(vr[i], value[i]);
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean[]) {
  return guarded(c, "fmi2SetBoolean", false, [&](Slave& s) {
    if (nvr == 0) return fmi2OK;
    throw FmuError("fmi2SetBoolean: " + s.description().model_identifier + " has no Boolean variables (value reference " + std::to_string(vr ? vr[0] : 0) + ")");
    return fmi2Error;
  });
}

FMI2_EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
  return guarded(c, "fmi2SetString", false, [&](Slave& s) {
    if (check_arrays(s, "fmi2SetString", vr, nvr, value) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) {
      if (!value[i]) throw FmuError("fmi2SetString: null string for value reference " + std::to_string(vr[i]));
      s.set_string(vr[i], value[i]);
    }
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* state) {
  return guarded(c, "fmi2GetFMUstate", false, [&](Slave& s) {
    if (!state) throw FmuError("fmi2GetFMUstate: null FMUstate pointer");
    auto saved = s.save();
    // A non-null *state is an earlier state of ours that the master wants overwritten.
    delete static_cast<fmu_export::SavedState*>(*state);
    *state = saved.release();
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
  return guarded(c, "fmi2SetFMUstate", false, [&](Slave& s) {
    if (!state) throw FmuError("fmi2SetFMUstate: null FMUstate");
    s.restore(*static_cast<const fmu_export::SavedState*>(state));
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* state) {
  return guarded(c, "fmi2FreeFMUstate", false, [&](Slave&) {
    if (state) {
      delete static_cast<fmu_export::SavedState*>(*state);
      *state = nullptr;
    }
    return fmi2OK;
  });
}

namespace {
fmi2Status unsupported(fmi2Component c, const std::string& what) {
  return guarded(c, what.c_str(), false, [&](Slave& s) -> fmi2Status {
    throw FmuError(what + ": not supported by " + s.description().model_identifier + " (see its modelDescription.xml)");
  });
}
}  // namespace

FMI2_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate, size_t*) {
  return unsupported(c, "fmi2SerializedFMUstateSize (canSerializeFMUstate=\"false\")");
}
FMI2_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate, fmi2Byte[], size_t) {
  return unsupported(c, "fmi2SerializeFMUstate (canSerializeFMUstate=\"false\")");
}
FMI2_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte[], size_t, fmi2FMUstate*) {
  return unsupported(c, "fmi2DeSerializeFMUstate (canSerializeFMUstate=\"false\")");
}
FMI2_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference[], size_t,
                                                    const fmi2ValueReference[], size_t, const fmi2Real[], fmi2Real[]) {
  return unsupported(c, "fmi2GetDirectionalDerivative (providesDirectionalDerivative=\"false\")");
}

FMI2_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[], const fmi2Real value[]) {
  return guarded(c, "fmi2SetRealInputDerivatives", false, [&](Slave& s) {
    if (check_arrays(s, "fmi2SetRealInputDerivatives", vr, nvr, value) != fmi2OK || (nvr > 0 && !order))
      return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) s.set_input_derivative(vr[i], order[i], value[i]);
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference[], size_t,
                                                    const fmi2Integer[], fmi2Real[]) {
  return unsupported(c, "fmi2GetRealOutputDerivatives (maxOutputDerivativeOrder=\"0\")");
}

FMI2_EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                                  fmi2Real communicationStepSize, fmi2Boolean) {
  return guarded(c, "fmi2DoStep", true, [&](Slave& s) {
    s.do_step(currentCommunicationPoint, communicationStepSize);
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2CancelStep(fmi2Component c) {
  return unsupported(c, "fmi2CancelStep (steps are synchronous: canRunAsynchronuously=\"false\")");
}

FMI2_EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Status* value) {
  return guarded(c, "fmi2GetStatus", false, [&](Slave&) {
    if (kind != fmi2DoStepStatus || !value) return fmi2Discard;
    *value = fmi2OK;  // doStep is synchronous: it has finished when this can be asked
    return fmi2OK;
  });
}

FMI2_EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind, fmi2Real*) {
  return guarded(c, "fmi2GetRealStatus", false, [&](Slave&) { return fmi2Discard; });
}
FMI2_EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind, fmi2Integer*) {
  return guarded(c, "fmi2GetIntegerStatus", false, [&](Slave&) { return fmi2Discard; });
}
FMI2_EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Boolean* value) {
  return guarded(c, "fmi2GetBooleanStatus", false, [&](Slave&) {
    if (kind != fmi2Terminated || !value) return fmi2Discard;
    *value = fmi2False;  // the FMU never asks to end the simulation
    return fmi2OK;
  });
}
FMI2_EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind, fmi2String*) {
  return guarded(c, "fmi2GetStringStatus", false, [&](Slave&) { return fmi2Discard; });
}
