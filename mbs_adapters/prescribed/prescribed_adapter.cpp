#include "prescribed_adapter.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

#include "cosim/files.hpp"
#include "cosim/yaml_config.hpp"

namespace prescribed {

namespace cfg = cosim::config;
using cosim::TimePoint;

namespace {

Mount read_mount(const YAML::Node& node, const std::string& p) {
  if (!node.IsMap())
    throw cfg::ConfigError(p + ": give a map {mass, stiffness, damping, gravity}");
  cfg::check_keys(node, p, {"mass", "stiffness", "damping", "gravity"});
  Mount m;
  m.mass = cfg::get_positive(node, p, "mass");
  m.stiffness = cfg::get_positive(node, p, "stiffness");
  m.damping = cfg::get_double_or(node, p, "damping", 0.0);
  if (!(m.damping >= 0))
    throw cfg::ConfigError(p + ".damping: must be >= 0 N s/m (got " + std::to_string(m.damping) + ")");
  if (node["gravity"]) {
    const auto g = cfg::get_vector(node, p, "gravity", 3);
    m.gravity = {g[0], g[1], g[2]};
  }
  return m;
}

std::vector<ToolTrack> read_tools(const YAML::Node& root, const std::string& path,
                                  const std::string& base) {
  const YAML::Node list = root["tools"];
  if (!list || !list.IsSequence() || list.size() == 0)
    throw cfg::ConfigError(path + ".tools: missing; give a list of {name, keyframes or csv}");
  std::vector<ToolTrack> out;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node t = list[i];
    const std::string p = path + ".tools." + std::to_string(i);
    cfg::check_keys(t, p, {"name", "wrench_input", "interpolation", "keyframes", "csv", "mount"});
    ToolTrack track;
    track.name = cfg::get_string(t, p, "name");
    cosim::require_valid_name(track.name, p + ".name");
    track.wrench_input = cfg::get_string_or(t, p, "wrench_input", track.name + "_wrench");
    cosim::require_valid_name(track.wrench_input, p + ".wrench_input");
    track.trajectory = cosim::read_trajectory(t, p, base);
    if (t["mount"]) track.mount = read_mount(t["mount"], p + ".mount");
    for (const auto& other : out)
      if (other.name == track.name || other.wrench_input == track.wrench_input ||
          other.name == track.wrench_input || other.wrench_input == track.name)
        throw cfg::ConfigError(p + ": name '" + track.name + "' or wrench_input '" +
                               track.wrench_input + "' is used twice");
    out.push_back(std::move(track));
  }
  return out;
}

}  // namespace

PrescribedAdapter::PrescribedAdapter(YAML::Node root, std::string base_dir)
    : root_(root ? YAML::Clone(root) : YAML::Node(YAML::NodeType::Map)), base_dir_(std::move(base_dir)) {}

PrescribedAdapter::~PrescribedAdapter() {
  try {
    flush();
  } catch (...) {
  }
}

void PrescribedAdapter::configure(const YAML::Node& parameters, const cosim::RunInfo& run) {
  const std::string path = "participants." + run.participant + ".parameters";
  YAML::Node root = YAML::Clone(root_);
  cfg::apply_overrides(root, parameters, path);
  cfg::check_keys(root, path, {"tools", "inner_step", "record"});
  tools_ = read_tools(root, path, base_dir_);
  // Nothing is integrated: the inner step only says which macro steps fit (any, at 1 ns).
  inner_step_ = cosim::seconds_to_duration(cfg::get_positive_or(root, path, "inner_step", 1e-9),
                                           path + ".inner_step");
  if (inner_step_ <= cosim::Duration::zero()) throw cfg::ConfigError(path + ".inner_step: must be at least 1 ns");
  // A mount is integrated (RK4): the inner step must resolve its own period and damping time,
  // h sqrt(k/m) <= 0.2 and h d/m <= 0.2 (RK4's error per period is then below 1e-4).
  const double h = cosim::to_seconds(inner_step_);
  states_.assign(tools_.size(), MountState{});
  for (std::size_t i = 0; i < tools_.size(); ++i) {
    if (!tools_[i].mount) continue;
    const Mount& m = *tools_[i].mount;
    const double rate = std::max(std::sqrt(m.stiffness / m.mass), m.damping / m.mass);
    if (!root["inner_step"] || h * rate > 0.2) {
      char limit[64];
      std::snprintf(limit, sizeof limit, "%.3g", 0.2 / rate);
      throw cfg::ConfigError(path + ".inner_step: tool '" + tools_[i].name +
                             "' has a mount, whose motion is integrated: give an inner_step of at most " +
                             limit + " s (0.2 sqrt(mass/stiffness) and 0.2 mass/damping) that divides the macro step");
    }
    // At rest on the driver, sagged by its weight: x = x_driver + m g / k.
    const Pose d = tools_[i].trajectory.evaluate(cosim::to_seconds(run.t_start));
    for (int a = 0; a < 3; ++a) {
      states_[i].x[a] = d.position[a] + m.mass * m.gravity[a] / m.stiffness;
      states_[i].v[a] = d.velocity[a];
    }
  }
  snapshot_ = states_;
  record_path_ = cfg::get_string_or(root, path, "record", "");
  record_.reset();
  pending_.clear();
  if (!record_path_.empty() && run.resume_steps_done > 0) {
    // load_checkpoint cuts the earlier session's file back to the checkpoint and appends.
    if (!std::filesystem::is_regular_file(record_path_))
      throw cfg::ConfigError(path + ".record: '" + record_path_ +
                             "' is missing; a resumed run continues the file of the run it resumes");
  } else if (!record_path_.empty()) {
    record_ = std::make_unique<std::ofstream>(record_path_);
    if (!*record_)
      throw cfg::ConfigError(path + ".record: cannot write '" + record_path_ +
                             "'; check that the folder exists");
    *record_ << "time,tool";
    for (const auto& c : cosim::Wrench::component_names()) *record_ << "," << c;
    *record_ << "\n";
  }
}

