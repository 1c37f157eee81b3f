// docs/dem.md lists every optional key of the DEM config with its default. This test reads
// that table and checks each entry against the code: a config that sets the key to the
// documented value must load to exactly the same scene, state and options as one that leaves
// the key out (the parser falls back to the struct initialisers, the one place a default is
// declared).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "cosim/yaml_config.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"

namespace {

namespace fs = std::filesystem;

const std::string kSource = DEM_SOURCE_DIR;

// Every section present with only its required keys, so that each optional key can be left
// out or set. particle_wall damps by coefficient, so both damping branches are read.
const char* kMinimal = R"(
scene: {dt: 1.0e-5}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: {distribution: uniform, min: 0.004, max: 0.005}}]
contact:
  particle_particle: {normal_stiffness: 4.0e7, restitution: 0.3}
  particle_wall: {normal_stiffness: 4.0e7, normal_damping: 2.0}
walls: [{name: bin, type: box, min: [0, 0, 0], max: [0.2, 0.2, 0.2]}]
tools:
  - name: blade
    mesh: MESH
    motion: {keyframes: [{time: 0, position: [0, 0, 0.3]}, {time: 1, position: [0.1, 0, 0.3]}]}
particles:
  checkpoint: CHECKPOINT
  list: [{species: grain, position: [0.1, 0.1, 0.1]}]
  fill: [{species: grain, min: [0, 0, 0], max: [0.2, 0.2, 0.05], count: 20}]
settle: {}
)";

// One folder per test process: ctest runs the tests of this file side by side.
std::string dir() {
  const fs::path d =
      fs::temp_directory_path() / ("dem_config_defaults_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d.string();
}

YAML::Node minimal_config() {
  // A small bed whose time is not 0, so that particles.keep_time matters.
  const std::string checkpoint = dir() + "/bed.h5";
  dem::State bed;
  dem::add_particle(bed, {0.05, 0.05, 0.15}, {0, 0, 0}, 0.005, 1e-3, 0, 0);
  bed.step = 7;
  dem::save_checkpoint(bed, checkpoint);
  YAML::Node root = YAML::Load(kMinimal);
  root["tools"][0]["mesh"] = kSource + "/configs/dem/meshes/blade.obj";
  root["particles"]["checkpoint"] = checkpoint;
  return root;
}

// Every field load_config fills, printed exactly (17 digits).
std::string describe(const dem::RunConfig& rc) {
  std::ostringstream o;
  o.precision(17);
  auto v = [&](const dem::Vec3& a) { o << a.x << ' ' << a.y << ' ' << a.z << ' '; };
  auto q = [&](const dem::Quat& a) { o << a.w << ' ' << a.x << ' ' << a.y << ' ' << a.z << ' '; };
  auto law = [&](const dem::ContactLaw& l) {
    o << "law " << l.stiffness_per_length << ' ' << l.normal_stiffness << ' '
      << l.damping_from_restitution << ' ' << l.restitution << ' ' << l.zeta << ' '
      << l.normal_damping << ' ' << l.clip_attractive << ' ' << l.tangential_stiffness_ratio
      << ' ' << l.tangential_damping_ratio << ' ' << l.friction << '\n';
  };
  const dem::Scene& s = rc.scene;
  o << "scene " << s.dt << ' ';
  v(s.gravity);
  o << s.broad_phase_interval << ' ' << s.skin << ' ' << static_cast<int>(s.guard) << ' '
    << s.threads << ' ' << static_cast<int>(s.thread_wait) << '\n';
  const dem::EngineOptions& e = rc.performance;
  o << "performance " << e.close_margin << ' ' << static_cast<int>(e.pair_schedule) << ' '
    << e.min_particles_per_thread << '\n';
  o << "stability " << s.stability.min_steps_per_contact << ' '
    << static_cast<int>(s.stability.on_violation) << ' ' << s.stability.max_speed << ' '
    << s.stability.overlap_tolerance << '\n';
  o << "sleep " << s.sleep.enabled << ' ' << s.sleep.speed << ' ' << s.sleep.wake() << ' '
    << s.sleep.steps << ' '
    << s.sleep.tool_distance << ' ' << s.sleep.close_pairs << '\n';
  o << "region " << s.region.enabled << ' ';
  v(s.region.min);
  v(s.region.max);
  o << '\n';
  for (const dem::Species& sp : s.species) {
    o << "species " << sp.name << ' ' << sp.density << ' ' << static_cast<int>(sp.radius.kind)
      << ' ' << sp.radius.min << ' ' << sp.radius.max << ' ';
    for (double x : sp.radius.values) o << x << ' ';
    for (double x : sp.radius.weights) o << x << ' ';
    o << '\n';
  }
  law(s.particle_particle);
  law(s.particle_wall);
  for (const dem::Wall& w : s.walls) {
    o << "wall " << w.name << ' ';
    v(w.point);
    v(w.normal);
    o << '\n';
  }
  for (const dem::Tool& t : s.tools) {
    o << "tool " << t.name << ' ' << t.mesh.triangles.size() << ' '
      << t.mesh.bounding_radius << ' ';
    for (const dem::Vec3& p : t.mesh.vertices) v(p);
    o << static_cast<int>(t.motion.interpolation) << ' ';
    for (const dem::Keyframe& k : t.motion.keyframes) {
      o << k.time << ' ';
      for (double x : k.position) o << x << ' ';     // cosim::Vec3: x y z
      for (double x : k.orientation) o << x << ' ';  // cosim::Quat: w x y z
    }
    o << '\n';
  }
  const dem::State& st = rc.state;
  o << "state " << st.step << ' ' << st.size() << '\n';
  for (std::size_t i = 0; i < st.size(); ++i) {
    v(st.x[i]);
    v(st.v[i]);
    v(st.u[i]);
    o << st.radius[i] << ' ' << st.mass[i] << ' ' << st.species[i] << ' ' << st.id[i] << '\n';
  }
  for (const dem::ToolPose& p : st.tool_pose) {
    v(p.position);
    q(p.orientation);
    v(p.velocity);
    v(p.angular_velocity);
  }
  for (const dem::FillRegion& f : rc.fill) {
    o << "fill " << f.species << ' ' << f.count << ' ' << f.seed << ' ';
    v(f.min);
    v(f.max);
  }
  o << "\nsettle " << rc.settle.enabled << ' ' << rc.settle.ke_per_particle << ' '
    << rc.settle.max_time << " '" << rc.settle.checkpoint << "'\n";
  o << "output '" << rc.output.file << "' " << rc.output.particles_every << ' '
    << rc.output.wrenches_every << ' ' << rc.output.progress_every << " '"
    << rc.output.checkpoint << "'\nrun " << rc.duration << '\n';
  return o.str();
}

struct Documented {
  std::string key, value;
};

// The rows "| `key` | `value` | ..." of the table under "## Defaults" in docs/dem.md.
std::vector<Documented> documented_defaults() {
  std::ifstream in(kSource + "/docs/dem.md");
  EXPECT_TRUE(in) << "cannot read docs/dem.md";
  std::vector<Documented> out;
  const std::regex row(R"(^\| `([^`]+)` \| `([^`]*)` \|.*)");
  bool in_section = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("## ", 0) == 0) in_section = line == "## Defaults";
    std::smatch m;
    if (in_section && std::regex_match(line, m, row)) out.push_back({m[1], m[2]});
  }
  return out;
}

