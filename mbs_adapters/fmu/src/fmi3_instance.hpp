// An FMI 3.0 co-simulation FMU's shared library (binaries/x86_64-linux/<modelIdentifier>.so) and
// one instance of it (fmi3InstantiateCoSimulation). The adapter uses no event mode
// (eventModeUsed = false: the FMU handles its events inside fmi3DoStep), no early return
// (earlyReturnAllowed = false) and no intermediate update callback, which every co-simulation
// FMU must accept (FMI 3.0, 4.2.1). Every call is checked as in Fmi2Instance.
#pragma once

#include <deque>
#include <functional>
#include <optional>
#include <string>

#include "cosim_fmi3.h"
#include "instance.hpp"
#include "shared_library.hpp"
#include "model_description.hpp"

namespace fmu {

class Fmi3Library {
 public:
  Fmi3Library(const std::string& so_path, const std::string& fmu);
  Fmi3Library(const Fmi3Library&) = delete;
  Fmi3Library& operator=(const Fmi3Library&) = delete;

  bool has_state_functions() const { return getFMUState && setFMUState && freeFMUState; }
  bool has_serialize_functions() const {
    return has_state_functions() && serializedFMUStateSize && serializeFMUState && deserializeFMUState;
  }

  fmi3GetVersionTYPE* getVersion = nullptr;
  fmi3InstantiateCoSimulationTYPE* instantiate = nullptr;
  fmi3FreeInstanceTYPE* freeInstance = nullptr;
  fmi3EnterInitializationModeTYPE* enterInitializationMode = nullptr;
  fmi3ExitInitializationModeTYPE* exitInitializationMode = nullptr;
  fmi3EnterConfigurationModeTYPE* enterConfigurationMode = nullptr;
  fmi3ExitConfigurationModeTYPE* exitConfigurationMode = nullptr;
  fmi3TerminateTYPE* terminate = nullptr;
  fmi3DoStepTYPE* doStep = nullptr;
  fmi3GetFloat32TYPE* getFloat32 = nullptr;
  fmi3SetFloat32TYPE* setFloat32 = nullptr;
  fmi3GetFloat64TYPE* getFloat64 = nullptr;
  fmi3SetFloat64TYPE* setFloat64 = nullptr;
  fmi3GetInt8TYPE* getInt8 = nullptr;
  fmi3SetInt8TYPE* setInt8 = nullptr;
  fmi3GetUInt8TYPE* getUInt8 = nullptr;
  fmi3SetUInt8TYPE* setUInt8 = nullptr;
  fmi3GetInt16TYPE* getInt16 = nullptr;
  fmi3SetInt16TYPE* setInt16 = nullptr;
  fmi3GetUInt16TYPE* getUInt16 = nullptr;
  fmi3SetUInt16TYPE* setUInt16 = nullptr;
  fmi3GetInt32TYPE* getInt32 = nullptr;
  fmi3SetInt32TYPE* setInt32 = nullptr;
  fmi3GetUInt32TYPE* getUInt32 = nullptr;
  fmi3SetUInt32TYPE* setUInt32 = nullptr;
  fmi3GetInt64TYPE* getInt64 = nullptr;
  fmi3SetInt64TYPE* setInt64 = nullptr;
  fmi3GetUInt64TYPE* getUInt64 = nullptr;
  fmi3SetUInt64TYPE* setUInt64 = nullptr;
  fmi3GetBooleanTYPE* getBoolean = nullptr;
  fmi3SetBooleanTYPE* setBoolean = nullptr;
  fmi3GetStringTYPE* getString = nullptr;
  fmi3SetStringTYPE* setString = nullptr;
  fmi3GetBinaryTYPE* getBinary = nullptr;
  fmi3SetBinaryTYPE* setBinary = nullptr;
  fmi3GetFMUStateTYPE* getFMUState = nullptr;  // optional from here on
  fmi3SetFMUStateTYPE* setFMUState = nullptr;
  fmi3FreeFMUStateTYPE* freeFMUState = nullptr;
  fmi3SerializedFMUStateSizeTYPE* serializedFMUStateSize = nullptr;
  fmi3SerializeFMUStateTYPE* serializeFMUState = nullptr;
  fmi3DeserializeFMUStateTYPE* deserializeFMUState = nullptr;

 private:
  SharedLibrary lib_;  // the binary the functions above point into
};

class Fmi3Instance final : public FmuInstance {
 public:
  // resource_path: the unpacked resources folder as a native path with a trailing '/' (FMI 3.0
  // takes a path, not a URI).
  Fmi3Instance(Fmi3Library& lib, const ModelDescription& md, const std::string& fmu_label,
               const std::string& instance_name, const std::string& resource_path, bool verbose,
               std::function<void(const std::string&)> sink);
  ~Fmi3Instance() override;
  Fmi3Instance(const Fmi3Instance&) = delete;
  Fmi3Instance& operator=(const Fmi3Instance&) = delete;

  // Structural parameters are set between these two (fmi3EnterConfigurationMode).
  void enter_configuration();
  void exit_configuration();
  void enter_initialization(double start, std::optional<double> tolerance, std::optional<double> stop) override;
  void exit_initialization() override;
  std::optional<double> do_step(double t, double h) override;
  void set(const Variable& v, const Scalar& value, const std::string& when) override;
  double get_number(const Variable& v, const std::string& when) override;
  std::string get_text(const Variable& v, const std::string& when) override;
  std::vector<double> get_array(const Variable& v, std::size_t n, const std::string& when) override;
  void set_array(const Variable& v, const std::vector<double>& values, const std::string& when) override;
  bool can_set_input_derivatives() const override { return false; }
  void set_input_derivative(const Variable& v, int order, double value, const std::string& when) override;
  bool has_state_functions() const override { return lib_.has_state_functions(); }
  bool has_serialize_functions() const override { return lib_.has_serialize_functions(); }
  void save_state() override;
  void restore_state() override;
  std::string serialize_state() override;
  void deserialize_state(const std::string& bytes) override;
  bool terminated() const override { return terminated_; }
  std::string who() const override;
  void log(fmi3Status status, const char* category, const std::string& message);

 private:
  void check(fmi3Status status, const char* function, const std::string& when);

  Fmi3Library& lib_;
  std::string label_, instance_name_;
  bool verbose_;
  std::function<void(const std::string&)> sink_;
  fmi3Instance c_ = nullptr;
  fmi3FMUState state_ = nullptr;
  bool initialized_ = false;
  bool fatal_ = false;
  bool failed_ = false;
  bool terminated_ = false;
  std::deque<std::string> recent_;
};

const char* status_name(fmi3Status s);

}  // namespace fmu
