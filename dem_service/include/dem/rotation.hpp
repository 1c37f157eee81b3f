// The rotating particle model (6 DOF spheres with rolling resistance), kept apart from the
// translating engine: its own pair loop (scalar), its contact function for walls and tools, and
// its integration step, which the engine selects at its hook points when
// Scene::rotation.model is rotating. Conventions in docs/physics.md "Rotation", numbers in
// docs/soil_models.md.
//
// Per contact, with n the unit normal from the other body towards particle i and the contact
// point c on the line of centres (x_i - a_i n = x_j + a_j n, a_i = r_i - delta/2, a_j =
// r_j - delta/2 for two spheres, so both see the same point; for a wall or tool c is the
// closest surface point):
//   * relative velocity at c: u_c = u_i + w_i x (c - x_i) - (u_j + w_j x (c - x_j))
//     = u_i - u_j - (a_i w_i + a_j w_j) x n (two spheres), which the translating contact law
//     (contact_force: normal dashpot, tangential spring and dashpot, Coulomb cap) receives;
//   * torque on i about its centre: (c - x_i) x F (j: (c - x_j) x (-F)), so the pair conserves
//     angular momentum exactly; a tool receives (c - p) x (-F) about its reference point p;
//   * rolling resistance (RollingResistance::Kind::epsd): rolling velocity w_r = w_i - w_j
//     (w_i - w_body for walls and tools) without its component along n (no twisting torque),
//     rolling radius R_r = r_i r_j / (r_i + r_j) (r_i at a wall), rolling spring torque M_k on i
//     kept in the tangent plane like the tangential spring, M_k -= k_r w_r dt, capped at
//     mu_r R_r F_n; M = M_k - C_r w_r below the cap, M = M_k at it. i gets M, j (or the tool) -M.
#pragma once

#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "dem/contact_law.hpp"
#include "dem/engine_types.hpp"
#include "dem/rotation_options.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace YAML {
class Node;
}

