// fmu_adapter's model: an FMI 2.0 or 3.0 co-simulation FMU as a participant. The mapping (YAML, keys
// in docs/fmi.md) names the FMU, its start values and parameters, and the ports: groups of FMU
// variables that make up a scalar, a kinematics (pose and twist) or a wrench signal.
#pragma once

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "archive.hpp"
#include "cosim/participant.hpp"
#include "euler.hpp"
#include "fmi2_instance.hpp"
#include "fmi3_instance.hpp"
#include "model_description.hpp"

namespace fmu {

// One number of a port: an FMU variable, a constant, or (inputs) nothing.
struct Component {
  const Variable* var = nullptr;
  double constant = 0;
  // A scalar port's unit conversion (SSP connections, or the mapping's factor/offset): an input
  // sets factor * received + offset, an output sends factor * FMU value + offset.
  double factor = 1, offset = 0;
  // FMI 3.0 arrays: the element (row-major, from 0) of `var` this component is; -1: a scalar.
  long long element = -1;
};
using Vec3Map = std::array<Component, 3>;

enum class OrientationMap { Identity, Quaternion, Angles };

struct PortMap {
  std::string name;
  cosim::SignalKind kind = cosim::SignalKind::Scalar;
  bool input = false;
  std::string path;  // its dotted key, for messages
  Component scalar;
  // kinematics
  Vec3Map position, velocity, angular_velocity;
  OrientationMap orientation = OrientationMap::Identity;
  std::array<Component, 4> quaternion;
  std::array<Component, 3> angles;
  EulerSequence sequence;
  bool angular_velocity_in_body = false;
  // wrench
  Vec3Map force, torque, point;
  std::string frame_port;  // "" = ground axes, else the kinematics port whose body axes
  std::string point_port;  // "" = `point`, else the kinematics port whose position
  // A wrench input whose reference_point names three FMU inputs: the received point is set
  // there and the torque passed about it unshifted.
  bool point_is_input = false;
};

class FmuModel final : public cosim::Model {
 public:
  // root: the adapter's config (mapping) after --set, possibly empty; base_dir resolves its
  // relative paths. The master's parameters amend it in configure().
  FmuModel(YAML::Node root, std::string base_dir);
  ~FmuModel() override;

  // Unpacks and loads the FMU and checks the mapping against it, without instantiating:
  // what configure() does first. Raises FmuError or config::ConfigError naming the key: under
  // "participants.<participant>.parameters", or (own_file, the check at start-up) as written in
  // the adapter's own file.
  void prepare(const YAML::Node& parameters, const std::string& participant, bool own_file = false);

  void configure(const YAML::Node& parameters, const cosim::RunInfo& run) override;
  cosim::Ports inputs() const override;
  cosim::Ports outputs() const override;
  cosim::Duration inner_step() const override { return inner_step_; }
  cosim::Signals initial_outputs() override;
  cosim::StepResult step(const cosim::StepInputs& in, bool want_average) override;
  bool can_repeat() const override;
  std::string repeat_note() const override;
  void save_snapshot() override;
  void restore_snapshot() override;
  // Checkpoints for --resume: the FMU's serialized state (canSerializeFMUstate) and what the
  // adapter itself carries from step to step.
  bool can_checkpoint() const override;
  void save_checkpoint(const std::string& path) override;
  void load_checkpoint(const std::string& path) override;

  const ModelDescription& description() const { return *md_; }
  // A variable's current value as text (String, Binary as hex, 64-bit integers exactly), after
  // configure(): for tests and diagnostics; raises FmuError for an unknown name.
  std::string value_text(const std::string& variable);
  // "<file name> (model '<modelName>')", as messages name the FMU
  const std::string& label() const { return label_; }

 private:
  std::string state_attribute() const;  // canGetAndSetFMUstate (2.0) or canGetAndSetFMUState (3.0)
  std::string serialize_attribute() const {
    return md_ && md_->fmi_major == 3 ? "canSerializeFMUState" : "canSerializeFMUstate";
  }
  void configure_instance(const YAML::Node& parameters, const cosim::RunInfo& run);
  void parse_mapping(const YAML::Node& root, const std::string& path);
  PortMap parse_port(const YAML::Node& node, const std::string& path, bool input);
  Component output_component(const YAML::Node& node, const std::string& path) const;
  Component input_component(const YAML::Node& node, const std::string& path) const;
  const Variable& variable(const std::string& name, const std::string& path) const;
  // Checks every start value against the model description (name, causality, type, range) and
  // keeps it for set_start_values(); raises config::ConfigError naming the key.
  void check_start_values(const YAML::Node& start, const std::string& path);
  void set_start_values();

  cosim::Kinematics kinematics_of(const std::string& port, const std::string& when);
  cosim::Value read_output(const PortMap& p, const std::string& when);
  void write_input(const PortMap& p, const cosim::Value& v, const std::string& when);
  void write_input_derivatives(const cosim::StepInputs& in, cosim::TimePoint t, const std::string& when);
  double read(const Component& c, const std::string& when);
  double array_element(const Component& c, const std::string& when);
  void write(const Component& c, double value, const PortMap& p, const std::string& when);
  cosim::Signals read_outputs(const std::string& when);

  YAML::Node root_;
  std::string base_dir_;
  std::string participant_ = "fmu";
  std::string prepared_yaml_;  // the mapping prepare() saw, so configure() reuses the FMU
  // Destroyed in reverse: instance, library, unpacked folder.
  std::unique_ptr<UnpackedFmu> unpacked_;
  std::unique_ptr<ModelDescription> md_;
  std::unique_ptr<Fmi2Library> lib_;   // FMI 2.0
  std::unique_ptr<Fmi3Library> lib3_;  // FMI 3.0
  std::unique_ptr<FmuInstance> inst_;
  bool lib_state_ = false, lib_serialize_ = false;  // the binary has the FMU-state functions
  std::string label_;
  std::string fmu_path_;
  std::string instance_name_;
  std::optional<double> step_size_s_;
  long long substeps_ = 0;
  std::optional<double> tolerance_;
  bool verbose_ = false;
  bool snapshots_ = true;
  bool input_derivatives_ = true;  // mapping key input_derivatives
  int max_derivative_order_ = 0;   // highest input derivative order set so far
  YAML::Node start_;
  struct StartValue {
    const Variable* var;
    Scalar value;
    std::string key;
    std::vector<double> array;  // an array's values, row-major (FMI 3.0)
  };
  // A variable by name, or an array element "name[i]" / "name[i,j]" (1-based, as written);
  // element: its row-major index from 0, -1 for a whole variable.
  const Variable& element_variable(const std::string& name, const std::string& path, long long* element) const;
  // The number of values of an FMI 3.0 array now: fixed dimensions, or the structural
  // parameter's value (from the instance once it exists, else its start value).
  std::size_t array_size(const Variable& v) const;
  std::vector<std::size_t> array_dims(const Variable& v) const;
  std::vector<StartValue> start_values_;
  std::vector<PortMap> inputs_, outputs_;
  cosim::Duration inner_step_{};
  std::map<std::string, cosim::Kinematics> received_;  // kinematics inputs last set
};

}  // namespace fmu
