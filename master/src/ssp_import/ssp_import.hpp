// SSP 1.0 (System Structure and Parameterization, Modelica Association) import for cosim_master:
// an .ssp package (a zip with SystemStructure.ssd at its root), a bare .ssd, or a master YAML
// with a top-level `ssp:` key naming one, becomes the master's config: each FMU component a
// participant run by fmu_adapter (its parameter set from SSV files or inline values as start
// values), each connection a master connection (unit conversion per SSP on the consumer's
// input port). Every problem raises SspError "file:line: reason" (docs/fmi.md#ssp).
#pragma once

#include <cosim/yaml_config.hpp>
#include <yaml-cpp/yaml.h>

#include <stdexcept>
#include <string>

namespace ssp {

// A config error of the master's (exit 2, "config refused: FILE:LINE: reason").
struct SspError : cosim::config::ConfigError {
  using cosim::config::ConfigError::ConfigError;
};

// .ssp or .ssd (by name).
bool is_system_file(const std::string& path);

// The master config for `path`: generated from an .ssp/.ssd; a YAML file as it is, expanded when
// it has an `ssp:` key (ssp: FILE, or ssp: {file: FILE, predictor: NAME}; its other keys are the
// master's and win over the SSD's default experiment). *source_text: the YAML to record as the
// run's config (the generated one for SSP, so that --resume reads it back).
YAML::Node load_root(const std::string& path, std::string* source_text);

// The SSD (or .ssp) as a master config YAML node, with `predictor` (a named predictor, "" for
// none) on every connection. Extracted packages go to a folder under $TMPDIR named after the
// package's path, size and time, reused while they do not change.
YAML::Node system_config(const std::string& path, const std::string& predictor = "");

}  // namespace ssp
