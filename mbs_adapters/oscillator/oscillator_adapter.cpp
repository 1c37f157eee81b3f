#include "oscillator_adapter.hpp"

#include <cosim/yaml_config.hpp>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace oscillator {

using namespace cosim;
namespace cfg = cosim::config;

Parameters read_parameters(Side side, const YAML::Node& node, Duration* inner_step) {
  Parameters p;
  const std::string path = "parameters";
  if (side == Side::Mass1) {
    cfg::check_keys(node, path, {"mass", "stiffness", "damping", "position", "velocity", "inner_step"});
    p.m1 = cfg::get_positive_or(node, path, "mass", p.m1);
    p.c1 = cfg::get_double_or(node, path, "stiffness", p.c1);
    p.d1 = cfg::get_double_or(node, path, "damping", p.d1);
    p.x1 = cfg::get_double_or(node, path, "position", p.x1);
    p.v1 = cfg::get_double_or(node, path, "velocity", p.v1);
  } else {
    cfg::check_keys(node, path, {"mass", "stiffness", "damping", "coupling_stiffness",
                                 "coupling_damping", "position", "velocity", "coupled_position",
                                 "coupled_velocity", "inner_step"});
    p.m2 = cfg::get_positive_or(node, path, "mass", p.m2);
    p.c2 = cfg::get_double_or(node, path, "stiffness", p.c2);
    p.d2 = cfg::get_double_or(node, path, "damping", p.d2);
    p.cc = cfg::get_double_or(node, path, "coupling_stiffness", p.cc);
    p.dc = cfg::get_double_or(node, path, "coupling_damping", p.dc);
    p.x2 = cfg::get_double_or(node, path, "position", p.x2);
    p.v2 = cfg::get_double_or(node, path, "velocity", p.v2);
    // mass1's initial state, which mass2's initial force depends on
    p.x1 = cfg::get_double_or(node, path, "coupled_position", p.x1);
    p.v1 = cfg::get_double_or(node, path, "coupled_velocity", p.v1);
  }
  for (double v : {p.c1, p.d1, p.c2, p.d2, p.cc, p.dc})
    if (v < 0) throw cfg::ConfigError(path + ": stiffness and damping values must be >= 0");
  *inner_step = seconds_to_duration(cfg::get_positive_or(node, path, "inner_step", 5e-6),
                                    path + ".inner_step");
  if (*inner_step <= Duration::zero()) throw cfg::ConfigError(path + ".inner_step: must be at least 1 ns");
  return p;
}

void OscillatorAdapter::configure(const YAML::Node& parameters, const RunInfo&) {
  p_ = read_parameters(side_, parameters, &inner_step_);
  half_ = std::make_unique<Half>(side_, p_, to_seconds(inner_step_));
}

Ports OscillatorAdapter::inputs() const {
  if (side_ == Side::Mass1) return {{"force", SignalKind::Scalar}};
  return {{"x", SignalKind::Scalar}, {"v", SignalKind::Scalar}};
}

Ports OscillatorAdapter::outputs() const {
  if (side_ == Side::Mass1) return {{"x", SignalKind::Scalar}, {"v", SignalKind::Scalar}};
  return {{"force", SignalKind::Scalar}};
}

Signals OscillatorAdapter::to_signals(const Eigen::VectorXd& out) const {
  if (side_ == Side::Mass1)
    return {{"x", {SignalKind::Scalar, {out(0)}}}, {"v", {SignalKind::Scalar, {out(1)}}}};
  return {{"force", {SignalKind::Scalar, {out(0)}}}};
}

Signals OscillatorAdapter::initial_outputs() {
  Eigen::VectorXd u(2);
  u << p_.x1, p_.v1;  // mass1's initial state (mass2: parameters coupled_position/velocity)
  return to_signals(half_->output(u));
}

StepResult OscillatorAdapter::step(const StepInputs& in, bool want_average) {
  const int m = half_->input_size();
  const auto names = side_ == Side::Mass1 ? std::vector<std::string>{"force"}
                                          : std::vector<std::string>{"x", "v"};
  int n_coeff = 0;
  for (const auto& n : names) n_coeff = std::max(n_coeff, in.polynomial(n).n_coefficients);
  std::vector<Eigen::VectorXd> a(n_coeff, Eigen::VectorXd::Zero(m));
  for (int i = 0; i < m; ++i) {
    const auto& poly = in.polynomial(names[i]);
    for (int j = 0; j < poly.n_coefficients; ++j) a[j](i) = poly.coefficients[j];
  }
  const int n_inner = static_cast<int>(in.length() / inner_step_);
  StepResult r;
  if (want_average)
    r.average = to_signals(half_->advance_with_average(a, n_inner));
  else
    half_->advance(a, n_inner);
  Eigen::VectorXd u_end(m);
  for (int i = 0; i < m; ++i) u_end(i) = in.at(names[i], in.t_end())[0];
  r.outputs = to_signals(half_->output(u_end));
  const auto& x = half_->state();
  r.diagnostics = {{"energy", 0.5 * (side_ == Side::Mass1 ? p_.m1 : p_.m2) * x(1) * x(1) +
                                  0.5 * (side_ == Side::Mass1 ? p_.c1 : p_.c2) * x(0) * x(0)}};
  return r;
}

namespace {
const char* side_name(Side side) { return side == Side::Mass1 ? "mass1" : "mass2"; }
}  // namespace

void OscillatorAdapter::save_checkpoint(const std::string& path) {
  std::ofstream out(path, std::ios::trunc);
  char line[160];
  const auto& x = half_->state();
  std::snprintf(line, sizeof line, "oscillator_checkpoint 1\nside %s\nstate %a %a\n", side_name(side_),
                x(0), x(1));  // %a: exact
  out << line;
  out.flush();
  if (!out) throw std::runtime_error("cannot write '" + path + "'");
}

void OscillatorAdapter::load_checkpoint(const std::string& path) {
  std::ifstream in(path);
  std::string magic, side_key, side, state_key, a, b;
  int version = 0;
  if (!(in >> magic >> version >> side_key >> side >> state_key >> a >> b) ||
      magic != "oscillator_checkpoint" || version != 1 || side_key != "side" || state_key != "state")
    throw std::runtime_error("not an oscillator checkpoint (version 1)");
  if (side != side_name(side_))
    throw std::runtime_error("it is of side " + side + ", this participant is " + side_name(side_));
  char* end = nullptr;
  Eigen::Vector2d x;
  x(0) = std::strtod(a.c_str(), &end);
  const bool ok0 = end && *end == '\0';
  x(1) = std::strtod(b.c_str(), &end);
  if (!ok0 || !end || *end != '\0' || !x.allFinite())
    throw std::runtime_error("its state '" + a + " " + b + "' is not two finite numbers");
  half_->set_state(x);
}

}  // namespace oscillator
