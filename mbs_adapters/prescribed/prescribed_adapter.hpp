// The prescribed participant: plays one trajectory per tool as kinematic outputs and records
// the wrench each tool receives. Config schema in docs/prescribed.md.
#pragma once

#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "cosim/participant.hpp"
#include "cosim/trajectory.hpp"

namespace prescribed {

using cosim::Pose;
using cosim::Trajectory;

struct ToolTrack {
  std::string name;          // kinematics output
  std::string wrench_input;  // wrench input (default <name>_wrench)
  Trajectory trajectory;
};

class PrescribedAdapter final : public cosim::Model {
 public:
  // root: the participant's config file (may be empty) after --set; base_dir resolves its
  // relative paths. The master's parameters amend it in configure().
  PrescribedAdapter(YAML::Node root, std::string base_dir);

  void configure(const YAML::Node& parameters, const cosim::RunInfo& run) override;
  cosim::Ports inputs() const override;
  cosim::Ports outputs() const override;
  cosim::Duration inner_step() const override { return inner_step_; }
  cosim::Signals initial_outputs() override;
  cosim::StepResult step(const cosim::StepInputs& in, bool want_average) override;
  bool can_repeat() const override { return true; }  // nothing evolves but time
  void save_snapshot() override {}
  void restore_snapshot() override { pending_.clear(); }  // the repeated step's rows
  // Nothing evolves but time, which the protocol restores: a checkpoint holds the length of
  // the `record` CSV at the checkpoint, which a resumed session cuts it back to and continues.
  bool can_checkpoint() const override { return true; }
  void save_checkpoint(const std::string& path) override;
  void load_checkpoint(const std::string& path) override;
  ~PrescribedAdapter() override;

  const std::vector<ToolTrack>& tools() const { return tools_; }

 private:
  cosim::Signals poses_at(cosim::TimePoint t) const;
  void flush();

  YAML::Node root_;
  std::string base_dir_;
  std::vector<ToolTrack> tools_;
  cosim::Duration inner_step_ = cosim::nanoseconds(1);
  std::string record_path_;
  std::unique_ptr<std::ofstream> record_;
  std::vector<std::string> pending_;  // rows of the current step until the next one starts
};

}  // namespace prescribed
