// The contact law, in one place: its parameters (with their defaults), the derived constants,
// validation, YAML parsing, and the inline force functions of the hot loop: linear
// spring-dashpot normal force, tangential spring with history plus dashpot, Coulomb cap.
// Conventions in docs/physics.md, config keys in docs/dem.md.
#pragma once

#include <cmath>
#include <string>

#include "dem/vec3.hpp"

namespace YAML {
class Node;
}

namespace dem {

// Linear spring-dashpot with tangential history and Coulomb cap. The initialisers are the
// config defaults (parse_contact_law reads them as the fallback of every optional key).
struct ContactLaw {
  // true: normal_stiffness is in Pa and k_N [N/m] = normal_stiffness * effective length.
  bool stiffness_per_length = true;
  double normal_stiffness = 0;  // required
  // true: damping ratio zeta derived from `restitution`; false: `normal_damping` in N s/m.
  bool damping_from_restitution = true;
  double restitution = 0.5;
  double zeta = 0;  // derived from restitution by finalize()
  double normal_damping = 0;
  bool clip_attractive = true;              // F_n >= 0 when true
  double tangential_stiffness_ratio = 1.0;  // k_T / k_N
  double tangential_damping_ratio = 0.5;    // eta_T / eta_N
  double friction = 0.5;                    // Coulomb mu
};

// The only validation of a contact law, for config and programmatic laws alike: checks the
// ranges and fills the derived fields (zeta from restitution). Throws std::invalid_argument
// "<path>.<key>: ..." naming the value and the fix.
void finalize(ContactLaw& law, const std::string& path);

// Reads a contact law from its YAML map at dotted `path` (e.g. "contact.particle_particle"):
// unknown keys, a wrong type, both or neither of restitution / normal_damping and the ranges
// of finalize() are refused with cosim::config::ConfigError. The result is finalized.
ContactLaw parse_contact_law(const YAML::Node& node, const std::string& path);

// Damping ratio for restitution e: zeta = -ln e / sqrt(pi^2 + ln^2 e).
double damping_ratio_from_restitution(double e);

// Per-contact coefficients; effective length and mass depend on the pair.
struct ContactCoefficients {
  double k = 0;     // normal stiffness, N/m
  double eta = 0;   // normal damping, N s/m
  double kt = 0;    // tangential stiffness, N/m
  double etat = 0;  // tangential damping, N s/m
  double neg_inv_kt = 0;  // -1 / kt (kt > 0), for the spring reset when the cap binds
};

// length: r_i r_j / (r_i + r_j) for two spheres, r_i against a wall or tool.
// m_eff: m_i m_j / (m_i + m_j) for two spheres, m_i against a wall or tool.
inline ContactCoefficients coefficients(const ContactLaw& law, double length, double m_eff) {
  ContactCoefficients c;
  c.k = law.stiffness_per_length ? law.normal_stiffness * length : law.normal_stiffness;
  c.eta = law.damping_from_restitution ? 2.0 * law.zeta * std::sqrt(m_eff * c.k)
                                       : law.normal_damping;
  c.kt = law.tangential_stiffness_ratio * c.k;
  c.etat = law.tangential_damping_ratio * c.eta;
  c.neg_inv_kt = c.kt > 0 ? -1.0 / c.kt : 0.0;
  return c;
}

// Force on the particle, or false if the contact is not active in this step.
// n: unit normal from the other body towards the particle; overlap: r_i + r_j - distance
// (may be slightly negative, see below); urel: particle velocity minus the other body's
// velocity at the contact, both taken at the force time (State::u). `spring` is the
// tangential displacement stored with the contact; it is rotated into the current tangent
// plane, advanced by vt dt and, when the Coulomb cap binds, reset so k_T |spring| = mu F_n.
//
// Contacts start and end between steps. The force of a step acts over the window
// [t - dt/2, t + dt/2]; when the overlap, moving at the current normal speed, changes sign
// inside that window the force is averaged over the part of the window in contact. This
// removes the O(dt) error of switching the dashpot on and off at step boundaries (see
// docs/physics.md); resting contacts (normal speed ~ 0) are unaffected.
inline bool contact_force(const ContactLaw& law, const ContactCoefficients& c, double overlap,
                          Vec3 n, Vec3 urel, Vec3& spring, double dt, Vec3& force) {
  const double vn = dot(urel, n);
  const double half = 0.5 * dt * std::abs(vn);
  if (overlap <= -half) return false;
  double fn;
  double active = 1;  // fraction of the window in contact
  if (overlap >= half) {
    fn = c.k * overlap;
  } else {
    const double w = overlap + half;
    active = w / (2 * half);
    fn = c.k * w * w / (4 * half);
  }
  fn -= active * c.eta * vn;
  if (law.clip_attractive && fn < 0) fn = 0;
  const Vec3 vt = urel - vn * n;

  // Keep the spring in the tangent plane without changing its length as the normal turns.
  const double s2 = norm2(spring);
  if (s2 > 0) {
    const double sn = dot(spring, n);
    const Vec3 sp = spring - sn * n;
    const double x = sn * sn / s2;  // fraction of the length squared that was normal
    // length factor 1 / sqrt(1 - x); its series is exact to 1e-18 for the usual tiny x
    const double f = x < 1e-6 ? 1 + 0.5 * x : (x < 1 ? 1 / std::sqrt(1 - x) : 0.0);
    spring = f * sp;
  }
  spring += (active * dt) * vt;
  Vec3 ft = -c.kt * spring - (active * c.etat) * vt;
  const double cap = law.friction * (fn > 0 ? fn : 0.0);
  const double ft2 = norm2(ft);
  // The cap binds in a fair share of the contacts of a resting bed, unpredictably, and its test
  // comes at the end of the longest chain of the step: a branch there flushes the work on the
  // next pairs when mispredicted. Both outcomes are computed and one is selected (bit for bit
  // what the branch gave; the unselected quotient may be inf or NaN and is dropped).
  const bool binds = ft2 > cap * cap;
  const Vec3 capped = (cap / std::sqrt(ft2)) * ft;
  const Vec3 reset = c.kt > 0 ? c.neg_inv_kt * capped : Vec3{};
  ft = select(binds, capped, ft);
  spring = select(binds, reset, spring);
  force = fn * n + ft;
  return true;
}

// Cheap test that a pair with squared centre distance d2 and contact distance rsum cannot be
// active this step (distance - rsum >= |urel| dt / 2), without a square root.
inline bool surely_apart(double d2, double rsum, double urel2, double dt) {
  if (d2 < rsum * rsum) return false;
  const double g2 = 0.25 * dt * dt * urel2;
  const double q = d2 - rsum * rsum - g2;
  return (q >= 0) & (q * q >= 4 * rsum * rsum * g2);  // one branch for the caller, not two
}

// Period used by the dt check: the shortest of the damped and undamped normal contact
// durations and the tangential half period, for the given effective length and mass.
double stability_period(const ContactLaw& law, double length, double m_eff);

}  // namespace dem
