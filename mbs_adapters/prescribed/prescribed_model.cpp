#include "prescribed_model.hpp"

#include <cerrno>
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

std::vector<ToolTrack> read_tools(const YAML::Node& root, const std::string& path,
                                  const std::string& base) {
  const YAML::Node list = root["tools"];
  if (!list || !list.IsSequence() || list.size() == 0)
    throw cfg::ConfigError(path + ".tools: missing; give a list of {name, keyframes or csv}");
  std::vector<ToolTrack> out;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node t = list[i];
    const std::string p = path + ".tools." + std::to_string(i);
    cfg::check_keys(t, p, {"name", "wrench_input", "interpolation", "keyframes", "csv"});
    ToolTrack track;
    track.name = cfg::get_string(t, p, "name");
    cosim::require_valid_name(track.name, p + ".name");
    track.wrench_input = cfg::get_string_or(t, p, "wrench_input", track.name + "_wrench");
    cosim::require_valid_name(track.wrench_input, p + ".wrench_input");
    track.trajectory = cosim::read_trajectory(t, p, base);
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

PrescribedModel::PrescribedModel(YAML::Node root, std::string base_dir)
    : root_(root ? YAML::Clone(root) : YAML::Node(YAML::NodeType::Map)), base_dir_(std::move(base_dir)) {}

PrescribedModel::~PrescribedModel() {
  try {
    flush();
  } catch (...) {
  }
}

void PrescribedModel::configure(const YAML::Node& parameters, const cosim::RunInfo& run) {
  const std::string path = "participants." + run.participant + ".parameters";
  YAML::Node root = YAML::Clone(root_);
  cfg::apply_overrides(root, parameters, path);
  cfg::check_keys(root, path, {"tools", "inner_step", "record"});
  tools_ = read_tools(root, path, base_dir_);
  // Nothing is integrated: the inner step only says which macro steps fit (any, at 1 ns).
  inner_step_ = cosim::seconds_to_duration(cfg::get_positive_or(root, path, "inner_step", 1e-9),
                                           path + ".inner_step");
  if (inner_step_ <= cosim::Duration::zero()) throw cfg::ConfigError(path + ".inner_step: must be at least 1 ns");
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

cosim::Ports PrescribedModel::inputs() const {
  cosim::Ports p;
  for (const auto& t : tools_) p.push_back({t.wrench_input, cosim::SignalKind::Wrench});
  return p;
}

cosim::Ports PrescribedModel::outputs() const {
  cosim::Ports p;
  for (const auto& t : tools_) p.push_back({t.name, cosim::SignalKind::Kinematics});
  return p;
}

cosim::Signals PrescribedModel::poses_at(TimePoint t) const {
  cosim::Signals s;
  for (const auto& tool : tools_) {
    const Pose p = tool.trajectory.evaluate(cosim::to_seconds(t));
    const cosim::Kinematics k{p.position, p.orientation, p.velocity, p.angular_velocity};
    s[tool.name] = {cosim::SignalKind::Kinematics, k.to_value()};
  }
  return s;
}

cosim::Signals PrescribedModel::initial_outputs() { return poses_at(TimePoint{}); }

void PrescribedModel::flush() {
  if (!record_) return;
  for (const auto& row : pending_) *record_ << row;
  pending_.clear();
  record_->flush();
  // A full disk: the run stops naming the file (docs/output.md#when-a-record-cannot-be-written).
  if (!*record_) throw std::runtime_error(cosim::write_failure(record_path_, std::strerror(errno)));
}

cosim::StepResult PrescribedModel::step(const cosim::StepInputs& in, bool /*want_average*/) {
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
  cosim::StepResult r;
  r.outputs = poses_at(in.t_end());
  // No interval average: the mean of a pose is not a pose. The reply says it has none.
  return r;
}

void PrescribedModel::save_checkpoint(const std::string& path) {
  flush();  // the step is accepted: its rows belong before the checkpoint
  const long long bytes = record_ ? static_cast<long long>(record_->tellp()) : 0;
  std::ofstream out(path, std::ios::trunc);
  out << "prescribed_checkpoint 1\nrecord_bytes " << bytes << "\n";
  out.flush();
  if (!out || bytes < 0) throw std::runtime_error("cannot write '" + path + "'");
}

void PrescribedModel::load_checkpoint(const std::string& path) {
  std::ifstream in(path);
  std::string magic, key;
  int version = 0;
  long long bytes = -1;
  if (!(in >> magic >> version >> key >> bytes) || magic != "prescribed_checkpoint" || version != 1 ||
      key != "record_bytes" || bytes < 0)
    throw std::runtime_error("not a prescribed participant's checkpoint (version 1)");
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
