#include "dem/config.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <filesystem>
#include <map>
#include <optional>
#include <numeric>
#include <stdexcept>
#include <sstream>

#include "cosim/paths.hpp"
#include "cosim/yaml_config.hpp"
#include "dem/bed.hpp"
#include "dem/checkpoint.hpp"
#include "dem/material_file.hpp"
#include "dem/packing.hpp"
#include "dem/coarse_grain.hpp"
#include "dem/rotation.hpp"

namespace dem {
namespace cfg = cosim::config;
using cfg::ConfigError;

namespace {

Vec3 vec3(const YAML::Node& n, const std::string& path, const std::string& key) {
  const auto v = cfg::get_vector(n, path, key, 3);
  return {v[0], v[1], v[2]};
}

RadiusDistribution parse_radius(const YAML::Node& n, const std::string& path) {
  RadiusDistribution d;
  if (n.IsScalar()) {
    try {
      d.min = d.max = n.as<double>();
    } catch (const YAML::Exception&) {
      throw ConfigError(path + ": expected a radius in metres or a distribution map, got '" +
                        n.Scalar() + "'");
    }
    if (!(d.min > 0) || !std::isfinite(d.min))
      throw ConfigError(path + ": radius must be > 0 m, got " + n.Scalar());
    return d;
  }
  cfg::check_keys(n, path, {"distribution", "min", "max", "values", "weights"});
  const std::string kind = cfg::get_choice(n, path, "distribution", {"uniform", "discrete"});
  if (kind == "uniform") {
    d.kind = RadiusDistribution::Kind::uniform;
    d.min = cfg::get_double(n, path, "min");
    d.max = cfg::get_double(n, path, "max");
    if (!(d.min > 0)) throw ConfigError(path + ".min: radius must be > 0 m");
    if (!(d.max >= d.min)) throw ConfigError(path + ".max: must be >= min");
  } else {
    d.kind = RadiusDistribution::Kind::discrete;
    if (!n["values"] || !n["values"].IsSequence() || n["values"].size() == 0)
      throw ConfigError(path + ".values: give a non-empty list of radii");
    for (const auto& v : n["values"]) d.values.push_back(v.as<double>());
    for (double v : d.values)
      if (!(v > 0)) throw ConfigError(path + ".values: every radius must be > 0 m");
    if (n["weights"]) {
      for (const auto& w : n["weights"]) d.weights.push_back(w.as<double>());
      if (d.weights.size() != d.values.size())
        throw ConfigError(path + ".weights: needs one weight per value");
    } else {
      d.weights.assign(d.values.size(), 1.0);
    }
    const double sum = std::accumulate(d.weights.begin(), d.weights.end(), 0.0);
    for (double w : d.weights)
      if (!(w >= 0) || !(sum > 0)) throw ConfigError(path + ".weights: must be >= 0, not all 0");
    for (double& w : d.weights) w /= sum;
    d.min = *std::min_element(d.values.begin(), d.values.end());
    d.max = *std::max_element(d.values.begin(), d.values.end());
  }
  return d;
}

int species_index(const Scene& scene, const std::string& name, const std::string& path) {
  for (std::size_t i = 0; i < scene.species.size(); ++i)
    if (scene.species[i].name == name) return static_cast<int>(i);
  std::string names;
  for (const auto& s : scene.species) names += (names.empty() ? "" : ", ") + s.name;
  throw ConfigError(path + ": unknown species '" + name + "' (defined: " + names + ")");
}

// --- Parsing, one function per section. Nothing here reads a file or places a particle; an
// absent optional key keeps the initialiser of its struct field (the one place a default is
// declared, listed in docs/dem.md).

void parse_stability(const YAML::Node& st, StabilityOptions& o) {
  const std::string p = "scene.stability";
  cfg::check_keys(st, p, {"min_steps_per_contact", "on_violation", "max_speed", "overlap_tolerance"});
  o.min_steps_per_contact = cfg::get_double_or(st, p, "min_steps_per_contact", o.min_steps_per_contact);
  if (!(o.min_steps_per_contact >= 1))
    throw ConfigError("scene.stability.min_steps_per_contact: must be >= 1");
  const bool warn = o.on_violation == DtViolation::warn;
  o.on_violation = cfg::get_choice(st, p, "on_violation", {"refuse", "warn"},
                                   warn ? "warn" : "refuse") == "warn"
                       ? DtViolation::warn
                       : DtViolation::refuse;
  o.max_speed = cfg::get_double_or(st, p, "max_speed", o.max_speed);
  if (!(o.max_speed > 0)) throw ConfigError("scene.stability.max_speed: must be > 0");
  o.overlap_tolerance = cfg::get_double_or(st, p, "overlap_tolerance", o.overlap_tolerance);
  if (!(o.overlap_tolerance >= 0))
    throw ConfigError("scene.stability.overlap_tolerance: must be >= 0");
}

ThreadWait parse_thread_wait(const YAML::Node& s, ThreadWait fallback) {
  const std::string v = cfg::get_choice(s, "scene", "thread_wait", {"passive", "brief", "spin", "yield"},
                                        thread_wait_name(fallback));
  for (ThreadWait w : kThreadWaits)
    if (v == thread_wait_name(w)) return w;
  return fallback;  // not reached: get_choice refused anything else
}

void parse_sleep(const YAML::Node& sl, const Scene& sc, SleepOptions& o) {
  const std::string p = "scene.sleep";
  if (!sl.IsMap())
    throw ConfigError(p + ": expected a map {enabled, speed, wake_speed, steps, tool_distance, "
                          "neighbourhood, close_pairs}");
  cfg::check_keys(sl, p, {"enabled", "speed", "wake_speed", "steps", "tool_distance",
                          "neighbourhood", "close_pairs"});
  o.close_pairs = cfg::get_bool_or(sl, p, "close_pairs", o.close_pairs);
  o.neighbourhood =
      cfg::get_choice(sl, p, "neighbourhood", {"sphere", "box"},
                      o.neighbourhood == SleepNeighbourhood::box ? "box" : "sphere") == "box"
          ? SleepNeighbourhood::box
          : SleepNeighbourhood::sphere;
  o.enabled = cfg::get_bool_or(sl, p, "enabled", o.enabled);
  o.speed = cfg::get_double_or(sl, p, "speed", o.speed);
  if (!(o.speed > 0) || !std::isfinite(o.speed))
    throw ConfigError("scene.sleep.speed: must be a speed > 0 in m/s (e.g. 0.01), got " +
                      std::to_string(o.speed));
  if (sl["wake_speed"]) o.wake_speed = cfg::get_double(sl, p, "wake_speed");
  // 0 is the default (wake at `speed`); given, it must be a speed up to `speed`.
  const bool wake_given = sl["wake_speed"] || o.wake_speed != 0;
  if (wake_given && (!(o.wake_speed > 0) || !std::isfinite(o.wake_speed) || o.wake_speed > o.speed)) {
    std::ostringstream msg;
    msg << "scene.sleep.wake_speed: must be a speed in (0, scene.sleep.speed = " << o.speed
        << "] m/s (an awake partner faster than it wakes a sleeper; e.g. speed / 5), got "
        << o.wake_speed << "; leave it out to wake at scene.sleep.speed";
    throw ConfigError(msg.str());
  }
  const long long steps = cfg::get_int_or(sl, p, "steps", o.steps);
  if (steps < 1 || steps > 100000000)
    throw ConfigError("scene.sleep.steps: must be between 1 and 1e8 steps (e.g. 200), got " +
                      std::to_string(steps));
  o.steps = static_cast<int>(steps);
  o.tool_distance = cfg::get_double_or(sl, p, "tool_distance", o.tool_distance);
  if (!(o.tool_distance >= 0) || !std::isfinite(o.tool_distance))
    throw ConfigError("scene.sleep.tool_distance: must be a distance >= 0 in m (e.g. 0.5), got " +
                      std::to_string(o.tool_distance));
  // A particle thrown up is slower than `speed` for 2 speed / (|g| dt) steps around its apex:
  // `steps` must be longer, or it would fall asleep in the air.
  const double g = norm(sc.gravity);
  if (o.enabled && g > 0) {
    const double apex = 2 * o.speed / (g * sc.dt);
    if (static_cast<double>(o.steps) <= apex) {
      std::ostringstream msg;
      msg << "scene.sleep.steps: " << o.steps << " steps is not longer than the " << apex
          << " steps a particle in free flight spends slower than scene.sleep.speed = "
          << o.speed << " m/s around its apex (2 speed / (|g| dt)); it would fall asleep in "
          << "the air. Raise scene.sleep.steps above " << static_cast<long long>(apex)
          << " or lower scene.sleep.speed";
      throw ConfigError(msg.str());
    }
  }
}

void parse_region(const YAML::Node& r, RegionOptions& o) {
  const std::string p = "scene.region";
  if (!r.IsMap()) throw ConfigError(p + ": expected a map {min: [x, y, z], max: [x, y, z]}");
  cfg::check_keys(r, p, {"min", "max"});
  if (!r["min"] || !r["max"])
    throw ConfigError(p + ": needs both min and max (the corners of the box particles must stay in)");
  o.min = vec3(r, p, "min");
  o.max = vec3(r, p, "max");
  if (!(o.min.x < o.max.x && o.min.y < o.max.y && o.min.z < o.max.z))
    throw ConfigError(p + ": min must be below max in x, y and z (swap the corners?)");
  o.enabled = true;
}

void parse_scene_options(const YAML::Node& s, Scene& sc) {
  if (!s) throw ConfigError("scene: missing (expected a map with dt, gravity, ...)");
  if (s.IsMap())
    for (const char* key : {"close_margin", "pair_schedule", "min_particles_per_thread"})
      if (s[key])
        throw ConfigError(std::string("scene.") + key + ": moved to performance." + key +
                          " (a top-level performance: section, beside scene:; how the engine "
                          "computes, not the scene; docs/dem.md#performance)");
  cfg::check_keys(s, "scene", {"dt", "gravity", "broad_phase_interval", "skin", "guard",
                               "threads", "thread_wait", "stability", "sleep", "region"});
  sc.dt = cfg::get_positive(s, "scene", "dt");
  if (s["gravity"]) sc.gravity = vec3(s, "scene", "gravity");
  sc.broad_phase_interval =
      static_cast<int>(cfg::get_int_or(s, "scene", "broad_phase_interval", sc.broad_phase_interval));
  if (sc.broad_phase_interval < 1)
    throw ConfigError("scene.broad_phase_interval: must be >= 1 (1 = broad phase every step)");
  sc.skin = cfg::get_double_or(s, "scene", "skin", sc.skin);
  if (!(sc.skin > 0)) throw ConfigError("scene.skin: must be > 0 (a fraction of r_max, e.g. 0.5)");
  const bool strict = sc.guard == GuardMode::strict;
  sc.guard = cfg::get_choice(s, "scene", "guard", {"rebuild", "strict"},
                             strict ? "strict" : "rebuild") == "strict"
                 ? GuardMode::strict
                 : GuardMode::rebuild;
  sc.threads = static_cast<int>(cfg::get_int_or(s, "scene", "threads", sc.threads));
  if (sc.threads < 1) throw ConfigError("scene.threads: must be >= 1");
  sc.thread_wait = parse_thread_wait(s, sc.thread_wait);
  if (const YAML::Node st = s["stability"]) parse_stability(st, sc.stability);
  if (const YAML::Node sl = s["sleep"]) parse_sleep(sl, sc, sc.sleep);
  if (const YAML::Node r = s["region"]) parse_region(r, sc.region);
}

// performance: how the engine computes (EngineOptions), never what: every value gives the same
// results (pair_schedule ranges: for one thread count). Absent: the defaults.
EngineOptions parse_performance(const YAML::Node& p, const Scene& sc) {
  EngineOptions o;
  if (!p) return o;
  const std::string w = "performance";
  if (!p.IsMap())
    throw ConfigError(w + ": expected a map {close_margin, pair_schedule, min_particles_per_thread}");
  cfg::check_keys(p, w, {"close_margin", "pair_schedule", "min_particles_per_thread"});
  o.close_margin = cfg::get_double_or(p, w, "close_margin", o.close_margin);
  if (!(o.close_margin >= 0 && o.close_margin < sc.skin)) {
    std::ostringstream msg;
    msg << "performance.close_margin: must be >= 0 and below scene.skin (now " << sc.skin
        << "), a fraction of r_max like the skin, e.g. 0.08; 0 turns close pairs off";
    throw ConfigError(msg.str());
  }
  o.pair_schedule =
      cfg::get_choice(p, w, "pair_schedule", {"blocks", "ranges"},
                      o.pair_schedule == PairSchedule::blocks ? "blocks" : "ranges") == "blocks"
          ? PairSchedule::blocks
          : PairSchedule::ranges;
  o.min_particles_per_thread = static_cast<int>(
      cfg::get_int_or(p, w, "min_particles_per_thread", o.min_particles_per_thread));
  if (o.min_particles_per_thread < 1)
    throw ConfigError(
        "performance.min_particles_per_thread: must be >= 1 (1 = always use scene.threads)");
  return o;
}

std::vector<Species> parse_species(const YAML::Node& mats, const YAML::Node& sps) {
  std::map<std::string, double> density;
  if (!mats || !mats.IsMap() || mats.size() == 0)
    throw ConfigError("materials: missing (expected e.g. {sand: {density: 2600}})");
  for (const auto& kv : mats) {
    const std::string name = kv.first.as<std::string>();
    const std::string p = "materials." + name;
    cfg::check_keys(kv.second, p, {"density"});
    density[name] = cfg::get_positive(kv.second, p, "density");
  }
  if (!sps || !sps.IsSequence() || sps.size() == 0)
    throw ConfigError("species: missing (expected a list of {name, material, radius})");
  std::vector<Species> out;
  for (std::size_t i = 0; i < sps.size(); ++i) {
    const std::string p = "species[" + std::to_string(i) + "]";
    cfg::check_keys(sps[i], p, {"name", "material", "radius"});
    Species sp;
    sp.name = cfg::get_string(sps[i], p, "name");
    const std::string mat = cfg::get_string(sps[i], p, "material");
    if (!density.count(mat))
      throw ConfigError(p + ".material: unknown material '" + mat + "'; define it under materials");
    sp.density = density[mat];
    if (!sps[i]["radius"]) throw ConfigError(p + ".radius: missing (metres, or a distribution)");
    sp.radius = parse_radius(sps[i]["radius"], p + ".radius");
    out.push_back(sp);
  }
  return out;
}

void parse_contact(const YAML::Node& c, Scene& sc) {
  if (!c) throw ConfigError("contact: missing (expected particle_particle and optional particle_wall)");
  cfg::check_keys(c, "contact", {"particle_particle", "particle_wall"});
  if (!c["particle_particle"]) throw ConfigError("contact.particle_particle: missing");
  sc.particle_particle = parse_contact_law(c["particle_particle"], "contact.particle_particle");
  sc.particle_wall = c["particle_wall"]
                         ? parse_contact_law(c["particle_wall"], "contact.particle_wall")
                         : sc.particle_particle;
}

std::vector<Wall> parse_walls(const YAML::Node& w) {
  std::vector<Wall> walls;
  if (!w) return walls;
  for (std::size_t i = 0; i < w.size(); ++i) {
    const std::string p = "walls[" + std::to_string(i) + "]";
    const std::string type = cfg::get_choice(w[i], p, "type", {"plane", "box"});
    const std::string name = cfg::get_string(w[i], p, "name");
    if (type == "plane") {
      cfg::check_keys(w[i], p, {"name", "type", "point", "normal", "contact"});
      Vec3 n = vec3(w[i], p, "normal");
      if (!(norm(n) > 0)) throw ConfigError(p + ".normal: must be non-zero");
      walls.push_back({name, vec3(w[i], p, "point"), (1.0 / norm(n)) * n});
    } else {
      cfg::check_keys(w[i], p, {"name", "type", "min", "max", "open_top", "contact"});
      const Vec3 lo = vec3(w[i], p, "min"), hi = vec3(w[i], p, "max");
      if (!(hi.x > lo.x && hi.y > lo.y && hi.z > lo.z))
        throw ConfigError(p + ": max must exceed min in x, y and z");
      // A container: particles stay inside, so each face's normal points inwards.
      walls.push_back({name + "/xmin", lo, {1, 0, 0}, true, lo, hi});
      walls.push_back({name + "/xmax", hi, {-1, 0, 0}, true, lo, hi});
      walls.push_back({name + "/ymin", lo, {0, 1, 0}, true, lo, hi});
      walls.push_back({name + "/ymax", hi, {0, -1, 0}, true, lo, hi});
      walls.push_back({name + "/zmin", lo, {0, 0, 1}, true, lo, hi});
      if (!cfg::get_bool_or(w[i], p, "open_top", true))
        walls.push_back({name + "/zmax", hi, {0, 0, -1}, true, lo, hi});
    }
  }
  return walls;
}

// walls[i].contact / tools[i].contact: a law of the wall's or tool's own, given as the keys
// that differ from contact.particle_wall (or particle_particle when that is left out); giving
// restitution replaces the base's normal_damping and the other way round. Parsed and validated
// as a whole law under its own dotted path.
ContactLaw boundary_law(const YAML::Node& contact, const YAML::Node& over, const std::string& path) {
  if (!over.IsMap())
    throw ConfigError(path + ": expected a map of contact-law keys (e.g. {friction: 0.0}) that "
                             "replace those of contact.particle_wall");
  YAML::Node merged = YAML::Clone(contact["particle_wall"] ? contact["particle_wall"]
                                                           : contact["particle_particle"]);
  if (over["restitution"]) merged.remove("normal_damping");
  if (over["normal_damping"]) merged.remove("restitution");
  for (const auto& kv : over) merged[kv.first.as<std::string>()] = kv.second;
  return parse_contact_law(merged, path);
}

// Scene::boundary_laws from walls[].contact and tools[].contact (after parse_walls and the
// tools): each config wall's law goes to every plane it made (a box makes 5 or 6).
void parse_boundary_laws(const YAML::Node& root, Scene& sc) {
  const YAML::Node contact = root["contact"];
  std::size_t plane = 0;
  if (const YAML::Node w = root["walls"])
    for (std::size_t i = 0; i < w.size(); ++i) {
      const std::string p = "walls[" + std::to_string(i) + "]";
      const bool box = cfg::get_string(w[i], p, "type") == "box";
      const std::size_t planes = !box ? 1 : cfg::get_bool_or(w[i], p, "open_top", true) ? 5 : 6;
      if (w[i]["contact"]) {
        sc.boundary_laws.push_back(boundary_law(contact, w[i]["contact"], p + ".contact"));
        for (std::size_t k = plane; k < plane + planes; ++k)
          sc.walls[k].law = static_cast<int>(sc.boundary_laws.size() - 1);
      }
      plane += planes;
    }
  if (const YAML::Node t = root["tools"])
    for (std::size_t i = 0; i < t.size(); ++i)
      if (t[i]["contact"]) {
        sc.boundary_laws.push_back(boundary_law(contact, t[i]["contact"], "tools[" + std::to_string(i) + "].contact"));
        sc.tools[i].law = static_cast<int>(sc.boundary_laws.size() - 1);
      }
}

// A tool as the config describes it: the files are read by load_tool.
struct ToolSource {
  std::string path;  // dotted, for messages
  std::string name;
  std::string mesh;  // file, as written
  double scale = 1.0;
  Vec3 reference_point;
  ToolMotion motion;  // keyframes given inline (or the fixed pose), else empty
  std::string csv;    // keyframes file, as written ("" = none)
};

std::vector<ToolSource> parse_tools(const YAML::Node& t) {
  std::vector<ToolSource> tools;
  if (!t) return tools;
  for (std::size_t i = 0; i < t.size(); ++i) {
    ToolSource tool;
    const std::string& p = tool.path = "tools[" + std::to_string(i) + "]";
    cfg::check_keys(t[i], p, {"name", "mesh", "scale", "reference_point", "motion", "contact"});
    tool.name = cfg::get_string(t[i], p, "name");
    tool.scale = cfg::get_positive_or(t[i], p, "scale", tool.scale);
    if (t[i]["reference_point"]) tool.reference_point = vec3(t[i], p, "reference_point");
    tool.mesh = cfg::get_string(t[i], p, "mesh");
    if (const YAML::Node m = t[i]["motion"]) {
      const std::string mp = p + ".motion";
      cfg::check_keys(m, mp, {"interpolation", "keyframes", "csv"});
      cosim::MotionSource motion = cosim::read_motion(m, mp);
      static_cast<cosim::Trajectory&>(tool.motion) = std::move(motion.trajectory);
      tool.csv = std::move(motion.csv);
    } else {
      tool.motion.keyframes = {Keyframe{}};  // fixed: mesh frame = world frame
    }
    tools.push_back(std::move(tool));
  }
  return tools;
}

// A particle of particles.list, checked against its species.
struct ListedParticle {
  int species = 0;
  Vec3 position, velocity;
  double radius = 0;
};

// The particles section: what to load, place and fill, in that order.
struct ParticleSources {
  std::string checkpoint;  // as written ("" = none)
  bool keep_time = false;
  Perturbation perturb;
  std::vector<ListedParticle> list;
  std::vector<FillRegion> fill;
  std::vector<InsertRegion> insert;
};

std::vector<FillRegion> parse_regions(const YAML::Node& list, const std::string& key, const Scene& sc);

ParticleSources parse_particles(const YAML::Node& parts, const Scene& sc) {
  if (!parts) throw ConfigError("particles: missing (give fill, list or checkpoint)");
  cfg::check_keys(parts, "particles", {"fill", "insert", "list", "checkpoint", "keep_time", "perturb",
                                       "model", "rolling_resistance",  // rotation.cpp
                                       "coarse_grain"});               // coarse_grain.cpp
  ParticleSources src;
  if (const YAML::Node pt = parts["perturb"]) {
    cfg::check_keys(pt, "particles.perturb", {"amplitude", "seed"});
    src.perturb.amplitude = cfg::get_double_or(pt, "particles.perturb", "amplitude", 0.0);
    if (!(src.perturb.amplitude >= 0) || !std::isfinite(src.perturb.amplitude))
      throw ConfigError("particles.perturb.amplitude: must be a finite length >= 0 m, got " +
                        std::to_string(src.perturb.amplitude));
    double r_min = std::numeric_limits<double>::infinity();
    for (const Species& sp : sc.species) r_min = std::min(r_min, sp.radius.min);
    if (src.perturb.amplitude > kMaxPerturbation * r_min) {
      std::ostringstream m;
      m << "particles.perturb.amplitude: " << src.perturb.amplitude << " m is more than "
        << kMaxPerturbation << " of the smallest radius (" << r_min
        << " m); a perturbation for ensembles must be physically negligible (try 1e-6 of the "
           "radius)";
      throw ConfigError(m.str());
    }
    const long long seed = cfg::get_int_or(pt, "particles.perturb", "seed", 0);
    if (seed < 0) throw ConfigError("particles.perturb.seed: must be an integer >= 0");
    src.perturb.seed = static_cast<std::uint64_t>(seed);
  }
  if (parts["checkpoint"]) {
    src.checkpoint = cfg::get_string(parts, "particles", "checkpoint");
    src.keep_time = cfg::get_bool_or(parts, "particles", "keep_time", src.keep_time);
  }
  if (const YAML::Node f = parts["fill"]) src.fill = parse_regions(f, "particles.fill", sc);
  if (const YAML::Node ins = parts["insert"]) src.insert = parse_regions(ins, "particles.insert", sc);
  if (const YAML::Node l = parts["list"]) {
    for (std::size_t i = 0; i < l.size(); ++i) {
      const std::string p = "particles.list[" + std::to_string(i) + "]";
      cfg::check_keys(l[i], p, {"species", "position", "velocity", "radius"});
      ListedParticle lp;
      lp.species = species_index(sc, cfg::get_string(l[i], p, "species"), p + ".species");
      lp.radius = l[i]["radius"] ? cfg::get_double(l[i], p, "radius")
                                 : sc.species[lp.species].radius.max;
      if (!(lp.radius > 0) || !std::isfinite(lp.radius))
        throw ConfigError(p + ".radius: must be a positive number of metres, got " +
                          std::to_string(lp.radius));
      if (l[i]["velocity"]) lp.velocity = vec3(l[i], p, "velocity");
      lp.position = vec3(l[i], p, "position");
      src.list.push_back(lp);
    }
  }
  return src;
}

// particles.fill (a jittered lattice) and particles.insert (random sequential insertion): a list
// of {species, min, max, count, seed}.
std::vector<FillRegion> parse_regions(const YAML::Node& list, const std::string& key, const Scene& sc) {
  std::vector<FillRegion> out;
  if (!list.IsSequence())
    throw ConfigError(key + ": expected a list of {species, min, max, count, seed}");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string p = key + "[" + std::to_string(i) + "]";
    cfg::check_keys(list[i], p, {"species", "min", "max", "count", "seed"});
    FillRegion r;
    r.species = species_index(sc, cfg::get_string(list[i], p, "species"), p + ".species");
    r.min = vec3(list[i], p, "min");
    r.max = vec3(list[i], p, "max");
    r.count = cfg::get_int(list[i], p, "count");
    if (r.count < 0) throw ConfigError(p + ".count: must be >= 0");
    const long long seed = cfg::get_int_or(list[i], p, "seed", static_cast<long long>(r.seed));
    if (seed < 0) throw ConfigError(p + ".seed: must be an integer >= 0");
    r.seed = static_cast<unsigned long long>(seed);
    out.push_back(r);
  }
  return out;
}

// prepare: the deposition of the inserted (or filled) grains, then frozen into contact.
PrepareOptions parse_prepare(const YAML::Node& pr) {
  PrepareOptions o;
  if (!pr) return o;
  const std::string p = "prepare";
  if (!pr.IsMap())
    throw ConfigError("prepare: expected a map {deposition_friction, ke_per_particle, max_time, "
                      "margin, checkpoint}");
  cfg::check_keys(pr, p, {"deposition_friction", "ke_per_particle", "max_time", "margin", "checkpoint"});
  o.enabled = true;
  o.deposition_friction = cfg::get_double_or(pr, p, "deposition_friction", o.deposition_friction);
  if (!(o.deposition_friction >= 0) || !std::isfinite(o.deposition_friction))
    throw ConfigError("prepare.deposition_friction: must be a Coulomb coefficient >= 0 (0 = "
                      "frictionless fall, densest), got " + std::to_string(o.deposition_friction));
  o.ke_per_particle = cfg::get_positive_or(pr, p, "ke_per_particle", o.ke_per_particle);
  o.max_time = cfg::get_positive_or(pr, p, "max_time", o.max_time);
  o.margin = cfg::get_double_or(pr, p, "margin", o.margin);
  if (!(o.margin >= 0) || !std::isfinite(o.margin))
    throw ConfigError("prepare.margin: must be >= 0 mean grain diameters (e.g. 2.5), got " +
                      std::to_string(o.margin));
  o.checkpoint = cfg::get_string_or(pr, p, "checkpoint", o.checkpoint);
  return o;
}

// A bed saved with its largest overlap (/bed/max_overlap_ratio, written by dem_run when it
// prepares or settles a bed) reloads whatever scene.stability.overlap_tolerance says: the
// tolerance is raised to the overlap the bed was made with.
void follow_bed_overlap(const std::string& checkpoint, StabilityOptions& o) {
  if (checkpoint.empty()) return;
  if (const std::optional<double> made = read_bed_overlap(checkpoint))
    o.overlap_tolerance = std::max(o.overlap_tolerance, *made * (1 + 1e-9));
}

SettleOptions parse_settle(const YAML::Node& st) {
  SettleOptions o;
  if (!st) return o;
  cfg::check_keys(st, "settle", {"ke_per_particle", "max_time", "checkpoint"});
  o.enabled = true;
  o.ke_per_particle = cfg::get_positive_or(st, "settle", "ke_per_particle", o.ke_per_particle);
  o.max_time = cfg::get_positive_or(st, "settle", "max_time", o.max_time);
  // An output: relative to the working directory, like output.file.
  o.checkpoint = cfg::get_string_or(st, "settle", "checkpoint", o.checkpoint);
  return o;
}

double parse_run(const YAML::Node& r, double duration) {
  if (!r) return duration;
  cfg::check_keys(r, "run", {"duration"});
  duration = cfg::get_double(r, "run", "duration");
  if (!(duration >= 0)) throw ConfigError("run.duration: must be >= 0 s");
  return duration;
}

OutputOptions parse_output(const YAML::Node& o) {
  OutputOptions out;
  if (!o) return out;
  cfg::check_keys(o, "output", {"file", "particles_every", "wrenches_every", "progress_every",
                                "checkpoint"});
  out.file = cfg::get_string_or(o, "output", "file", out.file);
  out.particles_every = cfg::get_double_or(o, "output", "particles_every", out.particles_every);
  out.wrenches_every = cfg::get_double_or(o, "output", "wrenches_every", out.wrenches_every);
  out.progress_every = cfg::get_double_or(o, "output", "progress_every", out.progress_every);
  out.checkpoint = cfg::get_string_or(o, "output", "checkpoint", out.checkpoint);
  if (out.particles_every < 0 || out.wrenches_every < 0)
    throw ConfigError("output.particles_every / wrenches_every: must be >= 0 s (0 = every step "
                      "for wrenches, start and end for particles)");
  return out;
}

// --- File loading: meshes, keyframe CSVs, checkpoints (paths relative to base_dir).

Tool load_tool(const ToolSource& src, const std::string& base_dir,
               std::vector<cosim::NamedFile>& inputs) {
  Tool tool;
  tool.name = src.name;
  const std::string mesh = cosim::input_path(base_dir, src.mesh);
  inputs.push_back({src.path + ".mesh", mesh});
  if (!src.csv.empty())
    inputs.push_back({src.path + ".motion.csv", cosim::input_path(base_dir, src.csv)});
  try {
    tool.mesh = load_mesh(mesh, src.scale, src.reference_point);
  } catch (const std::runtime_error& e) {
    throw ConfigError(src.path + ".mesh: " + e.what());
  }
  static_cast<cosim::Trajectory&>(tool.motion) =
      cosim::load_motion({src.motion, src.csv}, src.path + ".motion", base_dir);
  return tool;
}

State load_bed(const ParticleSources& src, const std::string& base_dir,
               std::vector<cosim::NamedFile>& inputs) {
  if (src.checkpoint.empty()) return State{};
  State s;
  inputs.push_back({"particles.checkpoint", cosim::input_path(base_dir, src.checkpoint)});
  try {
    s = load_checkpoint(inputs.back().path);
  } catch (const std::exception& e) {
    throw ConfigError(std::string("particles.checkpoint: ") + e.what());
  }
  // A prepared bed starts a new scene at t = 0 (tool keyframes count from there); keep the
  // checkpoint's time only to continue the same run.
  // A new scene also starts its own count of particles removed from its region of interest
  // (a preparation's removals are not this run's).
  if (!src.keep_time) {
    s.step = 0;
    s.removed_count = 0;
    s.removed_mass = 0;
  }
  return s;
}

// --- Generation: the listed particles, then the fill regions, after the loaded bed.

void place_listed(const Scene& sc, const std::vector<ListedParticle>& list, State& s) {
  for (const ListedParticle& lp : list) {
    const Species& sp = sc.species[lp.species];
    const double r = lp.radius;
    const std::int64_t id = s.id.empty() ? 0 : *std::max_element(s.id.begin(), s.id.end()) + 1;
    add_particle(s, lp.position, lp.velocity, r, sp.mass(r), lp.species, id);
  }
}

// Splitmix64: a well-mixed 64-bit hash, so a particle's displacement depends only on (seed,
// particle id, axis), not on the order of the particles or the library's random engines.
std::uint64_t mix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

bool parts_listed_empty(const YAML::Node& root) {
  const YAML::Node l = root["particles"]["list"];
  return l && l.IsSequence() && l.size() == 0;
}

// Checkpointed beds may come from another scene: the tool count is this scene's.
void pose_tools(const Scene& sc, State& s) {
  s.tool_pose.resize(sc.tools.size());
  for (std::size_t m = 0; m < sc.tools.size(); ++m)
    s.tool_pose[m] = sc.tools[m].motion.evaluate(s.step * sc.dt);
  if (s.tool_pose_at_rebuild.size() != sc.tools.size()) s.lists_valid = false;
}

}  // namespace

