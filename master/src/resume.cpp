#include "resume.hpp"

#include <cosim/bus.hpp>
#include <cosim/h5.hpp>

#include <cmath>
#include <regex>

namespace master {

using cosim::config::ConfigError;

namespace {

std::string prefix(const std::string& path) { return "--resume: '" + path + "'"; }

}  // namespace

ResumeRecord read_resume_record(const std::string& path) {
  ResumeRecord r;
  r.path = path;
  htri_t is_h5;
  H5E_BEGIN_TRY { is_h5 = H5Fis_hdf5(path.c_str()); }
  H5E_END_TRY;
  if (is_h5 <= 0)
    throw ConfigError(prefix(path) + " is missing or not an HDF5 file: give the output file "
                      "(output.file / --output) of the run to continue");
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  cosim::h5::Handle f(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!f.ok()) throw ConfigError(prefix(path) + " cannot be opened (is another process writing it?)");
  try {
    r.source_text = cosim::h5::read_string(f, "config");
    r.effective_yaml = cosim::h5::read_string(f, "config_effective");
  } catch (const std::exception& e) {
    throw ConfigError(prefix(path) + " is not a record of cosim_master (" + e.what() + ")");
  }
  if (H5Lexists(f, "status", H5P_DEFAULT) > 0) r.status = cosim::h5::read_string(f, "status");
  if (H5Lexists(f, "checkpoint", H5P_DEFAULT) <= 0)
    throw ConfigError(prefix(path) + " has no checkpoints: its run had checkpoints.every: 0, so "
                      "the participants saved no state to continue from. Run it again, with "
                      "checkpoints.every set to resume later runs (docs/protocol.md#checkpoints-and-resume)");
  if (r.status == "finished")
    throw ConfigError(prefix(path) + " is a finished run (/status: finished): there is nothing to resume");
  try {
    cosim::h5::Handle g(H5Gopen2(f, "checkpoint", H5P_DEFAULT), H5Gclose);
    r.run_id = cosim::parse_id_hex(cosim::h5::read_string_attribute(g, "run_id"));
    r.folder = cosim::h5::read_string_attribute(g, "folder");
    r.csv = cosim::h5::read_string_attribute(g, "csv");
    const double steps = cosim::h5::read_doubles(f, "checkpoint/steps_done").at(0);
    if (!(steps >= 0) || steps != std::floor(steps)) throw std::runtime_error("steps_done is not a count");
    r.steps_done = static_cast<int64_t>(steps);
    r.steps_recorded = static_cast<int64_t>(cosim::h5::read_doubles(f, "time").size()) - 1;
  } catch (const std::exception& e) {
    throw ConfigError(prefix(path) + ": its /checkpoint group is damaged (" + e.what() + ")");
  }
  if (r.steps_done == 0)
    throw ConfigError(prefix(path) + ": the run stopped (" +
                      (r.status.empty() ? std::string("no /status: the master itself was killed") : r.status) +
                      ") before its first checkpoint, so there is nothing to continue from; "
                      "start it again (a shorter checkpoints.every checkpoints sooner)");
  if (r.steps_recorded < r.steps_done)
    throw ConfigError(prefix(path) + " holds " + std::to_string(r.steps_recorded) +
                      " steps but says its checkpoint is after " + std::to_string(r.steps_done) +
                      ": the record is damaged");
  return r;
}

Config resume_config(const ResumeRecord& record, const std::vector<std::string>& overrides) {
  YAML::Node root = cosim::config::load_string(record.effective_yaml, record.path + ":/config_effective");
  // Keys that choose how to reach the participants, never what they compute.
  static const std::regex allowed(
      R"(^(bus\.url|connect_timeout|output\.progress|participants\.[A-Za-z0-9_]+\.(launch|timeout|retries))$)");
  for (const auto& o : overrides) {
    const std::string key = o.substr(0, o.find('='));
    if (!std::regex_match(key, allowed))
      throw ConfigError("--set " + key + ": not allowed with --resume (the rest of the run must "
                        "be as it was, or it would not continue bit-identically); allowed: "
                        "bus.url, connect_timeout, output.progress, participants.<name>.launch, "
                        ".timeout, .retries");
    cosim::config::apply_override(root, o);
  }
  Config c = parse_config(root, record.source_text);
  if (c.checkpoints.every <= Duration::zero())
    throw ConfigError(prefix(record.path) + ": its config has checkpoints.every: 0 although the "
                      "record has checkpoints: the record is damaged");
  return c;
}

ResumePoint read_resume_point(const ResumeRecord& record, const Config& config) {
  ResumePoint p;
  p.steps_done = record.steps_done;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  cosim::h5::Handle f(H5Fopen(record.path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!f.ok()) throw ConfigError(prefix(record.path) + " cannot be opened");
  const std::size_t rows = static_cast<std::size_t>(record.steps_done) + 1;
  auto table = [&](const std::string& name) {
    std::size_t width = 0;
    std::vector<double> all;
    try {
      all = cosim::h5::read_doubles(f, name, &width);
    } catch (const std::exception& e) {
      throw ConfigError(prefix(record.path) + ": " + e.what() + "; the record does not match its config");
    }
    if (all.size() < rows * width)
      throw ConfigError(prefix(record.path) + ": '" + name + "' is shorter than the checkpoint");
    std::vector<cosim::Value> out(rows);
    for (std::size_t i = 0; i < rows; ++i)
      out[i].assign(all.begin() + static_cast<std::ptrdiff_t>(i * width),
                    all.begin() + static_cast<std::ptrdiff_t>((i + 1) * width));
    return out;
  };
  if (config.coupling.adaptive.enabled) {  // the steps' ends as recorded (whole nanoseconds)
    for (const auto& t : table("time")) p.times.push_back(TimePoint(Duration(std::llround(t.at(0) * 1e9))));
    if (p.times.front() != config.t_start)
      throw ConfigError(prefix(record.path) + ": its /time does not start at time.start; the record is damaged");
  }
  if (H5Lexists(f, "checkpoint/algorithm_state", H5P_DEFAULT) > 0)
    p.algorithm_state = cosim::h5::read_string(f, "checkpoint/algorithm_state");
  else if (config.coupling.type == CouplingType::Implicit || config.coupling.adaptive.enabled)
    throw ConfigError(prefix(record.path) + ": it has no /checkpoint/algorithm_state, which an implicit or "
                      "adaptive run needs to continue; the record is damaged (or written before this was saved)");
  for (const auto& k : config.connections) {
    const std::string g = "connections/" + k.to.str();
    p.received.push_back(table(g + "/received"));
    p.received_average.push_back(k.use == Use::Average ? table(g + "/received_average")
                                                       : std::vector<cosim::Value>{});
  }
  return p;
}

}  // namespace master
