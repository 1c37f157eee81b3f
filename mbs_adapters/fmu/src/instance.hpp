// What fmu_adapter's model needs of one co-simulation instance, whatever the FMI version:
// Fmi2Instance (fmi2_instance.hpp) and Fmi3Instance (fmi3_instance.hpp) implement it. Every call
// is checked: a status other than OK or Warning raises FmuError naming the FMU, the instance, the
// function, the time and the FMU's last log messages.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "model_description.hpp"

namespace fmu {

// A value of any FMI type as the adapter moves it: numbers as double (64-bit integers exactly in
// int64/uint64 when they come from a start value), String as text, Binary as hex digits in text.
struct Scalar {
  double number = 0;
  std::string text;
  std::optional<long long> int64;
  std::optional<unsigned long long> uint64;
};

class FmuInstance {
 public:
  virtual ~FmuInstance() = default;
  // FMI 2.0: fmi2SetupExperiment and fmi2EnterInitializationMode; FMI 3.0:
  // fmi3EnterInitializationMode (which takes the same numbers).
  virtual void enter_initialization(double start, std::optional<double> tolerance, std::optional<double> stop) = 0;
  virtual void exit_initialization() = 0;
  // One doStep. Returns the time the FMU reached when it ended itself (FMI 2.0: fmi2Discard with
  // fmi2Terminated; FMI 3.0: terminateSimulation), nothing when the step completed.
  virtual std::optional<double> do_step(double t, double h) = 0;
  virtual void set(const Variable& v, const Scalar& value, const std::string& when) = 0;
  virtual double get_number(const Variable& v, const std::string& when) = 0;
  // String as text, Binary as lower-case hex digits, numbers as printed with full precision.
  virtual std::string get_text(const Variable& v, const std::string& when) = 0;
  // FMI 3.0 arrays (numeric types): all n values, row-major. FMI 2.0 has none.
  virtual std::vector<double> get_array(const Variable& v, std::size_t n, const std::string& when) {
    (void)n; (void)when;
    throw FmuError(who() + ": '" + v.name + "' is an array; arrays are FMI 3.0");
  }
  virtual void set_array(const Variable& v, const std::vector<double>& values, const std::string& when) {
    (void)values; (void)when;
    throw FmuError(who() + ": '" + v.name + "' is an array; arrays are FMI 3.0");
  }
  virtual bool can_set_input_derivatives() const = 0;
  virtual void set_input_derivative(const Variable& v, int order, double value, const std::string& when) = 0;
  virtual bool has_state_functions() const = 0;
  virtual bool has_serialize_functions() const = 0;
  virtual void save_state() = 0;
  virtual void restore_state() = 0;
  virtual std::string serialize_state() = 0;
  virtual void deserialize_state(const std::string& bytes) = 0;
  virtual bool terminated() const = 0;
  // "FMU 'X' (instance 'y')"
  virtual std::string who() const = 0;
};

}  // namespace fmu
