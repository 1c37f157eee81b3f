// The bus adapter around the hauler model: a thin layer mapping the model onto signals.
//   input   body_wrench    (wrench: force, torque about r, r; ground) on the dump body
//   outputs body           (kinematics of the body frame: origin on the hinge axis at the
//                           centre plane, x forward along the floor, z up from the floor)
//           front_fx front_fz rear1_fx rear1_fz rear2_fx rear2_fz
//                          tire forces on the machine per axle, TYDEX C axes [N]
//           front_stroke rear1_stroke rear2_stroke    strut strokes [m]
//           front_pressure rear_pressure              circuit pressures [Pa]
//           hoist_force [N]  body_angle [rad]
//           payload_rigid [kg]   only with a rigid test payload
#pragma once

#include <cosim/participant.hpp>
#include <yaml-cpp/yaml.h>

#include <memory>
#include <string>
#include <vector>

#include "hauler.hpp"

namespace hauler {

class HaulerModel final : public cosim::Model {
 public:
  // machine_config: the machine config (configs/hauler/machine.yaml layout, --set applied);
  // the master's parameters are applied on top of it in configure().
  explicit HaulerModel(YAML::Node machine_config = YAML::Node(YAML::NodeType::Map));
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

  const Hauler& model() const { return *model_; }
  // The scalar output names in port order (payload_rigid only with a test payload).
  const std::vector<std::string>& scalar_names() const { return scalars_; }

 private:
  struct Sample {
    cosim::Kinematics body;
    std::vector<double> scalars;
  };
  Sample sample() const;
  cosim::Signals to_signals(const Sample& s) const;
  void check_input(const cosim::StepInputs& in) const;

  YAML::Node base_;
  cosim::RunInfo run_;
  Parameters p_;
  cosim::Duration inner_step_{};
  std::unique_ptr<Hauler> model_;
  std::vector<std::string> scalars_;
};

}  // namespace hauler
