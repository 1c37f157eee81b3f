// YAML config -> Scene + initial State + run options, strictly: unknown keys and bad values
// are refused with cosim::config::ConfigError naming the dotted key and the fix. The schema
// and its defaults are documented in docs/dem.md; a default is the initialiser of its struct
// field here, in scene.hpp, contact_law.hpp or bed.hpp (the parser falls back to it).
#pragma once

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <string>

#include "cosim/files.hpp"
#include "dem/bed.hpp"
#include "dem/engine_options.hpp"
#include "dem/packing.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

struct SettleOptions {
  bool enabled = false;
  double ke_per_particle = 1e-9;  // J
  double max_time = 5.0;          // s of simulated time
  std::string checkpoint;         // save the settled state here ("" = do not save)
};

struct OutputOptions {
  std::string file = "dem_out.h5";
  double particles_every = 0;  // s; 0 = only at start and end
  double wrenches_every = 0;   // s; 0 = every step
  double progress_every = 2;   // wall-clock seconds between progress lines
  std::string checkpoint;      // final state ("" = none)
};

// particles.perturb: every particle's position moves by a seeded displacement, uniform in
// [-amplitude, amplitude] per axis, a function of (seed, particle id, axis) only. Members of an
// ensemble differ by their seed: a physically negligible change whose effect the scene's own
// chaos amplifies (docs/studies.md).
struct Perturbation {
  double amplitude = 0;  // m; 0 = none
  std::uint64_t seed = 0;
};
// The largest amplitude accepted, as a fraction of the smallest species radius.
inline constexpr double kMaxPerturbation = 1e-2;
void perturb_positions(State& s, const Perturbation& p);

struct RunConfig {
  Scene scene;
  // The performance: section (EngineOptions' close_margin, pair_schedule,
  // min_particles_per_thread); the apps join it to their other options with with_config.
  EngineOptions performance;
  State state;  // initial particles and tool poses
  std::vector<FillRegion> fill;
  std::vector<InsertRegion> insert;  // particles.insert: random sequential insertion
  PrepareOptions prepare;            // prepare: deposition, then frozen into contact
  SettleOptions settle;
  OutputOptions output;
  double duration = 0;
  // The state continues a run: a checkpoint with particles.keep_time and nothing added to it.
  // Its overlaps are the run's own, so validate_state does not check them.
  bool continues = false;
  Perturbation perturb;     // applied to state already
  std::string config_text;  // the config as run (after --set), stored in the output
  // The files the config made it read (meshes, keyframe CSVs, the checkpoint), as resolved.
  std::vector<cosim::NamedFile> inputs;
};

// The files a run writes: output.file, the XDMF file beside it, output.checkpoint and, with
// settle, settle.checkpoint. `output_key` names output.file in messages (e.g. "--output").
std::vector<cosim::NamedFile> output_files(const RunConfig& rc, const std::string& output_key = "output.file");

// Refuses outputs equal to each other or to an input (rc.inputs and the config file itself)
// before anything is written (cosim::check_output_files). extra_outputs: files the program
// writes besides output_files (dem_service's service.checkpoint).
void check_files(const RunConfig& rc, const std::string& config_path,
                 const std::string& output_key = "output.file",
                 const std::vector<cosim::NamedFile>& extra_outputs = {},
                 bool require_folders = true);

// Parses every section, then reads the files it names (meshes, keyframe CSVs, a checkpoint)
// and generates the initial state (checkpoint, then particles.list, then particles.fill).
// base_dir resolves relative mesh, CSV and checkpoint paths (the config file's folder).
RunConfig load_config(const YAML::Node& root, const std::string& base_dir);

// Only scene.thread_wait (validated, or its default): the programs apply it before they load
// the rest (dem/thread_wait.hpp), since applying it may execute the program again.
ThreadWait read_thread_wait(const YAML::Node& root);

}  // namespace dem
