#include <algorithm>
#include <cmath>
#include <cstring>
#include <string_view>

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
  if (!s.w.empty()) {  // the rotating model: a new particle starts without spin
    s.w.push_back(Vec3{});
    s.wu.push_back(Vec3{});
  }
  s.lists_valid = false;
}

}  // namespace dem

namespace dem {

void build_pair_rows(State& s) {
  const std::size_t n = s.size();
  s.pair_row_offset.assign(n + 1, 0);
  for (const std::int32_t j : s.pair_j) ++s.pair_row_offset[j + 1];
  for (std::size_t j = 0; j < n; ++j) s.pair_row_offset[j + 1] += s.pair_row_offset[j];
  s.pair_row.resize(s.pair_j.size());
  std::vector<std::int32_t> next(s.pair_row_offset.begin(), s.pair_row_offset.end() - 1);
  for (std::size_t i = 0; i < n; ++i)
    for (std::int32_t k = s.pair_offset[i]; k < s.pair_offset[i + 1]; ++k)
      s.pair_row[next[s.pair_j[k]]++] = static_cast<std::int32_t>(i);
}

std::size_t remove_particles(State& s, const std::vector<std::uint8_t>& remove) {
  const std::size_t n = s.size();
  std::vector<std::int32_t> new_index(n, -1);
  std::size_t m = 0;
  double mass = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (remove[i])
      mass += s.mass[i];
    else
      new_index[i] = static_cast<std::int32_t>(m++);
  }
  if (m == n) return 0;
  // The lists read the old numbering: compact them first. Rows of removed particles and
  // entries naming one go; the rest keep their order (so i < j still holds).
  if (s.pair_offset.size() == n + 1) {
    std::vector<std::int32_t> off(m + 1, 0), J;
    std::vector<Vec3> spring, roll;
    J.reserve(s.pair_j.size());
    spring.reserve(s.pair_spring.size());
    const bool rolls = !s.pair_roll.empty() && s.pair_roll.size() == s.pair_j.size();
    for (std::size_t i = 0; i < n; ++i) {
      if (remove[i]) continue;
      for (std::int32_t k = s.pair_offset[i]; k < s.pair_offset[i + 1]; ++k) {
        const std::int32_t j = new_index[s.pair_j[k]];
        if (j < 0) continue;
        J.push_back(j);
        spring.push_back(s.pair_spring[k]);
        if (rolls) roll.push_back(s.pair_roll[k]);  // the rotating model's rolling springs
      }
      off[new_index[i] + 1] = static_cast<std::int32_t>(J.size());
    }
    s.pair_offset.swap(off);
    s.pair_j.swap(J);
    s.pair_spring.swap(spring);
    s.pair_roll.swap(roll);
  }
  if (s.tri_offset.size() == n + 1) {
    std::vector<std::int32_t> off(m + 1, 0), tool, tri;
    for (std::size_t i = 0; i < n; ++i) {
      if (remove[i]) continue;
      for (std::int32_t k = s.tri_offset[i]; k < s.tri_offset[i + 1]; ++k) {
        tool.push_back(s.tri_tool[k]);
        tri.push_back(s.tri_index[k]);
      }
      off[new_index[i] + 1] = static_cast<std::int32_t>(tool.size());
    }
    s.tri_offset.swap(off);
    s.tri_tool.swap(tool);
    s.tri_index.swap(tri);
  }
  // Every per-particle array of the field list (particle and sorted fields, and the two derived
  // arrays that have one entry per particle); the boundary slot pool stays (slot_block keeps
  // indexing it) and tool poses are not per particle.
  auto compact = [&](auto& a) {
    if (a.size() != n) return;  // a sorted field before the first broad phase
    std::size_t k = 0;
    for (std::size_t i = 0; i < n; ++i)
      if (!remove[i]) a[k++] = a[i];
    a.resize(m);
  };
  for_each_array(s, [&](const char* name, auto& a, Field field) {
    const std::string_view key(name);
    if (field != Field::derived || key == "x_at_rebuild" || key == "wall_mask") compact(a);
  });
  s.pair_row_offset.clear();  // the lists changed: built again when sleeping needs it
  s.pair_row.clear();
  s.removed_count += static_cast<std::int64_t>(n - m);
  s.removed_mass += mass;
  return n - m;
}

std::string differing_arrays(const State& a, const State& b) {
  std::string names;
  for_each_array(a, [&](const char* name, const auto& x, Field) {
    for_each_array(b, [&](const char* other, const auto& y, Field) {
      if (std::strcmp(name, other) != 0) return;
      const std::size_t size = x.size() * sizeof(x[0]);
      if (y.size() != x.size() || (size > 0 && std::memcmp(x.data(), y.data(), size) != 0))
        names += std::string(" ") + name;
    });
  });
  return names;
}

}  // namespace dem
