// The FMU's shared library (binaries/linux64/<modelIdentifier>.so) and one co-simulation
// instance of it. Every FMI call goes through a checked wrapper: fmi2Warning is passed on to the
// log, fmi2Discard, fmi2Error, fmi2Fatal and fmi2Pending raise FmuError naming the FMU, the
// instance, the function, the time and the FMU's last log messages.
#pragma once

#include <deque>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "cosim_fmi2.h"
#include "instance.hpp"
#include "shared_library.hpp"
#include "model_description.hpp"

namespace fmu {

class Fmi2Library {
 public:
  // Loads `so_path`; `fmu` names the FMU in messages. Raises FmuError when the file cannot be
  // loaded or a required function is missing (optional ones: the FMU state functions, checked
  // by the caller through has_state_functions()).
  Fmi2Library(const std::string& so_path, const std::string& fmu);
  Fmi2Library(const Fmi2Library&) = delete;
  Fmi2Library& operator=(const Fmi2Library&) = delete;

  bool has_state_functions() const { return getFMUstate && setFMUstate && freeFMUstate; }
  bool has_serialize_functions() const {
    return has_state_functions() && serializedFMUstateSize && serializeFMUstate && deSerializeFMUstate;
  }

  fmi2GetTypesPlatformTYPE* getTypesPlatform = nullptr;
  fmi2GetVersionTYPE* getVersion = nullptr;
  fmi2SetDebugLoggingTYPE* setDebugLogging = nullptr;
  fmi2InstantiateTYPE* instantiate = nullptr;
  fmi2FreeInstanceTYPE* freeInstance = nullptr;
  fmi2SetupExperimentTYPE* setupExperiment = nullptr;
  fmi2EnterInitializationModeTYPE* enterInitializationMode = nullptr;
  fmi2ExitInitializationModeTYPE* exitInitializationMode = nullptr;
  fmi2TerminateTYPE* terminate = nullptr;
  fmi2GetRealTYPE* getReal = nullptr;
  fmi2GetIntegerTYPE* getInteger = nullptr;
  fmi2GetBooleanTYPE* getBoolean = nullptr;
  fmi2GetStringTYPE* getString = nullptr;
  fmi2SetRealTYPE* setReal = nullptr;
  fmi2SetIntegerTYPE* setInteger = nullptr;
  fmi2SetBooleanTYPE* setBoolean = nullptr;
  fmi2SetStringTYPE* setString = nullptr;
  fmi2GetFMUstateTYPE* getFMUstate = nullptr;
  fmi2SetFMUstateTYPE* setFMUstate = nullptr;
  fmi2FreeFMUstateTYPE* freeFMUstate = nullptr;
  fmi2DoStepTYPE* doStep = nullptr;
  fmi2GetStatusTYPE* getStatus = nullptr;
  fmi2GetRealStatusTYPE* getRealStatus = nullptr;
  fmi2GetBooleanStatusTYPE* getBooleanStatus = nullptr;
  fmi2SerializedFMUstateSizeTYPE* serializedFMUstateSize = nullptr;  // optional, with the next two
  fmi2SerializeFMUstateTYPE* serializeFMUstate = nullptr;
  fmi2DeSerializeFMUstateTYPE* deSerializeFMUstate = nullptr;
  fmi2SetRealInputDerivativesTYPE* setRealInputDerivatives = nullptr;  // optional

 private:
  SharedLibrary lib_;  // the binary the functions above point into
};

class Fmi2Instance final : public FmuInstance {
 public:
  // Instantiates a co-simulation instance. `resources_uri` is the file:// URI of the unpacked
  // resources folder. Messages the FMU logs go to `sink` (one line each) and the last few are
  // kept for error messages; `verbose` also passes on messages with status fmi2OK.
  Fmi2Instance(Fmi2Library& lib, const ModelDescription& md, const std::string& fmu_label,
               const std::string& instance_name, const std::string& resources_uri, bool verbose,
               std::function<void(const std::string&)> sink);
  ~Fmi2Instance() override;
  Fmi2Instance(const Fmi2Instance&) = delete;
  Fmi2Instance& operator=(const Fmi2Instance&) = delete;

  void enter_initialization(double start, std::optional<double> tolerance, std::optional<double> stop) override;
  void exit_initialization() override;
  // One fmi2DoStep. Returns the time the FMU reached when it ended itself (fmi2Discard with
  // fmi2GetBooleanStatus(fmi2Terminated) true: the time is fmi2GetRealStatus(fmi2LastSuccessfulTime));
  // nothing when the step completed. Any other failure raises FmuError.
  std::optional<double> do_step(double t, double h) override;
  bool terminated() const override { return terminated_; }
  // The FMU state serialized (fmi2SerializeFMUstate of a fresh fmi2GetFMUstate) and back.
  std::string serialize_state() override;
  void deserialize_state(const std::string& bytes) override;
  bool has_state_functions() const override { return lib_.has_state_functions(); }
  bool has_serialize_functions() const override { return lib_.has_serialize_functions(); }
  bool can_set_input_derivatives() const override { return lib_.setRealInputDerivatives != nullptr; }
  std::string get_text(const Variable& v, const std::string& when) override;
  // The `order`-th time derivative of a Real input for the next doStep (canInterpolateInputs).
  void set_input_derivative(const Variable& v, int order, double value, const std::string& when) override;
  // Values by variable; the type decides the FMI function.
  void set(const Variable& v, const Scalar& value, const std::string& when) override;
  double get_number(const Variable& v, const std::string& when) override;
  void get_numbers(const std::vector<const Variable*>& vars, std::vector<double>& out,
                   const std::string& when);
  void save_state() override;
  void restore_state() override;
  bool has_state() const { return state_ != nullptr; }

  const std::string& label() const { return label_; }
  // "FMU 'X' (instance 'y')"
  std::string who() const override;
  // Called by the logger callback.
  void log(fmi2Status status, const char* category, const std::string& message);

 private:
  // Raises FmuError unless status is fmi2OK or fmi2Warning.
  void check(fmi2Status status, const char* function, const std::string& when);

  Fmi2Library& lib_;
  std::string label_, instance_name_;
  bool verbose_;
  std::function<void(const std::string&)> sink_;
  fmi2CallbackFunctions callbacks_{};
  fmi2Component c_ = nullptr;
  fmi2FMUstate state_ = nullptr;
  bool initialized_ = false;
  bool fatal_ = false;   // after fmi2Fatal no call is allowed, not even fmi2FreeInstance
  bool failed_ = false;  // after fmi2Error only fmi2FreeInstance (and reset) are allowed
  bool terminated_ = false;  // the FMU ended itself (fmi2Terminated): no further doStep
  std::deque<std::string> recent_;  // the FMU's last log messages
};

const char* status_name(fmi2Status s);

}  // namespace fmu
