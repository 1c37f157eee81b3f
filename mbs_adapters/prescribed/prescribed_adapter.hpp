// The prescribed participant: plays one trajectory per tool as kinematic outputs and records
// the wrench each tool receives. Config schema in docs/prescribed.md.
#pragma once

#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cosim/participant.hpp"
#include "cosim/trajectory.hpp"

namespace prescribed {

using cosim::Pose;
using cosim::Trajectory;

// A tool mounted on the trajectory instead of following it rigidly: a body of `mass` whose
// reference point is tied to the trajectory's (the driver's) by an isotropic spring and damper,
// pushed by the received force and gravity. Its orientation stays the driver's (a rigid
// rotational mount: the received torque is recorded, not applied). docs/prescribed.md.
struct Mount {
  double mass = 0;       // kg
  double stiffness = 0;  // N/m
  double damping = 0;    // N s/m
  cosim::Vec3 gravity{};  // m/s^2
};

struct ToolTrack {
  std::string name;          // kinematics output
  std::string wrench_input;  // wrench input (default <name>_wrench)
  Trajectory trajectory;
  std::optional<Mount> mount;
};

// The translational state of a mounted tool: position and velocity of its reference point.
struct MountState {
  cosim::Vec3 x{}, v{};
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
  bool can_repeat() const override { return true; }
  // The mounted tools' states (nothing else evolves but time); the repeated step's rows go.
  void save_snapshot() override { snapshot_ = states_; }
  void restore_snapshot() override {
    states_ = snapshot_;
    pending_.clear();
  }
  // A checkpoint holds the mounted tools' states (exact) and the length of the `record` CSV at
  // the checkpoint, which a resumed session cuts it back to and continues.
  bool can_checkpoint() const override { return true; }
  void save_checkpoint(const std::string& path) override;
  void load_checkpoint(const std::string& path) override;
  ~PrescribedAdapter() override;

  const std::vector<ToolTrack>& tools() const { return tools_; }
  // The state of tool i (its driver's position and velocity when it has no mount).
  const MountState& state(std::size_t i) const { return states_.at(i); }

 private:
  cosim::Signals poses_at(cosim::TimePoint t) const;
  // Integrates the mounted tools over the step (RK4 at the inner step, the force polynomial
  // evaluated at each stage's time).
  void advance_mounts(const cosim::StepInputs& in);
  double mount_energy(cosim::TimePoint t) const;
  void flush();

  YAML::Node root_;
  std::string base_dir_;
  std::vector<ToolTrack> tools_;
  cosim::Duration inner_step_ = cosim::nanoseconds(1);
  std::string record_path_;
  std::unique_ptr<std::ofstream> record_;
  std::vector<MountState> states_, snapshot_;  // one per tool (used for mounted ones)
  std::vector<std::string> pending_;  // rows of the current step until the next one starts
};

}  // namespace prescribed
