#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "dem/contact_law.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

double Scene::r_max() const {
  double r = 0;
  for (const auto& s : species) {
    r = std::max(r, s.radius.max);
    for (double v : s.radius.values) r = std::max(r, v);
  }
  return r;
}

double damping_ratio_from_restitution(double e) {
  const double l = std::log(e);
  return -l / std::sqrt(M_PI * M_PI + l * l);
}

void finalize(ContactLaw& law, const std::string& path) {
  auto fail = [&](const std::string& key, const std::string& msg) {
    throw std::invalid_argument(path + "." + key + ": " + msg);
  };
  if (!(law.normal_stiffness > 0)) fail("normal_stiffness", "must be > 0");
  if (law.damping_from_restitution) {
    if (!(law.restitution > 0 && law.restitution <= 1))
      fail("restitution", "must be in (0, 1]; use normal_damping for a coefficient instead");
    law.zeta = damping_ratio_from_restitution(law.restitution);
  } else if (!(law.normal_damping >= 0)) {
    fail("normal_damping", "must be >= 0 (N s/m)");
  }
  if (!(law.tangential_stiffness_ratio >= 0)) fail("tangential_stiffness_ratio", "must be >= 0");
  if (!(law.tangential_damping_ratio >= 0)) fail("tangential_damping_ratio", "must be >= 0");
  if (!(law.friction >= 0)) fail("friction", "must be >= 0");
}

double stability_period(const ContactLaw& law, double length, double m_eff) {
  const ContactCoefficients c = coefficients(law, length, m_eff);
  const double w0 = std::sqrt(c.k / m_eff);
  const double zeta = c.eta / (2 * std::sqrt(c.k * m_eff));
  double t = zeta < 1 ? M_PI / (w0 * std::sqrt(1 - zeta * zeta)) : M_PI / w0;
  // Damping shortens the explicit stability limit below the undamped one: count it as a
  // shorter period so the steps-per-contact rule stays conservative.
  t = std::min(t, M_PI / w0);
  if (c.kt > 0) t = std::min(t, M_PI / std::sqrt(c.kt / m_eff));
  return t;
}

void add_particle(State& s, Vec3 x, Vec3 v, double radius, double mass, int species,
                  std::int64_t id) {
  s.x.push_back(x);
  s.v.push_back(v);
  s.u.push_back(v);
  s.radius.push_back(radius);
  s.mass.push_back(mass);
  s.species.push_back(species);
  s.id.push_back(id);
  s.lists_valid = false;
}

}  // namespace dem
