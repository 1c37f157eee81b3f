// The contact law, in one place: linear spring-dashpot normal force, tangential spring with
// history plus dashpot, Coulomb cap. Conventions in docs/physics.md.
#pragma once

#include <cmath>

#include "dem/scene.hpp"
#include "dem/vec3.hpp"

namespace dem {

// Per-contact coefficients; effective length and mass depend on the pair.
struct ContactCoefficients {
  double k = 0;     // normal stiffness, N/m
  double eta = 0;   // normal damping, N s/m
  double kt = 0;    // tangential stiffness, N/m
  double etat = 0;  // tangential damping, N s/m
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
  return c;
}

// Force on the particle. n: unit normal from the other body towards the particle; overlap > 0;
// vrel: particle velocity minus the other body's velocity at the contact. `spring` is the
// tangential displacement stored with the contact; it is rotated into the current tangent
// plane, advanced by vt dt and, when the Coulomb cap binds, reset so k_T |spring| = mu F_n.
inline Vec3 contact_force(const ContactLaw& law, const ContactCoefficients& c, double overlap,
                          Vec3 n, Vec3 vrel, Vec3& spring, double dt) {
  const double vn = dot(vrel, n);
  double fn = c.k * overlap - c.eta * vn;
  if (law.clip_attractive && fn < 0) fn = 0;
  const Vec3 vt = vrel - vn * n;

  // Keep the spring in the tangent plane without changing its length as the normal turns.
  const double s2 = norm2(spring);
  if (s2 > 0) {
    Vec3 sp = spring - dot(spring, n) * n;
    const double sp2 = norm2(sp);
    spring = sp2 > 0 ? std::sqrt(s2 / sp2) * sp : Vec3{};
  }
  spring += dt * vt;
  Vec3 ft = -c.kt * spring - c.etat * vt;
  const double cap = law.friction * (fn > 0 ? fn : 0.0);
  const double ft2 = norm2(ft);
  if (ft2 > cap * cap) {
    ft = (cap / std::sqrt(ft2)) * ft;
    spring = c.kt > 0 ? (-1.0 / c.kt) * ft : Vec3{};
  }
  return fn * n + ft;
}

// Period used by the dt check: the shortest of the damped and undamped normal contact
// durations and the tangential half period, for the given effective length and mass.
double stability_period(const ContactLaw& law, double length, double m_eff);

// Damping ratio for restitution e: zeta = -ln e / sqrt(pi^2 + ln^2 e).
double damping_ratio_from_restitution(double e);

}  // namespace dem
