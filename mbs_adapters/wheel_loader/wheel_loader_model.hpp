// The bus adapter around the wheel-loader model: a thin layer mapping the model onto signals.
//   input   bucket_wrench  (wrench: force, torque about r, r; ground)
//   outputs bucket         (kinematics of the bucket frame: origin = A-pin)
//           a_long a_vert j_long j_vert   section forces on the bucket, bucket frame [N]
//           lift_force tilt_force         cylinder forces, positive pushing [N]
//           speed x_machine drive_force normal_load bucket_pitch boom_angle edge_x edge_z
#pragma once

#include <cosim/participant.hpp>
#include <yaml-cpp/yaml.h>

#include <memory>

#include "wheel_loader.hpp"

namespace wheel_loader {

class WheelLoaderModel final : public cosim::Model {
 public:
  // machine_config: the machine config (configs/wheel_loader/machine.yaml layout, --set
  // applied); the master's parameters are applied on top of it in configure().
  explicit WheelLoaderModel(YAML::Node machine_config = YAML::Node(YAML::NodeType::Map));
  void configure(const YAML::Node& parameters, const cosim::RunInfo& run) override;
  cosim::Ports inputs() const override;
  cosim::Ports outputs() const override;
  cosim::Duration inner_step() const override { return inner_step_; }
  cosim::Signals initial_outputs() override;
  cosim::StepResult step(const cosim::StepInputs& in, bool want_average) override;
  bool can_repeat() const override { return true; }
  void save_snapshot() override { model_->save_snapshot(); }
  void restore_snapshot() override { model_->restore_snapshot(); }
  // The Simbody state (time, q, u, z) exactly, mbs_adapters/common/state_file.hpp.
  bool can_checkpoint() const override { return true; }
  void save_checkpoint(const std::string& path) override { model_->save_state(path); }
  void load_checkpoint(const std::string& path) override;

  const WheelLoader& model() const { return *model_; }

 private:
  struct Sample;
  Sample sample() const;
  void check_input(const cosim::StepInputs& in) const;

  YAML::Node base_;
  cosim::RunInfo run_;
  Parameters p_;
  cosim::Duration inner_step_{};
  std::unique_ptr<WheelLoader> model_;
};

}  // namespace wheel_loader
