// cosim_master --resume FILE.h5: what a stopped run's record holds for continuing it (the
// config it ran with, its checkpoint, the participants' checkpoint folder and run id) and the
// predictor history that makes the continuation bit-identical to an uninterrupted run
// (docs/protocol.md#checkpoints-and-resume, docs/output.md#checkpoints-and-resume).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "config.hpp"
#include "cosimulation.hpp"

namespace master {

struct ResumeRecord {
  std::string path;
  std::string source_text;     // /config: the file as the run read it
  std::string effective_yaml;  // /config_effective: after --set
  std::string status;          // /status ("" when the master itself was killed)
  int64_t steps_done = 0;      // /checkpoint/steps_done: the last common checkpoint
  int64_t steps_recorded = 0;  // rows of /time minus the initial one
  int64_t run_id = 0;          // /checkpoint run_id
  std::string folder;          // /checkpoint folder: where the participants wrote
  std::string csv;             // /checkpoint csv: the run's CSV export ("" none)
};

// Reads and checks a record for --resume. Raises config::ConfigError naming the file and what
// to do: not a record of cosim_master, no checkpoints (checkpoints.every was 0), a finished
// run, no checkpoint completed yet, a record shorter than its checkpoint.
ResumeRecord read_resume_record(const std::string& path);

// The run's config (its effective YAML) with --set overrides of the keys that cannot change a
// result only: bus.url, connect_timeout, output.progress and participants.<name>.launch,
// .timeout, .retries. Any other key is refused, naming it. Raises config::ConfigError.
Config resume_config(const ResumeRecord& record, const std::vector<std::string>& overrides);

// The predictors' history up to the checkpoint: every connection's received values (and
// interval means), rows 0..steps_done. Raises config::ConfigError for a damaged record.
ResumePoint read_resume_point(const ResumeRecord& record, const Config& config);

}  // namespace master