cosim::Ports PrescribedAdapter::inputs() const {
  cosim::Ports p;
  for (const auto& t : tools_) p.push_back({t.wrench_input, cosim::SignalKind::Wrench});
  return p;
}

cosim::Ports PrescribedAdapter::outputs() const {
  cosim::Ports p;
  for (const auto& t : tools_) p.push_back({t.name, cosim::SignalKind::Kinematics});
  return p;
}

cosim::Signals PrescribedAdapter::poses_at(TimePoint t) const {
  cosim::Signals s;
  for (std::size_t i = 0; i < tools_.size(); ++i) {
    const auto& tool = tools_[i];
    const Pose p = tool.trajectory.evaluate(cosim::to_seconds(t));
    cosim::Kinematics k{p.position, p.orientation, p.velocity, p.angular_velocity};
    if (tool.mount) {
      k.position = states_[i].x;
      k.velocity = states_[i].v;
    }
    s[tool.name] = {cosim::SignalKind::Kinematics, k.to_value()};
  }
  return s;
}

void PrescribedAdapter::advance_mounts(const cosim::StepInputs& in) {
  const double length = cosim::to_seconds(in.length());
  const double t0 = cosim::to_seconds(in.t_start());
  const long long n = in.length() / inner_step_;  // the master keeps macro steps whole multiples
  const double h = length / static_cast<double>(n);
  for (std::size_t i = 0; i < tools_.size(); ++i) {
    if (!tools_[i].mount) continue;
    const Mount& m = *tools_[i].mount;
    const auto& tool = tools_[i];
    const cosim::InputPolynomial& force = in.polynomial(tool.wrench_input);
    // d/dt (x, v) at time t (seconds since the step's start) for the state (x, v).
    auto rate = [&](double tau, const MountState& y, MountState& dy) {
      const Pose d = tool.trajectory.evaluate(t0 + tau);
      const cosim::Value w = force.evaluate(tau / length);
      for (int a = 0; a < 3; ++a) {
        dy.x[a] = y.v[a];
        dy.v[a] = (m.stiffness * (d.position[a] - y.x[a]) + m.damping * (d.velocity[a] - y.v[a]) +
                   w[cosim::Wrench::kForce + a]) / m.mass + m.gravity[a];
      }
    };
    MountState& y = states_[i];
    for (long long j = 0; j < n; ++j) {
      const double tau = static_cast<double>(j) * h;
      MountState k1, k2, k3, k4, tmp;
      rate(tau, y, k1);
      for (int a = 0; a < 3; ++a) tmp.x[a] = y.x[a] + 0.5 * h * k1.x[a], tmp.v[a] = y.v[a] + 0.5 * h * k1.v[a];
      rate(tau + 0.5 * h, tmp, k2);
      for (int a = 0; a < 3; ++a) tmp.x[a] = y.x[a] + 0.5 * h * k2.x[a], tmp.v[a] = y.v[a] + 0.5 * h * k2.v[a];
      rate(tau + 0.5 * h, tmp, k3);
      for (int a = 0; a < 3; ++a) tmp.x[a] = y.x[a] + h * k3.x[a], tmp.v[a] = y.v[a] + h * k3.v[a];
      rate(tau + h, tmp, k4);
      for (int a = 0; a < 3; ++a) {
        y.x[a] += h / 6 * (k1.x[a] + 2 * k2.x[a] + 2 * k3.x[a] + k4.x[a]);
        y.v[a] += h / 6 * (k1.v[a] + 2 * k2.v[a] + 2 * k3.v[a] + k4.v[a]);
      }
    }
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(y.x[a]) || !std::isfinite(y.v[a]))
        throw std::runtime_error("tool '" + tool.name + "': its mount's state is not finite at t = " +
                                 std::to_string(cosim::to_seconds(in.t_end())) +
                                 " s (the received force grew without bound: an unstable coupling)");
  }
}

