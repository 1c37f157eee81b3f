#include <algorithm>
#include <cmath>

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
