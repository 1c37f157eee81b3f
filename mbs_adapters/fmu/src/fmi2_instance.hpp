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
#include "model_description.hpp"

namespace fmu {

class Fmi2Library {
 public:
  // Loads `so_path`; `fmu` names the FMU in messages. Raises FmuError when the file cannot be
  // loaded or a required function is missing (optional ones: the FMU state functions, checked
  // by the caller through has_state_functions()).
  Fmi2Library(const std::string& so_path, const std::string& fmu);
  ~Fmi2Library();
  Fmi2Library(const Fmi2Library&) = delete;
  Fmi2Library& operator=(const Fmi2Library&) = delete;

  bool has_state_functions() const { return getFMUstate && setFMUstate && freeFMUstate; }

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
  fmi2SetRealInputDerivativesTYPE* setRealInputDerivatives = nullptr;  // optional

 private:
  void* handle_ = nullptr;
};

// A value of any FMI type as the adapter moves it: numbers as double, strings as text.
struct Scalar {
  double number = 0;
  std::string text;
};

class Fmi2Instance {
 public:
  // Instantiates a co-simulation instance. `resources_uri` is the file:// URI of the unpacked
  // resources folder. Messages the FMU logs go to `sink` (one line each) and the last few are
  // kept for error messages; `verbose` also passes on messages with status fmi2OK.
  Fmi2Instance(Fmi2Library& lib, const ModelDescription& md, const std::string& fmu_label,
               const std::string& instance_name, const std::string& resources_uri, bool verbose,
               std::function<void(const std::string&)> sink);
  ~Fmi2Instance();
  Fmi2Instance(const Fmi2Instance&) = delete;
  Fmi2Instance& operator=(const Fmi2Instance&) = delete;

  void setup_experiment(double start, std::optional<double> tolerance, std::optional<double> stop);
  void enter_initialization();
  void exit_initialization();
  void do_step(double t, double h);
  // The `order`-th time derivative of a Real input for the next doStep (canInterpolateInputs).
  void set_input_derivative(const Variable& v, int order, double value, const std::string& when);
  // Values by variable; the type decides the FMI function.
  void set(const Variable& v, const Scalar& value, const std::string& when);
  double get_number(const Variable& v, const std::string& when);
  void get_numbers(const std::vector<const Variable*>& vars, std::vector<double>& out,
                   const std::string& when);
  void save_state();
  void restore_state();
  bool has_state() const { return state_ != nullptr; }

  const std::string& label() const { return label_; }
  // "FMU 'X' (instance 'y')"
  std::string who() const;
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
  std::deque<std::string> recent_;  // the FMU's last log messages
};

const char* status_name(fmi2Status s);

}  // namespace fmu
