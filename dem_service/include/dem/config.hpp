// YAML config -> Scene + initial State + run options, strictly: unknown keys and bad values
// are refused with cosim::config::ConfigError naming the dotted key and the fix.
// The schema is documented in docs/dem.md.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>

#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

struct FillRegion {
  int species = 0;
  Vec3 min, max;
  long long count = 0;
  unsigned long long seed = 1;
};

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

struct RunConfig {
  Scene scene;
  State state;  // initial particles and tool poses
  std::vector<FillRegion> fill;
  SettleOptions settle;
  OutputOptions output;
  double duration = 0;
  std::string config_text;  // the config as run (after --set), stored in the output
};

// base_dir resolves relative mesh, CSV and checkpoint paths (the config file's folder).
RunConfig load_config(const YAML::Node& root, const std::string& base_dir);

// Samples one radius of species sp with the generator state `rng` (splitmix64).
double sample_radius(const Species& sp, std::uint64_t& rng);

// Fills the region with non-overlapping particles: a jittered lattice of pitch 2 r_max,
// filled from the bottom layer up, radii drawn from the species distribution. Seeded and
// reproducible on every platform (own generator).
void fill_region(const Scene& scene, const FillRegion& region, State& s);

}  // namespace dem
