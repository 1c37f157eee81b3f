#include "dem/contact_law.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "cosim/yaml_config.hpp"

namespace dem {
namespace cfg = cosim::config;

double damping_ratio_from_restitution(double e) {
  const double l = std::log(e);
  return -l / std::sqrt(M_PI * M_PI + l * l);
}

void finalize(ContactLaw& law, const std::string& path) {
  auto fail = [&](const std::string& key, double value, const std::string& fix) {
    std::ostringstream msg;
    msg << path << "." << key << ": " << value << " is not allowed; " << fix;
    throw std::invalid_argument(msg.str());
  };
  if (!(law.normal_stiffness > 0))
    fail("normal_stiffness", law.normal_stiffness,
         "give a stiffness > 0 (Pa, or N/m with stiffness_unit: N/m)");
  if (law.damping_from_restitution) {
    if (!(law.restitution > 0 && law.restitution <= 1))
      fail("restitution", law.restitution,
           "give a value in (0, 1], or normal_damping (N s/m) for a damping coefficient instead");
    law.zeta = damping_ratio_from_restitution(law.restitution);
  } else if (!(law.normal_damping >= 0)) {
    fail("normal_damping", law.normal_damping, "give a damping coefficient >= 0 (N s/m)");
  }
  if (!(law.tangential_stiffness_ratio >= 0))
    fail("tangential_stiffness_ratio", law.tangential_stiffness_ratio,
         "give k_T / k_N >= 0 (0 = no tangential spring)");
  if (!(law.tangential_damping_ratio >= 0))
    fail("tangential_damping_ratio", law.tangential_damping_ratio,
         "give eta_T / eta_N >= 0 (0 = no tangential dashpot)");
  if (!(law.friction >= 0))
    fail("friction", law.friction, "give a Coulomb coefficient >= 0 (0 = frictionless)");
}

ContactLaw parse_contact_law(const YAML::Node& n, const std::string& path) {
  cfg::check_keys(n, path,
                  {"normal_stiffness", "stiffness_unit", "restitution", "normal_damping",
                   "clip_attractive", "tangential_stiffness_ratio", "tangential_damping_ratio",
                   "friction"});
  ContactLaw l;  // its initialisers are the defaults
  l.normal_stiffness = cfg::get_double(n, path, "normal_stiffness");
  l.stiffness_per_length = cfg::get_choice(n, path, "stiffness_unit", {"Pa", "N/m"},
                                           l.stiffness_per_length ? "Pa" : "N/m") == "Pa";
  const bool has_e = static_cast<bool>(n["restitution"]);
  const bool has_eta = static_cast<bool>(n["normal_damping"]);
  if (has_e == has_eta)
    throw cfg::ConfigError(path + ": give exactly one of restitution (0..1) or normal_damping (N s/m)");
  l.damping_from_restitution = has_e;
  if (has_e)
    l.restitution = cfg::get_double(n, path, "restitution");
  else
    l.normal_damping = cfg::get_double(n, path, "normal_damping");
  l.clip_attractive = cfg::get_bool_or(n, path, "clip_attractive", l.clip_attractive);
  l.tangential_stiffness_ratio =
      cfg::get_double_or(n, path, "tangential_stiffness_ratio", l.tangential_stiffness_ratio);
  l.tangential_damping_ratio =
      cfg::get_double_or(n, path, "tangential_damping_ratio", l.tangential_damping_ratio);
  l.friction = cfg::get_double_or(n, path, "friction", l.friction);
  try {
    finalize(l, path);
  } catch (const std::invalid_argument& e) {
    throw cfg::ConfigError(e.what());
  }
  return l;
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

}  // namespace dem
