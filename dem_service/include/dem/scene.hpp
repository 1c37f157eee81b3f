// Scene: everything fixed after loading (MuJoCo's mjModel). The step never writes to it.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "dem/contact_law.hpp"
#include "dem/mesh.hpp"
#include "dem/rotation_options.hpp"
#include "dem/thread_wait.hpp"
#include "dem/tool_motion.hpp"
#include "dem/vec3.hpp"

namespace dem {

// Particle size distribution of one species.
struct RadiusDistribution {
  enum class Kind { constant, uniform, discrete } kind = Kind::constant;
  double min = 0, max = 0;      // constant: min == max
  std::vector<double> values;   // discrete
  std::vector<double> weights;  // discrete, normalised to sum 1
};

struct Species {
  std::string name;
  double density = 0;  // kg/m^3
  RadiusDistribution radius;

  // Mass of one of its spheres of radius r, kg.
  double mass(double r) const { return density * 4.0 / 3.0 * M_PI * r * r * r; }
};

// One-sided infinite plane: particles live on the side the normal points to.
struct Wall {
  std::string name;
  Vec3 point;
  Vec3 normal;  // unit
  // For pictures only (the physics sees an infinite plane): a face of a `box` wall is drawn as
  // the face of that box; a `plane` wall as a rectangle covering the run (docs/visualise.md).
  bool from_box = false;
  Vec3 box_min{}, box_max{};
  // Its contact law: an index into Scene::boundary_laws, or -1 for Scene::particle_wall.
  int law = -1;
};

// A rigid triangle-mesh tool; the mesh is stored relative to the reference point.
struct Tool {
  std::string name;
  Mesh mesh;
  ToolMotion motion;
  int law = -1;  // index into Scene::boundary_laws, or -1 for Scene::particle_wall
};

enum class GuardMode { rebuild, strict };
enum class DtViolation { refuse, warn };

struct StabilityOptions {
  double min_steps_per_contact = 20;
  DtViolation on_violation = DtViolation::refuse;
  double max_speed = 100;           // m/s; a faster particle stops the run as a blow-up
  double overlap_tolerance = 0.01;  // initial overlap allowed, fraction of the smaller radius
};

// Sleeping particles (docs/dem.md "Sleeping and the region of interest"): a particle slower than
// `speed` for `steps` consecutive steps while more than `tool_distance` from every tool's
// bounding sphere falls asleep (v = u = 0, x fixed, not integrated, no gravity, no wall or mesh
// forces, no forces between two sleepers). Its contacts with awake particles act on the awake
// one. It wakes when an awake contact partner moves faster than `wake_speed` (by default
// `speed`) relative to it, when a contact with an awake particle ends, or when a tool's
// bounding sphere comes within `tool_distance`.
// What counts as "near a tool" for sleeping: within tool_distance of the tool's bounding sphere
// (centred on its reference point, radius = the farthest vertex), or of the mesh's own
// axis-aligned box in the tool frame (tighter: a bucket's box is about 1.5 x 3.0 x 1.6 m where its
// bounding sphere about the A-pin has a 2.3 m radius).
enum class SleepNeighbourhood { sphere, box };

struct SleepOptions {
  bool enabled = false;
  double speed = 0.01;        // m/s
  // m/s: an awake partner faster than this (relative to the sleeper) wakes it; 0 (the default)
  // means `speed`. Lower than `speed`, a slow push through the bed wakes what it reaches
  // (docs/dem.md, "Choosing the thresholds").
  double wake_speed = 0;
  double wake() const { return wake_speed > 0 ? wake_speed : speed; }
  int steps = 500;            // consecutive steps at rest before sleeping
  double tool_distance = 0.5; // m, gap to the tool's neighbourhood shape (below)
  SleepNeighbourhood neighbourhood = SleepNeighbourhood::sphere;
  // Close pairs (EngineOptions::close_margin, performance.close_margin) while sleeping: the same bits either way, but in the
  // paper's scene they cost more than they save (docs/performance.md), so off unless asked.
  bool close_pairs = false;
};

// Region of interest: particles whose centre leaves the box are removed at the next broad
// phase and counted (State::removed_count, removed_mass). Off when `enabled` is false.
struct RegionOptions {
  bool enabled = false;
  Vec3 min, max;
};

struct Scene {
  double dt = 1e-5;
  Vec3 gravity{0, 0, -9.81};
  int broad_phase_interval = 5;
  double skin = 0.5;  // skin factor tau: candidate margin is skin * r_max
  GuardMode guard = GuardMode::rebuild;
  // How the engine computes (close pairs, the pair schedule, threads per particle count) is
  // not the scene's: EngineOptions (dem/engine_options.hpp), the config's performance: section.
  int threads = 1;
  // How idle threads wait (dem/thread_wait.hpp). The libgomp part is fixed when the program
  // starts: dem_run, dem_service and dem_side_by_side apply it with apply_thread_wait; with
  // yield the engine runs each step on its own threads (dem/thread_team.hpp).
  ThreadWait thread_wait = ThreadWait::yield;
  StabilityOptions stability;
  SleepOptions sleep;
  RegionOptions region;
  // The particle model (particles.model): translating by default; rotating adds State::w.
  RotationOptions rotation;
  std::vector<Species> species;
  ContactLaw particle_particle;
  ContactLaw particle_wall;  // walls and tools without a law of their own
  // Laws of walls and tools that name their own (walls[].contact, tools[].contact in the
  // config); empty when none does, and then every boundary contact uses particle_wall.
  std::vector<ContactLaw> boundary_laws;
  const ContactLaw& wall_law(std::size_t w) const {
    return walls[w].law < 0 ? particle_wall : boundary_laws[static_cast<std::size_t>(walls[w].law)];
  }
  const ContactLaw& tool_law(std::size_t m) const {
    return tools[m].law < 0 ? particle_wall : boundary_laws[static_cast<std::size_t>(tools[m].law)];
  }
  std::vector<Wall> walls;
  std::vector<Tool> tools;

  // Largest radius any species can produce; the skin and the grid are sized from it.
  double r_max() const;
  double skin_distance() const { return skin * r_max(); }
};

}  // namespace dem