double PrescribedAdapter::mount_energy(TimePoint t) const {
  double e = 0;
  for (std::size_t i = 0; i < tools_.size(); ++i) {
    if (!tools_[i].mount) continue;
    const Mount& m = *tools_[i].mount;
    const Pose d = tools_[i].trajectory.evaluate(cosim::to_seconds(t));
    for (int a = 0; a < 3; ++a) {
      const double dx = states_[i].x[a] - d.position[a];
      e += 0.5 * m.mass * states_[i].v[a] * states_[i].v[a] + 0.5 * m.stiffness * dx * dx;
    }
  }
  return e;
}

cosim::Signals PrescribedAdapter::initial_outputs() { return poses_at(TimePoint{}); }

void PrescribedAdapter::flush() {
  if (!record_) return;
  for (const auto& row : pending_) *record_ << row;
  pending_.clear();
  record_->flush();
  // A full disk: the run stops naming the file (docs/output.md#when-a-record-cannot-be-written).
  if (!*record_) throw std::runtime_error(cosim::write_failure(record_path_, std::strerror(errno)));
}

cosim::StepResult PrescribedAdapter::step(const cosim::StepInputs& in, bool /*want_average*/) {
  // Rows wait until the next step starts: a repeat (restore_snapshot) drops them instead.
  flush();
  for (const auto& tool : tools_) {
    // What arrived: the wrench polynomial at the step's start is the latest sample received.
    const cosim::Value w = in.at(tool.wrench_input, in.t_start());  // [f t r]
    char number[32];
    std::snprintf(number, sizeof number, "%.9f", cosim::to_seconds(in.t_start()));
    std::string row = number + ("," + tool.name);
    for (double x : w) {
      std::snprintf(number, sizeof number, ",%.17g", x);
      row += number;
    }
    pending_.push_back(row + "\n");
  }
  advance_mounts(in);
  cosim::StepResult r;
  r.outputs = poses_at(in.t_end());
  for (const auto& t : tools_)
    if (t.mount) {
      r.diagnostics = {{"mount_energy", mount_energy(in.t_end())}};
      break;
    }
  // No interval average: the mean of a pose is not a pose. The reply says it has none.
  return r;
}

void PrescribedAdapter::save_checkpoint(const std::string& path) {
  flush();  // the step is accepted: its rows belong before the checkpoint
  const long long bytes = record_ ? static_cast<long long>(record_->tellp()) : 0;
  std::ofstream out(path, std::ios::trunc);
  out << "prescribed_checkpoint 2\nrecord_bytes " << bytes << "\nstates " << states_.size() << "\n";
  for (const auto& y : states_) {
    char line[256];  // %a: exact
    std::snprintf(line, sizeof line, "%a %a %a %a %a %a\n", y.x[0], y.x[1], y.x[2], y.v[0], y.v[1], y.v[2]);
    out << line;
  }
  out.flush();
  if (!out || bytes < 0) throw std::runtime_error("cannot write '" + path + "'");
}

void PrescribedAdapter::load_checkpoint(const std::string& path) {
  std::ifstream in(path);
  std::string magic, key;
  int version = 0;
  long long bytes = -1;
  if (!(in >> magic >> version >> key >> bytes) || magic != "prescribed_checkpoint" ||
      (version != 1 && version != 2) || key != "record_bytes" || bytes < 0)
    throw std::runtime_error("not a prescribed participant's checkpoint (version 1 or 2)");
  bool mounted = false;
  for (const auto& t : tools_) mounted = mounted || t.mount.has_value();
  if (version == 1 && mounted)
    throw std::runtime_error("a version-1 checkpoint holds no mount state, and a tool here has a mount");
  if (version == 2) {
    std::size_t n = 0;
    if (!(in >> key >> n) || key != "states" || n != states_.size())
      throw std::runtime_error("its tool count differs from this configuration's (" +
                               std::to_string(states_.size()) + ")");
    for (auto& y : states_) {
      std::string words[6];
      double v[6];
      for (int a = 0; a < 6; ++a) {
        char* end = nullptr;
        if (!(in >> words[a])) throw std::runtime_error("its mount states are cut short");
        v[a] = std::strtod(words[a].c_str(), &end);
        if (!end || *end != '\0' || !std::isfinite(v[a]))
          throw std::runtime_error("its mount state '" + words[a] + "' is not a finite number");
      }
      y.x = {v[0], v[1], v[2]};
      y.v = {v[3], v[4], v[5]};
    }
    snapshot_ = states_;
  }
  pending_.clear();
  if (record_path_.empty()) return;
  std::error_code ec;
  const auto size = std::filesystem::file_size(record_path_, ec);
  if (ec || size < static_cast<std::uintmax_t>(bytes))
    throw std::runtime_error("record '" + record_path_ + "' is shorter (" + std::to_string(ec ? 0 : size) +
                             " bytes) than at the checkpoint (" + std::to_string(bytes) + ")");
  std::filesystem::resize_file(record_path_, static_cast<std::uintmax_t>(bytes));
  record_ = std::make_unique<std::ofstream>(record_path_, std::ios::app);
  if (!*record_) throw std::runtime_error("cannot append to record '" + record_path_ + "'");
}

}  // namespace prescribed