void perturb_positions(State& s, const Perturbation& p) {
  if (!(p.amplitude > 0)) return;
  for (std::size_t i = 0; i < s.size(); ++i) {
    double d[3];
    for (int a = 0; a < 3; ++a) {
      const std::uint64_t h = mix64(mix64(p.seed) ^ mix64(static_cast<std::uint64_t>(s.id[i]) * 3 + a));
      // 53 random bits -> [0, 1) -> [-1, 1)
      d[a] = p.amplitude * (2.0 * static_cast<double>(h >> 11) * 0x1.0p-53 - 1.0);
    }
    s.x[i] += Vec3{d[0], d[1], d[2]};
  }
}

ThreadWait read_thread_wait(const YAML::Node& root) {
  if (!root.IsMap()) return Scene{}.thread_wait;  // load_config names the problem
  const YAML::Node s = root["scene"];
  if (!s || !s.IsMap()) return Scene{}.thread_wait;  // load_config names the problem
  return parse_thread_wait(s, Scene{}.thread_wait);
}

RunConfig load_config(const YAML::Node& given, const std::string& base_dir) {
  std::vector<cosim::NamedFile> material_files;  // materials.<name>.file (docs/soil.md)
  const YAML::Node root = resolve_material_files(given, base_dir, material_files);
  cfg::check_keys(root, "", {"scene", "performance", "materials", "species", "contact", "walls",
                             "tools", "particles", "prepare", "settle", "run", "output"});
  RunConfig rc;
  {
    std::ostringstream text;
    text << root;
    rc.config_text = text.str();
  }
  rc.inputs = material_files;
  Scene& sc = rc.scene;
  parse_scene_options(root["scene"], sc);
  rc.performance = parse_performance(root["performance"], sc);
  sc.species = parse_species(root["materials"], root["species"]);
  parse_contact(root["contact"], sc);
  sc.walls = parse_walls(root["walls"]);
  for (const ToolSource& t : parse_tools(root["tools"]))
    sc.tools.push_back(load_tool(t, base_dir, rc.inputs));
  parse_boundary_laws(root, sc);
  const ParticleSources particles = parse_particles(root["particles"], sc);
  parse_rotation(root["particles"], sc);  // particles.model, particles.rolling_resistance
  rc.fill = particles.fill;
  rc.insert = particles.insert;
  // particles.coarse_grain (dem/coarse_grain.hpp): the same material at larger grains.
  if (const double cg = parse_coarse_grain(root["particles"]); cg != 1.0) {
    if (!particles.checkpoint.empty() || !particles.list.empty())
      throw ConfigError("particles.coarse_grain: a checkpoint or a list holds grains of their own "
                        "size; coarse-grain the config that prepared the bed (its fill or insert) "
                        "instead, or leave coarse_grain out");
    coarse_grain_scene(sc, cg);
    for (FillRegion& r : rc.fill) r.count = coarse_grain_count(r.count, cg);
    for (InsertRegion& r : rc.insert) r.count = coarse_grain_count(r.count, cg);
  }
  rc.prepare = parse_prepare(root["prepare"]);
  rc.settle = parse_settle(root["settle"]);
  rc.duration = parse_run(root["run"], rc.duration);
  rc.output = parse_output(root["output"]);

  rc.state = load_bed(particles, base_dir, rc.inputs);
  if (!particles.checkpoint.empty()) follow_bed_overlap(rc.inputs.back().path, sc.stability);
  rc.continues = !particles.checkpoint.empty() && particles.keep_time && particles.list.empty() &&
                 rc.fill.empty() && rc.insert.empty();
  place_listed(sc, particles.list, rc.state);
  {  // Before the particle arrays grow: the scene must fit in memory (docs/dem.md#memory).
    double total = static_cast<double>(rc.state.size());
    for (std::size_t i = 0; i < rc.fill.size(); ++i) {
      total += static_cast<double>(rc.fill[i].count);
      check_memory_for_particles(total, "particles.fill[" + std::to_string(i) + "].count");
    }
  }
  for (const FillRegion& r : rc.fill) fill_region(sc, r, rc.state);
  for (std::size_t i = 0; i < rc.insert.size(); ++i)
    insert_random(sc, rc.insert[i], rc.state, "particles.insert[" + std::to_string(i) + "]");
  if (rc.state.size() == 0) {
    std::string why;
    auto add = [&](const char* r) { why += (why.empty() ? "" : "; ") + std::string(r); };
    if (!particles.checkpoint.empty()) add("particles.checkpoint holds none");
    if (parts_listed_empty(root)) add("particles.list is empty");
    if (!rc.fill.empty()) add("particles.fill places none (count 0)");
    if (!rc.insert.empty()) add("particles.insert places none (count 0)");
    if (why.empty()) add("none given");
    throw ConfigError("particles: the scene has no particles (" + why +
                      "): give at least one in particles.list, a particles.fill count > 0 or a "
                      "particles.checkpoint with particles");
  }
  perturb_positions(rc.state, particles.perturb);
  rc.perturb = particles.perturb;
  pose_tools(sc, rc.state);
  return rc;
}

std::vector<cosim::NamedFile> output_files(const RunConfig& rc, const std::string& output_key) {
  std::vector<cosim::NamedFile> out{{output_key, rc.output.file}};
  if (!rc.output.file.empty())
    out.push_back({"the XDMF file beside " + output_key,
                   std::filesystem::path(rc.output.file).replace_extension(".xdmf").string()});
  out.push_back({"output.checkpoint", rc.output.checkpoint});
  if (rc.settle.enabled) out.push_back({"settle.checkpoint", rc.settle.checkpoint});
  if (rc.prepare.enabled) out.push_back({"prepare.checkpoint", rc.prepare.checkpoint});
  return out;
}

void check_files(const RunConfig& rc, const std::string& config_path, const std::string& output_key,
                 const std::vector<cosim::NamedFile>& extra_outputs, bool require_folders) {
  std::vector<cosim::NamedFile> outputs = output_files(rc, output_key);
  outputs.insert(outputs.end(), extra_outputs.begin(), extra_outputs.end());
  std::vector<cosim::NamedFile> inputs{{"the config file", config_path}};
  inputs.insert(inputs.end(), rc.inputs.begin(), rc.inputs.end());
  cosim::check_output_files(outputs, inputs, require_folders);
}

}  // namespace dem
