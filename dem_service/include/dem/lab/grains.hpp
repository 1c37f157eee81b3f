// Virtual lab tests (docs/soil_lab.md): what every lab scene shares. The grains of a test (their
// density, radius distribution and particle contact law, in the keys of dem_run's sections), the
// scene the lab builds around them (no gravity or gravity, frictionless elastic rig walls), a
// seeded random insertion without a lattice, and a box rig of six analytic walls that the lab
// moves between steps (positions through Scene::walls, forces through Engine::wall_forces()).
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "dem/engine.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem::lab {

// The grains under test. `law` is the particle-particle contact law (contact.particle_particle
// of dem_run); the rig's walls get the same stiffness, no friction and no damping (an elastic,
// smooth platen: a moving wall is seen by the engine at rest, so a dashpot against it would add
// a force proportional to the wall's speed to the measured stress).
struct Grains {
  double density = 0;              // kg/m^3
  double radius_min = 0, radius_max = 0;  // m; uniform in [min, max] (equal: one size)
  ContactLaw law;
  // The particle model (grains.model, grains.rolling_resistance: the keys of dem_run's
  // particles.model and particles.rolling_resistance): translating (default) or rotating.
  RotationOptions rotation;

  double mean_radius() const { return 0.5 * (radius_min + radius_max); }
  // Mean volume of one grain, m^3: 4/3 pi E[r^3] for r uniform in [min, max].
  double mean_volume() const;
};

// Reads `grains: {density, radius, contact, model, rolling_resistance}` at dotted `path`;
// radius is a number (m) or {min, max} (uniform); model translating (default) or rotating,
// rolling_resistance as particles.rolling_resistance of dem_run (docs/dem.md). Unknown keys
// and bad values are refused with cosim::config::ConfigError (or std::invalid_argument from the
// contact law) naming the key under `path`.
Grains parse_grains(const YAML::Node& node, const std::string& path);
// The particle model alone: `model` and `rolling_resistance` of the map at `path`, read and
// checked by the engine's reader (parse_rotation) with its messages naming path.model and
// path.rolling_resistance instead of particles.model and particles.rolling_resistance.
RotationOptions parse_model(const YAML::Node& node, const std::string& path);

// The scene of a lab test: one species "grain" of these grains, their law between particles
// and their particle model (the rotating model's rolling resistance acts at the walls too: it is
// one setting of the scene), the frictionless elastic wall law, the given gravity; dt is the largest safe step for the
// contact law (scene.stability.min_steps_per_contact 20) times dt_factor (<= 1).
Scene make_scene(const Grains& g, Vec3 gravity, int threads, double dt_factor = 1.0);

// Seeded random sequential insertion of `count` grains with centres uniform in [lo, hi] (the
// box the centres may take, the caller keeps a radius from walls) and no overlap, each radius
// drawn uniformly. Throws std::invalid_argument naming `what` when the box cannot take them
// (more than 2000 tries per grain). `inside` (optional) rejects a centre that lies outside a
// shape (e.g. a cylinder). Ids continue after the largest in s.
void insert_random(const Scene& scene, State& s, Vec3 lo, Vec3 hi, long count,
                   std::uint64_t seed, const std::string& what,
                   bool (*inside)(Vec3 centre, double r, const void* ctx) = nullptr,
                   const void* ctx = nullptr);

// Six walls of an axis-aligned box, faces in the order -x, +x, -y, +y, -z, +z, each with its
// normal into the box, appended to scene.walls. The lab moves them with move(), which writes
// Scene::walls (the engine keeps a reference to the scene and reads the walls every step) and
// forces a broad phase when a wall moved a tenth of the skin since the last one (the broad
// phase lists each particle's walls within reach; the engine's guard does not know that walls
// move).
class BoxRig {
 public:
  BoxRig(Scene& scene, Vec3 lo, Vec3 hi);
  Vec3 lo() const { return lo_; }
  Vec3 hi() const { return hi_; }
  Vec3 size() const { return hi_ - lo_; }
  double volume() const;
  double area(int face) const;  // of the face, from the current box
  // Moves face f inward (along its normal) by dx (negative: outward).
  void move(int face, double dx);
  // Normal stress on face f from the last step (Pa, compression positive).
  double stress(const Engine& engine, int face) const;
  // Stiffness of the contacts on face f now: the sum of k_N of the grains touching it (N/m).
  double contact_stiffness(const State& s, int face) const;
  // Before a step: a broad phase if a wall moved too far since the last one.
  void before_step(Engine& engine, State& s);
  int wall(int face) const { return first_ + face; }

 private:
  Scene& scene_;
  int first_;
  Vec3 lo_, hi_;
  std::array<double, 6> moved_{};
  std::int64_t rebuilds_seen_ = -1;
};

// The servo of one face: wall speed = gain * area * (target - measured) / (K dt), K the contact
// stiffness on the face (at least one grain's k_N), capped at max_speed. gain is the fraction
// of the stress error that one step would remove if only the touching grains were compressed
// (the sample behind them is softer, so the real fraction is smaller): below 1 the loop is
// stable; 0.05-0.3 is the useful range.
double servo_speed(double gain, double area, double error, double stiffness, double dt,
                   double max_speed);

// Packing fraction in the box [lo, hi]: the grains' volume inside it (a grain cut by a face
// counts its part inside; the caps of grains at an edge are counted approximately) / its volume.
double packing_fraction(const State& s, Vec3 lo, Vec3 hi);
// Mean contacts per grain (particle-particle contacts x 2 / grains, rattlers included).
double coordination(const Engine& engine, const State& s);

}  // namespace dem::lab
