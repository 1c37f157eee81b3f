#include "dem/coarse_grain.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "cosim/yaml_config.hpp"

namespace dem {
namespace cfg = cosim::config;

double parse_coarse_grain(const YAML::Node& parts) {
  if (!parts || !parts.IsMap() || !parts["coarse_grain"]) return 1.0;
  const double s = cfg::get_double(parts, "particles", "coarse_grain");
  if (!(s >= 0.1 && s <= 10) || !std::isfinite(s)) {
    std::ostringstream m;
    m << "particles.coarse_grain: must be a grain size factor in [0.1, 10] (e.g. 2: grains twice "
         "the radius, 1/8 as many; docs/soil_models.md), got "
      << s;
    throw cfg::ConfigError(m.str());
  }
  return s;
}

namespace {
void scale_law(ContactLaw& law, double s) {
  if (!law.stiffness_per_length) law.normal_stiffness *= s;
  if (!law.damping_from_restitution) law.normal_damping *= s * s;
}
}  // namespace

void coarse_grain_scene(Scene& sc, double s) {
  for (Species& sp : sc.species) {
    sp.radius.min *= s;
    sp.radius.max *= s;
    for (double& v : sp.radius.values) v *= s;
  }
  scale_law(sc.particle_particle, s);
  scale_law(sc.particle_wall, s);
  for (ContactLaw& law : sc.boundary_laws) scale_law(law, s);
  sc.dt *= s;
}

long long coarse_grain_count(long long count, double s) {
  if (count <= 0) return count;
  return std::max(1LL, std::llround(static_cast<double>(count) / (s * s * s)));
}

}  // namespace dem
