// The FMI 2.0 co-simulation life cycle shared by the project's FMUs: variable values by
// value reference, the calling-sequence checks of the standard (which call is allowed in
// which state), input derivatives, and the logger. A concrete FMU derives from Slave and
// supplies the model: what happens at initialization, in a step and when outputs are read.
// Errors are thrown as FmuError; the fmi2 functions (fmi2_functions.cpp) log the text
// through the environment's logger and return fmi2Error.
#pragma once

#include <cosim_fmi2.h>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "description.hpp"

namespace fmu_export {

struct FmuError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// A call out of sequence or with bad arguments that changed nothing: the instance stays usable.
struct SequenceError : FmuError {
  using FmuError::FmuError;
};

// Whole nanoseconds of `seconds` (time is counted in ns, as in the rest of the project, so steps
// and inner steps divide exactly), or FmuError "<what> = x s is not a whole number of
// nanoseconds" + hint.
std::int64_t whole_ns(double seconds, const std::string& what, const std::string& hint = "");

// The step of an fmi2DoStep(t, h) in whole ns, checked: t must be where the FMU is (`at_ns`) and,
// with `inner_ns` > 0, h a positive multiple of the inner step (parameter 'inner_step').
// Throws FmuError naming the argument.
std::int64_t step_ns(double t, double h, std::int64_t at_ns, std::int64_t inner_ns = 0);

enum class Mode { Instantiated, Initialization, Step, Terminated, Error };

// A saved FMU state: what a slave needs to go back, as an opaque object.
struct SavedState {
  virtual ~SavedState() = default;
};

class Slave {
 public:
  Slave(const Description& d, std::string instance_name, const fmi2CallbackFunctions& callbacks,
        bool logging_on);
  virtual ~Slave() = default;

  // --- calls from the fmi2 functions (they check the mode first) ---
  void setup_experiment(double start, std::optional<double> stop);
  void enter_initialization();
  void exit_initialization();
  void do_step(double t, double h);
  void terminate();
  void reset();
  void set_real(fmi2ValueReference vr, double value);
  void set_integer(fmi2ValueReference vr, int value);
  void set_string(fmi2ValueReference vr, const std::string& value);
  void set_input_derivative(fmi2ValueReference vr, int order, double value);
  double get_real(fmi2ValueReference vr);
  int get_integer(fmi2ValueReference vr);
  const std::string& get_string(fmi2ValueReference vr);
  std::unique_ptr<SavedState> save();
  void restore(const SavedState& s);

  Mode mode() const { return mode_; }
  void set_mode(Mode m) { mode_ = m; }
  const std::string& instance_name() const { return instance_; }
  const Description& description() const { return d_; }
  void set_logging(bool on) { logging_ = on; }
  // Errors always reach the logger; other messages only with logging on.
  void log(fmi2Status status, const char* category, const std::string& message) const;

 protected:
  // At fmi2ExitInitializationMode: parameters are final; validate them (FmuError naming the
  // parameter and the fix), build the model, make the outputs valid.
  virtual void initialize() = 0;
  // One communication step [t, t + h]; the inputs are their values at t, plus derivatives
  // where the master set them (input_derivative). time() is t; afterwards t + h.
  virtual void step(double t, double h) = 0;
  // Brings the outputs up to date with the state and the current inputs (before a get).
  virtual void update_outputs() {}
  virtual void on_terminate() {}
  // FMU state: the slave's own part of it (the base keeps values, derivatives, time).
  virtual std::shared_ptr<const void> save_model() const { return nullptr; }
  virtual void restore_model(const std::shared_ptr<const void>&) {}

  double& real(const std::string& name);
  double real(const std::string& name) const;
  int integer(const std::string& name) const;
  const std::string& string(const std::string& name) const;
  // The derivative of `order` (1..3) of a Real input set for the current step (0 if none).
  double input_derivative(const std::string& name, int order) const;
  // The highest derivative order set for any input this step (0: none).
  int input_derivative_order() const;
  double start_time() const { return start_; }
  std::optional<double> stop_time() const { return stop_; }
  double time() const { return t_; }

 private:
  struct Slot {
    const Variable* var;
    double real = 0;
    int integer = 0;
    std::string string;
  };
  Slot& slot(Type type, fmi2ValueReference vr, const char* function);
  Slot& slot(const std::string& name);
  const Slot& slot(const std::string& name) const;
  void check_settable(const Variable& v, const char* function) const;
  void load_start_values();

  const Description& d_;
  std::string instance_;
  fmi2CallbackFunctions callbacks_;
  bool logging_;
  Mode mode_ = Mode::Instantiated;
  double start_ = 0, t_ = 0;
  std::optional<double> stop_;
  std::map<std::pair<int, fmi2ValueReference>, Slot> slots_;
  // Input derivatives of the current step by value reference, orders 1..3.
  std::map<fmi2ValueReference, std::array<double, kMaxInputDerivativeOrder>> derivatives_;

  friend struct BaseState;
};

// Defined by each FMU: its slave for one fmi2Instantiate (throws FmuError to refuse).
std::unique_ptr<Slave> make_slave(const std::string& instance_name,
                                  const fmi2CallbackFunctions& callbacks, bool logging_on);

}  // namespace fmu_export
