#include "dem/config.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <numeric>
#include <sstream>

#include "cosim/yaml_config.hpp"
#include "dem/checkpoint.hpp"

namespace dem {
namespace cfg = cosim::config;
using cfg::ConfigError;

namespace {

Vec3 vec3(const YAML::Node& n, const std::string& path, const std::string& key) {
  const auto v = cfg::get_vector(n, path, key, 3);
  return {v[0], v[1], v[2]};
}

// Input files are looked up next to the config first, then in the working directory.
std::string resolve(const std::string& base, const std::string& p) {
  if (p.empty() || std::filesystem::path(p).is_absolute() || base.empty()) return p;
  const std::string beside = (std::filesystem::path(base) / p).string();
  if (!std::filesystem::exists(beside) && std::filesystem::exists(p)) return p;
  return beside;
}

ContactLaw parse_law(const YAML::Node& n, const std::string& path) {
  cfg::check_keys(n, path,
                  {"normal_stiffness", "stiffness_unit", "restitution", "normal_damping",
                   "clip_attractive", "tangential_stiffness_ratio", "tangential_damping_ratio",
                   "friction"});
  ContactLaw l;
  l.normal_stiffness = cfg::get_positive(n, path, "normal_stiffness");
  l.stiffness_per_length = cfg::get_choice(n, path, "stiffness_unit", {"Pa", "N/m"}, "Pa") == "Pa";
  const bool has_e = static_cast<bool>(n["restitution"]);
  const bool has_eta = static_cast<bool>(n["normal_damping"]);
  if (has_e == has_eta)
    throw ConfigError(path + ": give exactly one of restitution (0..1) or normal_damping (N s/m)");
  l.damping_from_restitution = has_e;
  if (has_e) {
    l.restitution = cfg::get_double(n, path, "restitution");
    if (!(l.restitution > 0 && l.restitution <= 1))
      throw ConfigError(path + ".restitution: " + std::to_string(l.restitution) +
                        " is not in (0, 1]");
  } else {
    l.normal_damping = cfg::get_double(n, path, "normal_damping");
  }
  l.clip_attractive = cfg::get_bool_or(n, path, "clip_attractive", true);
  l.tangential_stiffness_ratio = cfg::get_double_or(n, path, "tangential_stiffness_ratio", 1.0);
  l.tangential_damping_ratio = cfg::get_double_or(n, path, "tangential_damping_ratio", 0.5);
  l.friction = cfg::get_double_or(n, path, "friction", 0.5);
  try {
    finalize(l, path);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(e.what());
  }
  return l;
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

std::vector<Keyframe> parse_keyframes(const YAML::Node& n, const std::string& path) {
  if (!n.IsSequence() || n.size() == 0)
    throw ConfigError(path + ": give a list of {time, position, orientation}");
  std::vector<Keyframe> keys;
  for (std::size_t i = 0; i < n.size(); ++i) {
    const std::string p = path + "[" + std::to_string(i) + "]";
    cfg::check_keys(n[i], p, {"time", "position", "orientation"});
    Keyframe k;
    k.time = cfg::get_double(n[i], p, "time");
    k.position = vec3(n[i], p, "position");
    if (n[i]["orientation"]) {
      const auto q = cfg::get_vector(n[i], p, "orientation", 4);
      k.orientation = {q[0], q[1], q[2], q[3]};
    }
    keys.push_back(k);
  }
  try {
    validate_keyframes(keys, path);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(e.what());
  }
  return keys;
}

int species_index(const Scene& scene, const std::string& name, const std::string& path) {
  for (std::size_t i = 0; i < scene.species.size(); ++i)
    if (scene.species[i].name == name) return static_cast<int>(i);
  std::string names;
  for (const auto& s : scene.species) names += (names.empty() ? "" : ", ") + s.name;
  throw ConfigError(path + ": unknown species '" + name + "' (defined: " + names + ")");
}

}  // namespace

double sample_radius(const Species& sp, std::uint64_t& rng) {
  // splitmix64: the same numbers on every platform, unlike std:: distributions.
  auto next = [&] {
    std::uint64_t z = (rng += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return static_cast<double>((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
  };
  const RadiusDistribution& d = sp.radius;
  switch (d.kind) {
    case RadiusDistribution::Kind::constant:
      return d.min;
    case RadiusDistribution::Kind::uniform:
      return d.min + (d.max - d.min) * next();
    case RadiusDistribution::Kind::discrete: {
      double u = next(), acc = 0;
      for (std::size_t k = 0; k < d.values.size(); ++k) {
        acc += d.weights[k];
        if (u < acc) return d.values[k];
      }
      return d.values.back();
    }
  }
  return d.min;
}

void fill_region(const Scene& scene, const FillRegion& region, State& s) {
  const Species& sp = scene.species[region.species];
  const double rmax = std::max(sp.radius.max, sp.radius.min);
  // 15 % slack: the jitter is large enough that settling columns collapse into a random
  // packing instead of staying stacked, and neighbours can never overlap.
  const double pitch = 2 * rmax * 1.15;
  // Half a pitch from the region's faces: a jittered particle stays inside the region.
  const double e = pitch / 2;
  const Vec3 lo = region.min + Vec3{e, e, e}, hi = region.max - Vec3{e, e, e};
  const long nx = static_cast<long>(std::floor((hi.x - lo.x) / pitch)) + 1;
  const long ny = static_cast<long>(std::floor((hi.y - lo.y) / pitch)) + 1;
  const long nz = static_cast<long>(std::floor((hi.z - lo.z) / pitch)) + 1;
  if (hi.x < lo.x || hi.y < lo.y || hi.z < lo.z || nx * ny * nz < region.count) {
    std::ostringstream msg;
    msg << "particles.fill: region holds at most "
        << (hi.x < lo.x || hi.y < lo.y || hi.z < lo.z ? 0 : nx * ny * nz) << " particles of '"
        << sp.name << "' (lattice pitch " << pitch << " m) but count is " << region.count
        << "; enlarge the region or lower count";
    throw ConfigError(msg.str());
  }
  std::uint64_t rng = region.seed * 0x2545F4914F6CDD1Dull + 12345;
  auto uniform = [&] {
    std::uint64_t z = (rng += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return static_cast<double>((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
  };
  long long placed = 0;
  std::int64_t next_id = s.id.empty() ? 0 : *std::max_element(s.id.begin(), s.id.end()) + 1;
  for (long iz = 0; iz < nz && placed < region.count; ++iz) {
    // Random order within a layer so a partly filled top layer is not one-sided.
    std::vector<long> cells(static_cast<std::size_t>(nx * ny));
    std::iota(cells.begin(), cells.end(), 0);
    for (std::size_t k = cells.size(); k > 1; --k)
      std::swap(cells[k - 1], cells[static_cast<std::size_t>(uniform() * k)]);
    for (long c : cells) {
      if (placed >= region.count) break;
      const double r = sample_radius(sp, rng);
      const double slack = pitch / 2 - r;  // room to jitter without touching a neighbour
      const Vec3 centre{lo.x + (c % nx) * pitch, lo.y + (c / nx) * pitch, lo.z + iz * pitch};
      const Vec3 jitter{slack * (2 * uniform() - 1), slack * (2 * uniform() - 1),
                        slack * (2 * uniform() - 1)};
      const double mass = sp.density * 4.0 / 3.0 * M_PI * r * r * r;
      add_particle(s, centre + 0.999 * jitter, {}, r, mass, region.species, next_id++);
      ++placed;
    }
  }
}

RunConfig load_config(const YAML::Node& root, const std::string& base_dir) {
  RunConfig rc;
  Scene& sc = rc.scene;
  cfg::check_keys(root, "", {"scene", "materials", "species", "contact", "walls", "tools",
                             "particles", "settle", "run", "output"});
  {
    std::ostringstream text;
    text << root;
    rc.config_text = text.str();
  }
  // scene
  const YAML::Node s = root["scene"];
  if (!s) throw ConfigError("scene: missing (expected a map with dt, gravity, ...)");
  cfg::check_keys(s, "scene", {"dt", "gravity", "broad_phase_interval", "skin", "guard", "threads",
                               "min_particles_per_thread", "stability"});
  sc.dt = cfg::get_positive(s, "scene", "dt");
  if (s["gravity"]) sc.gravity = vec3(s, "scene", "gravity");
  sc.broad_phase_interval = static_cast<int>(cfg::get_int_or(s, "scene", "broad_phase_interval", 5));
  if (sc.broad_phase_interval < 1)
    throw ConfigError("scene.broad_phase_interval: must be >= 1 (1 = broad phase every step)");
  sc.skin = cfg::get_double_or(s, "scene", "skin", 0.5);
  if (!(sc.skin > 0)) throw ConfigError("scene.skin: must be > 0 (a fraction of r_max, e.g. 0.5)");
  sc.guard = cfg::get_choice(s, "scene", "guard", {"rebuild", "strict"}, "rebuild") == "strict"
                 ? GuardMode::strict
                 : GuardMode::rebuild;
  sc.threads = static_cast<int>(cfg::get_int_or(s, "scene", "threads", 1));
  if (sc.threads < 1) throw ConfigError("scene.threads: must be >= 1");
  sc.min_particles_per_thread =
      static_cast<int>(cfg::get_int_or(s, "scene", "min_particles_per_thread", 2000));
  if (sc.min_particles_per_thread < 1)
    throw ConfigError("scene.min_particles_per_thread: must be >= 1 (1 = always use scene.threads)");
  if (const YAML::Node st = s["stability"]) {
    cfg::check_keys(st, "scene.stability",
                    {"min_steps_per_contact", "on_violation", "max_speed", "overlap_tolerance"});
    sc.stability.min_steps_per_contact =
        cfg::get_double_or(st, "scene.stability", "min_steps_per_contact", 20);
    if (!(sc.stability.min_steps_per_contact >= 1))
      throw ConfigError("scene.stability.min_steps_per_contact: must be >= 1");
    sc.stability.on_violation =
        cfg::get_choice(st, "scene.stability", "on_violation", {"refuse", "warn"}, "refuse") ==
                "warn"
            ? DtViolation::warn
            : DtViolation::refuse;
    sc.stability.max_speed = cfg::get_double_or(st, "scene.stability", "max_speed", 100);
    if (!(sc.stability.max_speed > 0)) throw ConfigError("scene.stability.max_speed: must be > 0");
    sc.stability.overlap_tolerance =
        cfg::get_double_or(st, "scene.stability", "overlap_tolerance", 0.01);
    if (!(sc.stability.overlap_tolerance >= 0))
      throw ConfigError("scene.stability.overlap_tolerance: must be >= 0");
  }

  // materials and species
  std::map<std::string, double> density;
  const YAML::Node mats = root["materials"];
  if (!mats || !mats.IsMap() || mats.size() == 0)
    throw ConfigError("materials: missing (expected e.g. {sand: {density: 2600}})");
  for (const auto& kv : mats) {
    const std::string name = kv.first.as<std::string>();
    const std::string p = "materials." + name;
    cfg::check_keys(kv.second, p, {"density"});
    density[name] = cfg::get_positive(kv.second, p, "density");
  }
  const YAML::Node sps = root["species"];
  if (!sps || !sps.IsSequence() || sps.size() == 0)
    throw ConfigError("species: missing (expected a list of {name, material, radius})");
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
    sc.species.push_back(sp);
  }

  // contact
  const YAML::Node c = root["contact"];
  if (!c) throw ConfigError("contact: missing (expected particle_particle and optional particle_wall)");
  cfg::check_keys(c, "contact", {"particle_particle", "particle_wall"});
  if (!c["particle_particle"]) throw ConfigError("contact.particle_particle: missing");
  sc.particle_particle = parse_law(c["particle_particle"], "contact.particle_particle");
  sc.particle_wall = c["particle_wall"] ? parse_law(c["particle_wall"], "contact.particle_wall")
                                        : sc.particle_particle;

  // walls
  if (const YAML::Node w = root["walls"]) {
    for (std::size_t i = 0; i < w.size(); ++i) {
      const std::string p = "walls[" + std::to_string(i) + "]";
      const std::string type = cfg::get_choice(w[i], p, "type", {"plane", "box"});
      const std::string name = cfg::get_string(w[i], p, "name");
      if (type == "plane") {
        cfg::check_keys(w[i], p, {"name", "type", "point", "normal"});
        Vec3 n = vec3(w[i], p, "normal");
        if (!(norm(n) > 0)) throw ConfigError(p + ".normal: must be non-zero");
        sc.walls.push_back({name, vec3(w[i], p, "point"), (1.0 / norm(n)) * n});
      } else {
        cfg::check_keys(w[i], p, {"name", "type", "min", "max", "open_top"});
        const Vec3 lo = vec3(w[i], p, "min"), hi = vec3(w[i], p, "max");
        if (!(hi.x > lo.x && hi.y > lo.y && hi.z > lo.z))
          throw ConfigError(p + ": max must exceed min in x, y and z");
        // A container: particles stay inside, so each face's normal points inwards.
        sc.walls.push_back({name + "/xmin", lo, {1, 0, 0}});
        sc.walls.push_back({name + "/xmax", hi, {-1, 0, 0}});
        sc.walls.push_back({name + "/ymin", lo, {0, 1, 0}});
        sc.walls.push_back({name + "/ymax", hi, {0, -1, 0}});
        sc.walls.push_back({name + "/zmin", lo, {0, 0, 1}});
        if (!cfg::get_bool_or(w[i], p, "open_top", true))
          sc.walls.push_back({name + "/zmax", hi, {0, 0, -1}});
      }
    }
  }

  // tools
  if (const YAML::Node t = root["tools"]) {
    for (std::size_t i = 0; i < t.size(); ++i) {
      const std::string p = "tools[" + std::to_string(i) + "]";
      cfg::check_keys(t[i], p, {"name", "mesh", "scale", "reference_point", "motion"});
      Tool tool;
      tool.name = cfg::get_string(t[i], p, "name");
      const double scale = cfg::get_positive_or(t[i], p, "scale", 1.0);
      const Vec3 ref = t[i]["reference_point"] ? vec3(t[i], p, "reference_point") : Vec3{};
      const std::string file = resolve(base_dir, cfg::get_string(t[i], p, "mesh"));
      try {
        tool.mesh = load_mesh(file, scale, ref);
      } catch (const std::runtime_error& e) {
        throw ConfigError(p + ".mesh: " + e.what());
      }
      if (const YAML::Node m = t[i]["motion"]) {
        const std::string mp = p + ".motion";
        cfg::check_keys(m, mp, {"interpolation", "keyframes", "csv"});
        tool.motion.interpolation =
            cfg::get_choice(m, mp, "interpolation", {"linear", "cubic"}, "linear") == "cubic"
                ? ToolMotion::Interpolation::cubic
                : ToolMotion::Interpolation::linear;
        if (static_cast<bool>(m["keyframes"]) == static_cast<bool>(m["csv"]))
          throw ConfigError(mp + ": give exactly one of keyframes or csv");
        if (m["keyframes"]) {
          tool.motion.keyframes = parse_keyframes(m["keyframes"], mp + ".keyframes");
        } else {
          try {
            tool.motion.keyframes = load_keyframes_csv(resolve(base_dir, cfg::get_string(m, mp, "csv")));
          } catch (const std::exception& e) {
            throw ConfigError(mp + ".csv: " + e.what());
          }
        }
      } else {
        tool.motion.keyframes = {Keyframe{}};  // fixed: mesh frame = world frame
      }
      sc.tools.push_back(std::move(tool));
    }
  }

  // particles
  const YAML::Node parts = root["particles"];
  if (!parts) throw ConfigError("particles: missing (give fill, list or checkpoint)");
  cfg::check_keys(parts, "particles", {"fill", "list", "checkpoint", "keep_time"});
  if (parts["checkpoint"]) {
    const std::string file = resolve(base_dir, cfg::get_string(parts, "particles", "checkpoint"));
    try {
      rc.state = load_checkpoint(file);
    } catch (const std::exception& e) {
      throw ConfigError(std::string("particles.checkpoint: ") + e.what());
    }
    // A prepared bed starts a new scene at t = 0 (tool keyframes count from there); keep the
    // checkpoint's time only to continue the same run.
    if (!cfg::get_bool_or(parts, "particles", "keep_time", false)) rc.state.step = 0;
  }
  if (const YAML::Node f = parts["fill"]) {
    for (std::size_t i = 0; i < f.size(); ++i) {
      const std::string p = "particles.fill[" + std::to_string(i) + "]";
      cfg::check_keys(f[i], p, {"species", "min", "max", "count", "seed"});
      FillRegion r;
      r.species = species_index(sc, cfg::get_string(f[i], p, "species"), p + ".species");
      r.min = vec3(f[i], p, "min");
      r.max = vec3(f[i], p, "max");
      r.count = cfg::get_int(f[i], p, "count");
      if (r.count < 0) throw ConfigError(p + ".count: must be >= 0");
      r.seed = static_cast<unsigned long long>(cfg::get_int_or(f[i], p, "seed", 1));
      rc.fill.push_back(r);
    }
  }
  if (const YAML::Node l = parts["list"]) {
    for (std::size_t i = 0; i < l.size(); ++i) {
      const std::string p = "particles.list[" + std::to_string(i) + "]";
      cfg::check_keys(l[i], p, {"species", "position", "velocity", "radius"});
      const int spi = species_index(sc, cfg::get_string(l[i], p, "species"), p + ".species");
      const Species& sp = sc.species[spi];
      const double r = l[i]["radius"] ? cfg::get_double(l[i], p, "radius") : sp.radius.max;
      if (!(r > 0) || !std::isfinite(r))
        throw ConfigError(p + ".radius: must be a positive number of metres, got " +
                          std::to_string(r));
      const Vec3 v = l[i]["velocity"] ? vec3(l[i], p, "velocity") : Vec3{};
      const std::int64_t id =
          rc.state.id.empty() ? 0 : *std::max_element(rc.state.id.begin(), rc.state.id.end()) + 1;
      add_particle(rc.state, vec3(l[i], p, "position"), v, r,
                   sp.density * 4.0 / 3.0 * M_PI * r * r * r, spi, id);
    }
  }
  for (const FillRegion& r : rc.fill) fill_region(sc, r, rc.state);

  // settle, run, output
  if (const YAML::Node st = root["settle"]) {
    cfg::check_keys(st, "settle", {"ke_per_particle", "max_time", "checkpoint"});
    rc.settle.enabled = true;
    rc.settle.ke_per_particle = cfg::get_positive_or(st, "settle", "ke_per_particle", 1e-9);
    rc.settle.max_time = cfg::get_positive_or(st, "settle", "max_time", 5.0);
    // An output: relative to the working directory, like output.file.
    rc.settle.checkpoint = cfg::get_string_or(st, "settle", "checkpoint", "");
  }
  if (const YAML::Node r = root["run"]) {
    cfg::check_keys(r, "run", {"duration"});
    rc.duration = cfg::get_double(r, "run", "duration");
    if (!(rc.duration >= 0)) throw ConfigError("run.duration: must be >= 0 s");
  }
  if (const YAML::Node o = root["output"]) {
    cfg::check_keys(o, "output", {"file", "particles_every", "wrenches_every", "progress_every",
                                  "checkpoint"});
    rc.output.file = cfg::get_string_or(o, "output", "file", rc.output.file);
    rc.output.particles_every = cfg::get_double_or(o, "output", "particles_every", 0);
    rc.output.wrenches_every = cfg::get_double_or(o, "output", "wrenches_every", 0);
    rc.output.progress_every = cfg::get_double_or(o, "output", "progress_every", 2);
    rc.output.checkpoint = cfg::get_string_or(o, "output", "checkpoint", "");
    if (rc.output.particles_every < 0 || rc.output.wrenches_every < 0)
      throw ConfigError("output.particles_every / wrenches_every: must be >= 0 s (0 = every step "
                        "for wrenches, start and end for particles)");
  }
  // Checkpointed beds may come from another scene: the tool count is this scene's.
  rc.state.tool_pose.resize(sc.tools.size());
  for (std::size_t m = 0; m < sc.tools.size(); ++m)
    rc.state.tool_pose[m] = sc.tools[m].motion.evaluate(rc.state.step * sc.dt);
  if (rc.state.tool_pose_at_rebuild.size() != sc.tools.size()) rc.state.lists_valid = false;
  return rc;
}

}  // namespace dem
