#include "dem/lab/grains.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "cosim/yaml_config.hpp"
#include "dem/bed.hpp"
#include "dem/rotation.hpp"
#include "dem/stability.hpp"

namespace dem::lab {
namespace cfg = cosim::config;

double Grains::mean_volume() const {
  const double a = radius_min, b = radius_max;
  const double r3 = b > a ? (b * b * b * b - a * a * a * a) / (4 * (b - a)) : a * a * a;
  return 4.0 / 3.0 * M_PI * r3;
}

Grains parse_grains(const YAML::Node& n, const std::string& path) {
  if (!n) throw cfg::ConfigError(path + ": missing (expected {density, radius, contact})");
  cfg::check_keys(n, path, {"density", "radius", "contact", "model", "rolling_resistance"});
  Grains g;
  g.density = cfg::get_double(n, path, "density");
  if (!(g.density > 0) || !std::isfinite(g.density))
    throw cfg::ConfigError(path + ".density: must be > 0 kg/m^3, got " + n["density"].Scalar());
  const YAML::Node r = n["radius"];
  if (!r) throw cfg::ConfigError(path + ".radius: missing (metres, or {min, max})");
  if (r.IsMap()) {
    cfg::check_keys(r, path + ".radius", {"min", "max"});
    g.radius_min = cfg::get_double(r, path + ".radius", "min");
    g.radius_max = cfg::get_double(r, path + ".radius", "max");
  } else {
    g.radius_min = g.radius_max = cfg::get_double(n, path, "radius");
  }
  if (!(g.radius_min > 0) || !std::isfinite(g.radius_max) || !(g.radius_max >= g.radius_min))
    throw cfg::ConfigError(path + ".radius: need 0 < min <= max (m), got " +
                           std::to_string(g.radius_min) + " .. " + std::to_string(g.radius_max));
  if (!n["contact"]) throw cfg::ConfigError(path + ".contact: missing (the particle contact law, "
                                            "keys of contact.particle_particle in docs/dem.md)");
  g.law = parse_contact_law(n["contact"], path + ".contact");
  g.rotation = parse_model(n, path);
  return g;
}

RotationOptions parse_model(const YAML::Node& n, const std::string& path) {
  // The engine's own reader and checks of particles.model and particles.rolling_resistance,
  // with their messages naming the lab's keys (path.model, path.rolling_resistance).
  YAML::Node parts(YAML::NodeType::Map);
  if (n && n.IsMap()) {
    if (n["model"]) parts["model"] = n["model"];
    if (n["rolling_resistance"]) parts["rolling_resistance"] = n["rolling_resistance"];
  }
  Scene sc;  // no sleeping: the lab does not sleep
  try {
    parse_rotation(parts, sc);
  } catch (const cfg::ConfigError& e) {
    std::string m = e.what();
    const std::string from = "particles.", to = path + ".";
    for (std::size_t at = m.find(from); at != std::string::npos; at = m.find(from, at + to.size()))
      m.replace(at, from.size(), to);
    throw cfg::ConfigError(m);
  }
  return sc.rotation;
}

Scene make_scene(const Grains& g, Vec3 gravity, int threads, double dt_factor) {
  Scene sc;
  sc.gravity = gravity;
  sc.threads = std::max(1, threads);
  Species sp;
  sp.name = "grain";
  sp.density = g.density;
  sp.radius.kind = g.radius_max > g.radius_min ? RadiusDistribution::Kind::uniform
                                               : RadiusDistribution::Kind::constant;
  sp.radius.min = g.radius_min;
  sp.radius.max = g.radius_max;
  sc.species.push_back(sp);
  sc.particle_particle = g.law;
  sc.rotation = g.rotation;
  ContactLaw wall = g.law;
  wall.friction = 0;
  wall.damping_from_restitution = false;
  wall.normal_damping = 0;
  wall.tangential_damping_ratio = 0;
  finalize(wall, "lab walls");
  sc.particle_wall = wall;
  sc.dt = largest_safe_dt(sc) * dt_factor;
  return sc;
}

void insert_random(const Scene& scene, State& s, Vec3 lo, Vec3 hi, long count,
                   std::uint64_t seed, const std::string& what,
                   bool (*inside)(Vec3, double, const void*), const void* ctx) {
  const Species& sp = scene.species.at(0);
  const double rmax = std::max(sp.radius.min, sp.radius.max);
  const double cell = 2 * rmax;
  auto key = [&](long i, long j, long k) {
    return (static_cast<std::int64_t>(i) * 73856093) ^ (static_cast<std::int64_t>(j) * 19349663) ^
           (static_cast<std::int64_t>(k) * 83492791);
  };
  auto index = [&](double v, double o) { return static_cast<long>(std::floor((v - o) / cell)); };
  std::unordered_multimap<std::int64_t, std::size_t> grid;
  for (std::size_t i = 0; i < s.size(); ++i)
    grid.emplace(key(index(s.x[i].x, lo.x), index(s.x[i].y, lo.y), index(s.x[i].z, lo.z)), i);
  std::uint64_t rng = seed * 0x2545F4914F6CDD1Dull + 777;
  std::int64_t next_id = s.id.empty() ? 0 : *std::max_element(s.id.begin(), s.id.end()) + 1;
  const long long max_tries = 2000LL * std::max(1L, count);
  long long tries = 0;
  for (long placed = 0; placed < count;) {
    if (++tries > max_tries) {
      std::ostringstream msg;
      msg << what << ": only " << placed << " of " << count
          << " grains found room by random insertion; give fewer grains or a lower "
             "initial packing fraction";
      throw std::invalid_argument(msg.str());
    }
    const double r = sp.radius.kind == RadiusDistribution::Kind::uniform
                         ? sp.radius.min + (sp.radius.max - sp.radius.min) * uniform01(rng)
                         : sp.radius.min;
    const Vec3 x{lo.x + (hi.x - lo.x) * uniform01(rng), lo.y + (hi.y - lo.y) * uniform01(rng),
                 lo.z + (hi.z - lo.z) * uniform01(rng)};
    if (inside && !inside(x, r, ctx)) continue;
    const long ci = index(x.x, lo.x), cj = index(x.y, lo.y), ck = index(x.z, lo.z);
    bool free = true;
    for (long a = -1; a <= 1 && free; ++a)
      for (long b = -1; b <= 1 && free; ++b)
        for (long c = -1; c <= 1 && free; ++c) {
          auto range = grid.equal_range(key(ci + a, cj + b, ck + c));
          for (auto it = range.first; it != range.second; ++it) {
            const std::size_t j = it->second;
            const double d = r + s.radius[j];
            if (norm2(s.x[j] - x) < d * d) {
              free = false;
              break;
            }
          }
        }
    if (!free) continue;
    add_particle(s, x, {}, r, sp.mass(r), 0, next_id++);
    grid.emplace(key(ci, cj, ck), s.size() - 1);
    ++placed;
  }
}

BoxRig::BoxRig(Scene& scene, Vec3 lo, Vec3 hi) : scene_(scene), lo_(lo), hi_(hi) {
  first_ = static_cast<int>(scene.walls.size());
  const char* names[6] = {"x_min", "x_max", "y_min", "y_max", "z_min", "z_max"};
  for (int f = 0; f < 6; ++f) {
    Wall w;
    w.name = names[f];
    const int axis = f / 2;
    const double sign = f % 2 == 0 ? 1.0 : -1.0;
    Vec3 n{0, 0, 0};
    (axis == 0 ? n.x : axis == 1 ? n.y : n.z) = sign;
    w.normal = n;
    w.point = f % 2 == 0 ? lo : hi;
    w.from_box = true;
    w.box_min = lo;
    w.box_max = hi;
    scene.walls.push_back(w);
  }
}

double BoxRig::volume() const {
  const Vec3 d = size();
  return d.x * d.y * d.z;
}

double BoxRig::area(int face) const {
  const Vec3 d = size();
  const int axis = face / 2;
  return axis == 0 ? d.y * d.z : axis == 1 ? d.x * d.z : d.x * d.y;
}

void BoxRig::move(int face, double dx) {
  Wall& w = scene_.walls[static_cast<std::size_t>(first_ + face)];
  w.point += dx * w.normal;
  const int axis = face / 2;
  double& v = face % 2 == 0 ? (axis == 0 ? lo_.x : axis == 1 ? lo_.y : lo_.z)
                            : (axis == 0 ? hi_.x : axis == 1 ? hi_.y : hi_.z);
  v = face % 2 == 0 ? v + dx : v - dx;
  moved_[static_cast<std::size_t>(face)] += std::abs(dx);
  for (int f = 0; f < 6; ++f) {
    scene_.walls[static_cast<std::size_t>(first_ + f)].box_min = lo_;
    scene_.walls[static_cast<std::size_t>(first_ + f)].box_max = hi_;
  }
}

double BoxRig::stress(const Engine& engine, int face) const {
  const Wall& w = scene_.walls[static_cast<std::size_t>(first_ + face)];
  return -dot(engine.wall_forces()[static_cast<std::size_t>(first_ + face)], w.normal) /
         area(face);
}

double BoxRig::contact_stiffness(const State& s, int face) const {
  const Wall& w = scene_.walls[static_cast<std::size_t>(first_ + face)];
  const ContactLaw& law = scene_.particle_wall;
  double k = 0;
  for (std::size_t i = 0; i < s.size(); ++i)
    if (dot(s.x[i] - w.point, w.normal) < s.radius[i])
      k += law.stiffness_per_length ? law.normal_stiffness * s.radius[i] : law.normal_stiffness;
  return k;
}

void BoxRig::before_step(Engine& engine, State& s) {
  if (s.rebuilds != rebuilds_seen_) {
    moved_.fill(0);
    rebuilds_seen_ = s.rebuilds;
  }
  const double most = *std::max_element(moved_.begin(), moved_.end());
  if (s.lists_valid && most > 0.1 * scene_.skin_distance()) {
    engine.rebuild(s);
    moved_.fill(0);
    rebuilds_seen_ = s.rebuilds;
  }
}

double servo_speed(double gain, double area, double error, double stiffness, double dt,
                   double max_speed) {
  const double v = gain * area * error / (stiffness * dt);
  return std::clamp(v, -max_speed, max_speed);
}

double packing_fraction(const State& s, Vec3 lo, Vec3 hi) {
  // Each grain's volume inside the box: its whole volume less the caps beyond the faces it
  // crosses (a grain whose centre is outside counts the cap inside). Grains at an edge or a
  // corner count a cap twice; at two or more grains across the box that is far below 1e-3.
  auto cap = [](double r, double h) { return M_PI * h * h * (3 * r - h) / 3; };
  double v = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double r = s.radius[i];
    const double c[3] = {s.x[i].x, s.x[i].y, s.x[i].z};
    const double a[3] = {lo.x, lo.y, lo.z}, b[3] = {hi.x, hi.y, hi.z};
    bool outside = false;
    double inside = 4.0 / 3.0 * M_PI * r * r * r;
    for (int k = 0; k < 3 && !outside; ++k) {
      if (c[k] < a[k] - r || c[k] > b[k] + r) outside = true;
    }
    if (outside) continue;
    int out_faces = 0;
    double out_cap = 0;
    for (int k = 0; k < 3; ++k) {
      for (const double d : {c[k] - a[k], b[k] - c[k]}) {
        if (d >= r) continue;
        if (d >= 0) {
          inside -= cap(r, r - d);
        } else {
          ++out_faces;
          out_cap = cap(r, r + d);  // the part inside this face
        }
      }
    }
    if (out_faces == 1) inside = out_cap;
    else if (out_faces > 1) inside = 0;  // beyond an edge of the box: a sliver, left out
    v += std::max(0.0, inside);
  }
  const Vec3 d = hi - lo;
  return v / (d.x * d.y * d.z);
}

double coordination(const Engine& engine, const State& s) {
  if (s.size() == 0) return 0;
  return 2.0 * static_cast<double>(engine.particle_contacts(s).size()) /
         static_cast<double>(s.size());
}

}  // namespace dem::lab
