#include "dem/material_file.hpp"

#include <filesystem>
#include <string>

#include "cosim/paths.hpp"
#include "cosim/yaml_config.hpp"

namespace dem {

namespace cfg = cosim::config;
using cfg::ConfigError;

namespace {

// Reads and checks one material file; `key` is materials.<name>.file for messages.
YAML::Node read_material_file(const std::string& path, const std::string& key) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw ConfigError(key + ": cannot read '" + path +
                      "' (no such file; a relative path is looked for beside the config, then "
                      "in the working directory)");
  if (fs::is_directory(path, ec))
    throw ConfigError(key + ": '" + path + "' is a folder; give a material file (.yaml)");
  YAML::Node m;
  try {
    m = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw ConfigError(key + ": cannot read '" + path + "' (permissions?)");
  } catch (const YAML::Exception& e) {
    throw ConfigError(key + ": '" + path + "' is not valid YAML (" + e.what() + ")");
  }
  const std::string p = key + " '" + path + "'";
  if (!m.IsMap())
    throw ConfigError(p + ": expected a map with density, radius and contact.particle_particle "
                          "(a material file written by scripts/calibrate.py)");
  cfg::check_keys(m, p, kMaterialFileKeys);
  cfg::get_positive(m, p, "density");  // refuses a missing or bad density by name
  if (!m["radius"]) throw ConfigError(p + ".radius: missing (metres, or a distribution)");
  const YAML::Node c = m["contact"];
  if (!c || !c.IsMap())
    throw ConfigError(p + ".contact: missing (expected {particle_particle: {...}})");
  cfg::check_keys(c, p + ".contact", {"particle_particle"});
  if (!c["particle_particle"] || !c["particle_particle"].IsMap())
    throw ConfigError(p + ".contact.particle_particle: missing (the grains' contact law)");
  if (const YAML::Node pr = m["prepare"]) {
    cfg::check_keys(pr, p + ".prepare", {"deposition_friction"});
    if (cfg::get_double(pr, p + ".prepare", "deposition_friction") < 0)
      throw ConfigError(p + ".prepare.deposition_friction: must be >= 0");
  }
  if (const YAML::Node pa = m["particles"]) {
    if (!pa.IsMap())
      throw ConfigError(p + ".particles: expected a map {model, rolling_resistance}");
    cfg::check_keys(pa, p + ".particles", {"model", "rolling_resistance"});
  }
  if (const YAML::Node cal = m["calibration"]; cal && !cal.IsMap())
    throw ConfigError(p + ".calibration: expected a map (the calibration's record)");
  return m;
}

}  // namespace

YAML::Node resolve_material_files(const YAML::Node& root, const std::string& base_dir,
                                  std::vector<cosim::NamedFile>& inputs) {
  if (!root.IsMap()) return root;
  const YAML::Node mats = root["materials"];
  if (!mats || !mats.IsMap()) return root;
  bool any = false;
  for (const auto& kv : mats)
    if (kv.second.IsMap() && kv.second["file"]) any = true;
  if (!any) return root;

  YAML::Node out = YAML::Clone(root);
  std::string law_from;  // the material whose file gave contact.particle_particle
  for (auto kv : out["materials"]) {
    const std::string name = kv.first.as<std::string>();
    YAML::Node entry = kv.second;
    if (!entry.IsMap() || !entry["file"]) continue;
    const std::string key = "materials." + name + ".file";
    cfg::check_keys(entry, "materials." + name, {"file"});  // density comes from the file
    const std::string given = cfg::get_string(entry, "materials." + name, "file");
    if (given.empty()) throw ConfigError(key + ": empty; give the material file's path");
    const std::string path = cosim::input_path(base_dir, given);
    const YAML::Node m = read_material_file(path, key);
    inputs.push_back({key, path});

    YAML::Node resolved;
    resolved["density"] = m["density"];
    out["materials"][name] = resolved;

    if (YAML::Node sps = out["species"]; sps && sps.IsSequence())
      for (std::size_t i = 0; i < sps.size(); ++i) {
        YAML::Node sp = sps[i];
        if (sp.IsMap() && sp["material"] && sp["material"].IsScalar() &&
            sp["material"].as<std::string>() == name && !sp["radius"])
          sp["radius"] = YAML::Clone(m["radius"]);
      }

    if (!law_from.empty())
      throw ConfigError(key + ": materials." + law_from +
                        ".file gives the grains' contact law already; a scene has one "
                        "contact.particle_particle, so name one material file");
    law_from = name;
    YAML::Node contact = out["contact"];
    if (!contact || contact.IsNull()) {
      out["contact"] = YAML::Node(YAML::NodeType::Map);
      contact = out["contact"];
    }
    if (!contact.IsMap()) continue;  // load_config names the problem
    YAML::Node law = YAML::Clone(m["contact"]["particle_particle"]);
    if (const YAML::Node own = contact["particle_particle"]; own && own.IsMap()) {
      // The config's own keys win; restitution and normal_damping replace each other.
      if (own["restitution"]) law.remove("normal_damping");
      if (own["normal_damping"]) law.remove("restitution");
      for (const auto& k : own) law[k.first.as<std::string>()] = YAML::Clone(k.second);
    }
    contact["particle_particle"] = law;

    if (const YAML::Node pm = m["prepare"]) {
      YAML::Node prep = out["prepare"];
      if (prep && prep.IsMap() && !prep["deposition_friction"])
        prep["deposition_friction"] = YAML::Clone(pm["deposition_friction"]);
    }
    // The particle model the law was calibrated for; the config's own keys win (checked with
    // the config's particles section as usual). The material's rolling resistance belongs to
    // its model: a config that names another model does not get it.
    if (const YAML::Node pa = m["particles"]) {
      if (!out["particles"] || out["particles"].IsNull())
        out["particles"] = YAML::Node(YAML::NodeType::Map);
      YAML::Node parts = out["particles"];
      if (parts.IsMap()) {
        const bool own_model = !parts["model"] || !pa["model"] ||
                               (parts["model"].IsScalar() && pa["model"].IsScalar() &&
                                parts["model"].Scalar() == pa["model"].Scalar());
        for (const auto& k : pa) {
          const std::string key = k.first.as<std::string>();
          if (key == "rolling_resistance" && !own_model) continue;
          if (!parts[key]) parts[key] = YAML::Clone(k.second);
        }
      }
    }
  }
  return out;
}

}  // namespace dem
