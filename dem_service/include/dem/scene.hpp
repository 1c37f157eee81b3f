// Scene: everything fixed after loading (MuJoCo's mjModel). The step never writes to it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dem/mesh.hpp"
#include "dem/tool_motion.hpp"
#include "dem/vec3.hpp"

namespace dem {

// Linear spring-dashpot with tangential history and Coulomb cap; see docs/physics.md.
struct ContactLaw {
  // true: normal_stiffness is in Pa and k_N [N/m] = normal_stiffness * effective length.
  bool stiffness_per_length = true;
  double normal_stiffness = 0;
  // true: damping ratio zeta derived from `restitution`; false: `normal_damping` in N s/m.
  bool damping_from_restitution = true;
  double restitution = 0.5;
  double zeta = 0;  // derived from restitution
  double normal_damping = 0;
  bool clip_attractive = true;              // F_n >= 0 when true
  double tangential_stiffness_ratio = 1.0;  // k_T / k_N
  double tangential_damping_ratio = 0.5;    // eta_T / eta_N
  double friction = 0.5;                    // Coulomb mu
};

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
};

// One-sided infinite plane: particles live on the side the normal points to.
struct Wall {
  std::string name;
  Vec3 point;
  Vec3 normal;  // unit
};

// A rigid triangle-mesh tool; the mesh is stored relative to the reference point.
struct Tool {
  std::string name;
  Mesh mesh;
  ToolMotion motion;
};

enum class GuardMode { rebuild, strict };
enum class DtViolation { refuse, warn };

struct StabilityOptions {
  double min_steps_per_contact = 20;
  DtViolation on_violation = DtViolation::refuse;
  double max_speed = 100;           // m/s; a faster particle stops the run as a blow-up
  double overlap_tolerance = 0.01;  // initial overlap allowed, fraction of the smaller radius
};

struct Scene {
  double dt = 1e-5;
  Vec3 gravity{0, 0, -9.81};
  int broad_phase_interval = 5;
  double skin = 0.5;  // skin factor tau: candidate margin is skin * r_max
  GuardMode guard = GuardMode::rebuild;
  int threads = 1;
  // Fewer particles per thread than this and the step uses fewer threads: for small scenes
  // the barriers cost more than the work (and a lot more on a loaded machine).
  int min_particles_per_thread = 2000;
  StabilityOptions stability;
  std::vector<Species> species;
  ContactLaw particle_particle;
  ContactLaw particle_wall;  // walls and tools
  std::vector<Wall> walls;
  std::vector<Tool> tools;

  // Largest radius any species can produce; the skin and the grid are sized from it.
  double r_max() const;
  double skin_distance() const { return skin * r_max(); }
};

// Fills derived fields (zeta from restitution) and checks ranges; throws std::invalid_argument
// naming the field and the fix.
void finalize(ContactLaw& law, const std::string& path);

}  // namespace dem
