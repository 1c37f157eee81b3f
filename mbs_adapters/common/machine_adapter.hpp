// The bus adapter of a machine model (machine.hpp): a thin layer mapping the machine onto
// signals, the same for every machine.
//   input   <body>_wrench  (wrench: force, torque about r, r; ground) on the coupled body
//   outputs <body>         (kinematics of the coupled body's frame)
//           the machine's scalars, in the order its adapter names them
// The machine config (its parameter file, --set applied) is amended by the master's
// participants.<name>.parameters at configure(); a wrench above the machine's limits is
// refused (InputError) with the state kept; steps repeat bit for bit from the snapshot; a
// checkpoint is the Simbody state. A machine's adapter is a MachineAdapterOf<its model> whose
// read(), scalars() and diagnostics() its adapter file defines (wheel_loader_adapter.cpp):
// read its config, name the coupled body and the scalars, sample them and the diagnostics.
#pragma once

#include <cosim/participant.hpp>
#include <yaml-cpp/yaml.h>

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "interval_average.hpp"
#include "machine.hpp"

namespace mbs {

class MachineAdapter : public cosim::Model {
 public:
  void configure(const YAML::Node& parameters, const cosim::RunInfo& run) final;
  cosim::Ports inputs() const final;
  cosim::Ports outputs() const final;
  cosim::Duration inner_step() const final { return inner_step_; }
  cosim::Signals initial_outputs() final;
  cosim::StepResult step(const cosim::StepInputs& in, bool want_average) final;
  bool can_repeat() const final { return true; }
  void save_snapshot() final { machine_->save_snapshot(); }
  void restore_snapshot() final { machine_->restore_snapshot(); }
  // The Simbody state (time, q, u, z) exactly, mbs_adapters/common/state_file.hpp.
  bool can_checkpoint() const final { return true; }
  void save_checkpoint(const std::string& path) final { machine_->save_state(path); }
  void load_checkpoint(const std::string& path) final;

  // Reads and checks a machine config without building the machine (a bad file is refused
  // before the process joins a session); raises cosim::config::ConfigError.
  void check(const YAML::Node& config) { read(config); }
  // The scalar output names in port order (known after configure).
  const std::vector<std::string>& scalar_names() const { return settings_.scalars; }

  // What a machine config says to the adapter.
  struct Settings {
    std::string body;                     // the coupled body's port; its input: body + "_wrench"
    double inner_step = 0;                // s
    double max_force = 0, max_torque = 0;  // limits on the wrench: N, N m about the body origin
    std::vector<std::string> scalars;     // scalar output names, the order of scalars()
  };

 protected:
  // machine_config: the machine config (its parameter file's layout, --set applied).
  explicit MachineAdapter(YAML::Node machine_config) : base_(std::move(machine_config)) {}

  // Reads and validates the config (raises cosim::config::ConfigError naming the key) and
  // keeps what build() needs.
  virtual Settings read(const YAML::Node& config) = 0;
  // Builds the machine that read() described at rest at t_start; may raise
  // std::invalid_argument or std::runtime_error (refused as a config error).
  virtual std::unique_ptr<Machine> build(double t_start) = 0;
  // The scalars now, in the order of Settings::scalars, and the step's diagnostics.
  virtual std::vector<double> scalars() const = 0;
  virtual std::vector<std::pair<std::string, double>> diagnostics() const = 0;

  const Machine& machine() const { return *machine_; }

 private:
  MachineSample sample() const;
  cosim::Signals to_signals(const MachineSample& s) const;
  void check_input(const cosim::StepInputs& in) const;

  YAML::Node base_;
  cosim::RunInfo run_;
  Settings settings_;
  std::string wrench_;
  cosim::Duration inner_step_{};
  std::unique_ptr<Machine> machine_;
};

// The adapter of one machine: ModelT is a Machine built as ModelT(parameters, t_start) from its
// ParametersT. The machine's adapter file defines read(), scalars() and diagnostics() for it
// (explicit specializations, declared in its header).
template <class ModelT, class ParametersT>
class MachineAdapterOf final : public MachineAdapter {
 public:
  explicit MachineAdapterOf(YAML::Node machine_config = YAML::Node(YAML::NodeType::Map))
      : MachineAdapter(std::move(machine_config)) {}
  const ModelT& model() const { return static_cast<const ModelT&>(machine()); }

 private:
  Settings read(const YAML::Node& config) override;
  std::unique_ptr<Machine> build(double t_start) override { return std::make_unique<ModelT>(p_, t_start); }
  std::vector<double> scalars() const override;
  std::vector<std::pair<std::string, double>> diagnostics() const override;

  ParametersT p_;
};

// main() of a machine adapter executable:
//   PROGRAM [CONFIG.yaml] [--set key=value ...] [--name NAME] [--bus URL] ...
// make(config) builds the adapter from the machine config (CONFIG.yaml, or the built-in
// defaults without one, with --set applied), which is checked before the process joins any
// session. default_name: the participant name without --name.
int serve_machine(int argc, char** argv, const std::string& program, const std::string& default_name,
                  const std::function<std::unique_ptr<MachineAdapter>(YAML::Node config)>& make);

}  // namespace mbs
