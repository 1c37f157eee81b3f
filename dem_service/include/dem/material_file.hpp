// Material files (docs/soil.md#material-files): a calibrated soil named by a config,
//   materials: {sand: {file: ../materials/dry_sand.yaml}}
// The file gives the grain density, the grain radius, the particle contact law and the
// deposition friction of its packing (scripts/calibrate.py writes it). resolve_material_files
// returns a copy of the config with the file's values put in where the config leaves them out:
// materials.<name>.density, the radius of every species of that material, the keys of
// contact.particle_particle (the config's own keys win, so --set can vary one) and
// prepare.deposition_friction (when the config has a prepare: section), and the particle model
// the law was calibrated for (particles.model, particles.rolling_resistance: where the config
// does not give them; docs/soil_models.md). A missing, unreadable
// or malformed file is refused naming materials.<name>.file and the problem.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

#include "cosim/files.hpp"

namespace dem {

// Keys of a material file.
inline const std::vector<std::string> kMaterialFileKeys{
    "name", "density", "radius", "contact", "prepare", "particles", "calibration"};

// The config with every materials.<name>.file resolved (paths by cosim::input_path from
// base_dir); the files read are appended to `inputs` (an output may not overwrite them). A
// config without material files is returned as it is (the same node).
YAML::Node resolve_material_files(const YAML::Node& root, const std::string& base_dir,
                                  std::vector<cosim::NamedFile>& inputs);

}  // namespace dem