// "tools[].scale" -> "tools.0.scale"; "contact.<law>.friction" -> one path per law.
std::vector<std::string> override_paths(const std::string& key) {
  std::string k = std::regex_replace(key, std::regex(R"(\[\])"), ".0");
  const std::string law = "<law>";
  const auto at = k.find(law);
  if (at == std::string::npos) return {k};
  std::vector<std::string> out;
  for (const char* name : {"particle_particle", "particle_wall"})
    out.push_back(std::string(k).replace(at, law.size(), name));
  return out;
}

TEST(dem_ConfigDefaults, DocsMatchTheCode) {
  const std::string base = describe(dem::load_config(minimal_config(), dir()));
  const auto rows = documented_defaults();
  EXPECT_GE(rows.size(), 30u) << "the table under '## Defaults' in docs/dem.md went missing";
  for (const Documented& d : rows) {
    for (const std::string& path : override_paths(d.key)) {
      YAML::Node root = minimal_config();
      std::string with;
      try {
        cosim::config::apply_override(root, path + "=" + (d.value.empty() ? "\"\"" : d.value));
        with = describe(dem::load_config(root, dir()));
      } catch (const std::exception& e) {
        ADD_FAILURE() << "docs/dem.md: `" << d.key << "` = `" << d.value << "`: " << e.what();
        continue;
      }
      EXPECT_EQ(with, base) << "docs/dem.md documents `" << d.key << "` = `" << d.value
                            << "`, but the code's default differs (" << path << ")";
    }
  }
}

// The check above can fail: a wrong documented value changes the loaded config.
TEST(dem_ConfigDefaults, AWrongDefaultIsNoticed) {
  const std::string base = describe(dem::load_config(minimal_config(), dir()));
  for (const char* set : {"scene.skin=0.4", "contact.particle_wall.friction=0.4",
                          "tools.0.scale=2", "particles.keep_time=true", "settle.max_time=4",
                          "particles.fill.0.seed=2", "walls.0.open_top=false",
                          "scene.sleep.speed=0.02", "scene.sleep.wake_speed=0.005", "scene.sleep.steps=400",
                          "scene.sleep.tool_distance=0.4", "scene.sleep.close_pairs=true"}) {
    YAML::Node root = minimal_config();
    cosim::config::apply_override(root, set);
    EXPECT_NE(describe(dem::load_config(root, dir())), base) << set;
  }
}

}  // namespace
