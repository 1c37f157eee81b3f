// The protocol adapter around one oscillator half: a thin layer mapping the half's inputs and
// outputs onto signals (mass1: input force, outputs x, v; mass2: inputs x, v, output force).
#pragma once

#include <cosim/participant.hpp>

#include <memory>

#include "oscillator.hpp"

namespace oscillator {

class OscillatorAdapter final : public cosim::Model {
 public:
  explicit OscillatorAdapter(Side side) : side_(side) {}
  void configure(const YAML::Node& parameters, const cosim::RunInfo& run) override;
  cosim::Ports inputs() const override;
  cosim::Ports outputs() const override;
  cosim::Duration inner_step() const override { return inner_step_; }
  cosim::Signals initial_outputs() override;
  cosim::StepResult step(const cosim::StepInputs& in, bool want_average) override;
  bool can_repeat() const override { return true; }
  void save_snapshot() override { snapshot_ = half_->state(); }
  void restore_snapshot() override { half_->set_state(snapshot_); }
  // The half's state (x, v) as exact hexadecimal floating-point text.
  bool can_checkpoint() const override { return true; }
  void save_checkpoint(const std::string& path) override;
  void load_checkpoint(const std::string& path) override;

 private:
  cosim::Signals to_signals(const Eigen::VectorXd& out) const;
  Side side_;
  Parameters p_;
  cosim::Duration inner_step_{};
  std::unique_ptr<Half> half_;
  Eigen::Vector2d snapshot_ = Eigen::Vector2d::Zero();
};

// Reads one half's parameters (keys listed in docs/config.md); raises config::ConfigError.
Parameters read_parameters(Side side, const YAML::Node& node, cosim::Duration* inner_step);

}  // namespace oscillator