namespace dem {

// Solid sphere: I = 2/5 m r^2.
inline double moment_of_inertia(double m, double r) { return 0.4 * m * r * r; }

// particles.model and particles.rolling_resistance (the map `particles`, may be null): fills
// sc.rotation; throws cosim::config::ConfigError naming the key and the fix. Needs sc.sleep
// parsed (the rotating model refuses sleeping).
void parse_rotation(const YAML::Node& particles, Scene& sc);

// The checks of parse_rotation for a Scene built in code (the engine calls it): throws
// std::invalid_argument naming the key and the fix.
void validate_rotation(const Scene& sc);

// The shortest period the rotation adds (tangential contact oscillation with the spins free,
// rolling spring), over the species' smallest and largest radii; INFINITY for the translating
// model. `which` names the contact.
double rotating_contact_period(const Scene& sc, std::string* which = nullptr);

// The rolling resistance constants of one contact. R_r: rolling radius; I_r: the reduced
// rolling inertia 1 / (1/(I_i + m_i r_i^2) + 1/(I_j + m_j r_j^2)) (the wall's term is 0);
// k_N: the contact's normal stiffness in N/m (Ai et al. 2011, eq. for model C).
struct RollingCoefficients {
  double kr = 0;   // rolling stiffness, N m / rad
  double cr = 0;   // rolling damping, N m s / rad
  double lever = 0;  // mu_r R_r: the cap is lever * F_n
};
inline RollingCoefficients rolling_coefficients(const RollingResistance& rr, double kn,
                                                double rolling_radius, double inertia) {
  RollingCoefficients c;
  if (rr.kind == RollingResistance::Kind::none) return c;
  c.lever = rr.friction * rolling_radius;
  c.kr = rr.stiffness_factor * kn * c.lever * c.lever;
  c.cr = rr.damping * 2.0 * std::sqrt(inertia * c.kr);
  return c;
}

// Keeps a history vector in the plane normal to n without changing its length (as the
// tangential spring in contact_force).
inline Vec3 keep_in_plane(Vec3 h, Vec3 n) {
  const double h2 = norm2(h);
  if (!(h2 > 0)) return h;
  const double hn = dot(h, n);
  const Vec3 hp = h - hn * n;
  const double x = hn * hn / h2;
  const double f = x < 1e-6 ? 1 + 0.5 * x : (x < 1 ? 1 / std::sqrt(1 - x) : 0.0);
  return f * hp;
}

// The rolling torque on particle i of a contact that carries the normal force fn (>= 0), its
// rolling spring `roll` advanced by the rolling velocity (w_rel without its part along n).
inline Vec3 rolling_torque(const RollingCoefficients& c, Vec3 n, Vec3 w_rel, double fn,
                           Vec3& roll, double dt) {
  if (!(c.kr > 0)) return Vec3{};
  const Vec3 wr = w_rel - dot(w_rel, n) * n;
  roll = keep_in_plane(roll, n);
  roll -= (c.kr * dt) * wr;
  const double cap = c.lever * (fn > 0 ? fn : 0.0);
  const double r2 = norm2(roll);
  if (r2 >= cap * cap) {  // full mobilisation: the spring carries the cap, no dashpot
    roll = r2 > 0 ? (cap / std::sqrt(r2)) * roll : Vec3{};
    return roll;
  }
  return roll - c.cr * wr;
}

// A wall or tool contact of particle i in the rotating model: force on i (contact_force with
// the velocity of the contact point), its torque about x_i (tangential force and rolling) and,
// separately, the rolling torque (the body receives -rolling on top of the moment of -force).
// Returns false if the contact is not active in this step.
struct BoundarySpin {
  const ContactLaw* law;
  ContactCoefficients coef;
  RollingCoefficients roll;
};
inline bool rotating_boundary_contact(const BoundarySpin& b, double overlap, Vec3 n, Vec3 point,
                                      Vec3 xi, Vec3 ui, Vec3 wi, Vec3 body_velocity,
                                      Vec3 body_w, Vec3& spring, Vec3& roll, double dt,
                                      Vec3& force, Vec3& torque, Vec3& rolling) {
  const Vec3 arm = point - xi;
  const Vec3 uc = ui + cross(wi, arm) - body_velocity;
  if (!contact_force(*b.law, b.coef, overlap, n, uc, spring, dt, force)) return false;
  rolling = rolling_torque(b.roll, n, wi - body_w, dot(force, n), roll, dt);
  torque = cross(arm, force) + rolling;
  return true;
}

// Engine part of the rotating model: the torques of a step, the pair loop and the spin
// integration. The pair loop is scalar and on one thread (docs/soil_models.md: its cost).
namespace detail {
struct PairSleep;  // dem/pair_kernel.hpp
}

class Rotation {
 public:
  // w, wu sized to the particles (zeros for new ones), the rolling springs to their lists.
  static void size_arrays(State& s);
  // Gravity plus every pair force on force[i] (resized to the particles), every pair torque on
  // torque(); springs of pairs out of contact are cleared. With `sleep` (scene.sleep, the rules
  // of detail::pair_rows_sleep, one thread: every wake is direct) two sleepers' pair is skipped
  // (both springs keep their bits), a pair force and torque act on the awake particle only, and
  // a sleeper is woken as in the translating model.
  void pair_forces(const Scene& sc, State& s, std::vector<Vec3>& force, ContactStats& stats,
                   const detail::PairSleep* sleep = nullptr);
  Vec3* torque() { return torque_.data(); }
  // Semi-implicit Euler of the spins, as for the velocities: w += dt T / I, then
  // wu = w + dt/2 T / I (the spin at the next force time). Throws SimulationError for a NaN.
  // Runs before the translating integration of the step (s.step not yet counted) so that the
  // fall-asleep test sees the new spin; with scene.sleep only the particles awake at the start
  // of the step are advanced (a sleeper's w = wu = 0 stays so; one woken in this step turns
  // from the next step on, as its v does).
  void integrate(const Scene& sc, State& s);
  std::size_t bytes() const { return torque_.capacity() * sizeof(Vec3); }

 private:
  std::vector<Vec3> torque_;
};

// Rotational kinetic energy sum 1/2 I |w|^2 (0 for the translating model).
double rotational_energy(const State& s);

}  // namespace dem
