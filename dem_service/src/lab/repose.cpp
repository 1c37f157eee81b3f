#include "dem/lab/repose.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>

#include "cosim/yaml_config.hpp"
#include "dem/mesh.hpp"
#include "dem/rotation.hpp"
#include "dem/stability.hpp"

namespace dem::lab {
namespace cfg = cosim::config;

namespace {
constexpr double kDeg = 180.0 / M_PI;

double nonnegative(const YAML::Node& n, const std::string& path, const std::string& key,
                   double fallback, const std::string& what) {
  if (!n || !n[key]) return fallback;
  const double v = cfg::get_double(n, path, key);
  if (!(v >= 0) || !std::isfinite(v))
    throw cfg::ConfigError(path + "." + key + ": must be >= 0 (" + what + "), got " +
                           n[key].Scalar());
  return v;
}

struct Cylinder {
  double radius;
};
bool inside_cylinder(Vec3 c, double r, const void* ctx) {
  const double R = static_cast<const Cylinder*>(ctx)->radius;
  return std::hypot(c.x, c.y) <= R - r;
}

// A tube of radius R from z0 to z1 about the z axis, `segments` facets, triangles facing both
// ways (mesh contacts are by distance).
Mesh tube(double R, double z0, double z1, int segments) {
  std::vector<Vec3> c;
  for (int k = 0; k < segments; ++k) {
    const double a0 = 2 * M_PI * k / segments, a1 = 2 * M_PI * (k + 1) / segments;
    const Vec3 p0{R * std::cos(a0), R * std::sin(a0), z0}, p1{R * std::cos(a1), R * std::sin(a1), z0};
    const Vec3 q0{p0.x, p0.y, z1}, q1{p1.x, p1.y, z1};
    c.insert(c.end(), {p0, p1, q1, p0, q1, q0});
  }
  return build_mesh(c, "lab cylinder");
}
}  // namespace

ReposeOptions parse_repose(const YAML::Node& root) {
  cfg::check_keys(root, "", {"grains", "repose", "run"});
  ReposeOptions o;
  o.grains = parse_grains(root["grains"], "grains");
  const YAML::Node n = root["repose"];
  if (!n) throw cfg::ConfigError("repose: missing (expected at least {count})");
  cfg::check_keys(n, "repose", {"count", "seed", "cylinder_radius", "lift_speed", "base_radius",
                                "ke_per_grain", "max_time", "sectors"});
  if (n["count"]) {
    o.count = cfg::get_int(n, "repose", "count");
    if (o.count < 50 || o.count > 2000000)
      throw cfg::ConfigError("repose.count: " + std::to_string(o.count) +
                             " grains is outside 50 .. 2000000; a heap needs a few hundred");
  }
  if (n["seed"]) {
    const long long s = cfg::get_int(n, "repose", "seed");
    if (s < 0) throw cfg::ConfigError("repose.seed: must be an integer >= 0");
    o.seed = static_cast<std::uint64_t>(s);
  }
  o.cylinder_radius = nonnegative(n, "repose", "cylinder_radius", 0, "m; 0 = the column of grains stands two radii high");
  o.lift_speed = nonnegative(n, "repose", "lift_speed", 0, "m/s; 0 = 0.5 sqrt(g d)");
  o.base_radius = nonnegative(n, "repose", "base_radius", 0, "m; 0 = 4 cylinder radii");
  o.ke_per_grain = nonnegative(n, "repose", "ke_per_grain", 0, "J; 0 = 1e-6 m g d");
  if (n["max_time"]) {
    o.max_time = cfg::get_double(n, "repose", "max_time");
    if (!(o.max_time > 0) || !std::isfinite(o.max_time))
      throw cfg::ConfigError("repose.max_time: must be > 0 s, got " + n["max_time"].Scalar());
  }
  if (n["sectors"]) {
    o.sectors = static_cast<int>(cfg::get_int(n, "repose", "sectors"));
    if (o.sectors < 1 || o.sectors > 64)
      throw cfg::ConfigError("repose.sectors: must be 1 .. 64");
  }
  const double d = 2 * o.grains.mean_radius();
  if (o.cylinder_radius > 0 && o.cylinder_radius < 3 * d)
    throw cfg::ConfigError("repose.cylinder_radius: " + std::to_string(o.cylinder_radius) +
                           " m is less than 3 grain diameters; a heap needs room");
  if (o.base_radius > 0) {
    const double R = o.cylinder_radius > 0 ? o.cylinder_radius
                     : std::cbrt(static_cast<double>(o.count) * o.grains.mean_volume() / (0.6 * 2 * M_PI));
    if (o.base_radius < 2 * R)
      throw cfg::ConfigError("repose.base_radius: " + std::to_string(o.base_radius) +
                             " m is less than twice the cylinder radius; the heap spreads wider");
  }
  const YAML::Node r = root["run"];
  if (r) {
    cfg::check_keys(r, "run", {"threads"});
    if (r["threads"]) {
      o.threads = static_cast<int>(cfg::get_int(r, "run", "threads"));
      if (o.threads < 1 || o.threads > 256) throw cfg::ConfigError("run.threads: must be 1 .. 256");
    }
  }
  return o;
}

namespace {
// Line height = a + b radius through the points; false with fewer than 3 or no spread.
bool line_fit(const std::vector<std::pair<double, double>>& pts, double& a, double& b) {
  double X = 0, Y = 0, XX = 0, XY = 0;
  const double N = static_cast<double>(pts.size());
  for (const auto& [x, y] : pts) {
    X += x;
    Y += y;
    XX += x * x;
    XY += x * y;
  }
  const double den = N * XX - X * X;
  if (pts.size() < 3 || den <= 0) return false;
  b = (N * XY - X * Y) / den;
  a = (Y - b * X) / N;
  return true;
}
}  // namespace

ReposeResult fit_heap(const std::vector<Vec3>& x, const std::vector<double>& r, double base,
                      double bin, int sectors) {
  ReposeResult out;
  // The surface: the highest grain top in each ring (radial bin) for the angle, and in each
  // sector of each ring for the scatter between sectors.
  // (height, radius of that grain)
  std::map<int, std::pair<double, double>> ring;
  std::map<std::pair<int, int>, std::pair<double, double>> top;
  double hmax = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double h = x[i].z + r[i] - base;
    const double rr = std::hypot(x[i].x, x[i].y);
    double a = std::atan2(x[i].y, x[i].x);
    if (a < 0) a += 2 * M_PI;
    const int s = std::min(sectors - 1, static_cast<int>(a / (2 * M_PI) * sectors));
    const int b = static_cast<int>(rr / bin);
    auto it = top.find({s, b});
    if (it == top.end() || h > it->second.first) top[{s, b}] = {h, rr};
    auto jt = ring.find(b);
    if (jt == ring.end() || h > jt->second.first) ring[b] = {h, rr};
    hmax = std::max(hmax, h);
  }
  out.height = hmax;
  // The slope: heights between 15 % and 85 % of the heap's (the flat top and the toe left out).
  const double lo = 0.15 * hmax, hi = 0.85 * hmax;
  auto slope_point = [&](double h) { return h >= lo && h <= hi; };
  std::vector<std::pair<double, double>> pts;
  for (const auto& [b, hr] : ring) {
    const double h = hr.first;
    SurfacePoint p;
    p.sector = -1;
    p.radius = hr.second;
    p.height = h;
    p.used = slope_point(h);
    out.surface.push_back(p);
    if (p.used) pts.emplace_back(p.radius, h);
  }
  double a = 0, slope = 0;
  if (!line_fit(pts, a, slope)) return out;
  out.intercept = a;
  out.angle = std::atan(-slope) * kDeg;
  out.pile_radius = slope < 0 ? a / -slope : 0;
  std::vector<std::vector<std::pair<double, double>>> per(static_cast<std::size_t>(sectors));
  for (const auto& [key, hr] : top) {
    const double h = hr.first;
    SurfacePoint p;
    p.sector = key.first;
    p.radius = hr.second;
    p.height = h;
    // The innermost ring's sectors are too small to hold the surface.
    p.used = key.second >= 1 && slope_point(h);
    out.surface.push_back(p);
    if (p.used) per[static_cast<std::size_t>(p.sector)].emplace_back(p.radius, h);
  }
  std::vector<double> angles;
  for (const auto& sp : per) {
    double sa, sb;
    if (line_fit(sp, sa, sb)) angles.push_back(std::atan(-sb) * kDeg);
  }
  out.sectors = static_cast<int>(angles.size());
  if (angles.size() >= 2) {
    double m = 0, v = 0;
    for (double v1 : angles) m += v1;
    m /= static_cast<double>(angles.size());
    for (double v1 : angles) v += (v1 - m) * (v1 - m);
    out.angle_sd = std::sqrt(v / static_cast<double>(angles.size() - 1));
  }
  return out;
}

ReposeResult run_repose(const ReposeOptions& o, const Progress& progress) {
  const double g = 9.81;
  const double d = 2 * o.grains.mean_radius(), rmax = o.grains.radius_max;
  // Default radius: the poured column, settled near 0.6 packing, stands two radii high.
  const double R = o.cylinder_radius > 0
                       ? o.cylinder_radius
                       : std::cbrt(static_cast<double>(o.count) * o.grains.mean_volume() / (0.6 * 2 * M_PI));
  const double Rb = o.base_radius > 0 ? o.base_radius : 4 * R;
  Scene scene = make_scene(o.grains, {0, 0, -g}, o.threads);
  const double mg = o.grains.density * o.grains.mean_volume() * g;
  const double ke = o.ke_per_grain > 0 ? o.ke_per_grain : 1e-6 * mg * d;
  const double lift = o.lift_speed > 0 ? o.lift_speed : 0.5 * std::sqrt(g * d);
  // The base: a rough plate of grains of the largest radius pinned in a square array, touching
  // (a free grain cannot pass between four of them), then the grains inside the cylinder, whose
  // bottom edge stands just above the base.
  State s;
  {
    const double pitch = 2 * rmax;
    const long m = static_cast<long>(std::floor(Rb / pitch));
    const Species& sp = scene.species[0];
    std::int64_t id = 0;
    for (long i = -m; i <= m; ++i)
      for (long j = -m; j <= m; ++j) {
        const Vec3 c{i * pitch, j * pitch, rmax};
        if (std::hypot(c.x, c.y) > Rb - rmax) continue;
        add_particle(s, c, {}, rmax, sp.mass(rmax), 0, id++);
      }
  }
  const long nbase = static_cast<long>(s.size());
  std::vector<Vec3> base_x(static_cast<std::size_t>(nbase));
  double base_top = 0;
  for (long i = 0; i < nbase; ++i) {
    base_x[static_cast<std::size_t>(s.id[static_cast<std::size_t>(i)])] = s.x[static_cast<std::size_t>(i)];
    base_top += s.x[static_cast<std::size_t>(i)].z + s.radius[static_cast<std::size_t>(i)];
  }
  base_top /= static_cast<double>(std::max(1L, nbase));
  const double z0 = 2 * rmax * 1.001;  // cylinder's bottom edge
  const double fill_h = static_cast<double>(o.count) * o.grains.mean_volume() / (0.3 * M_PI * (R - rmax) * (R - rmax));
  const double z1 = z0 + rmax + fill_h + 2 * rmax;
  const Cylinder cyl{R};
  insert_random(scene, s, {-R, -R, z0 + rmax}, {R, R, z0 + rmax + fill_h}, o.count, o.seed,
                "repose.count", inside_cylinder, &cyl);
  Tool tool;
  tool.name = "cylinder";
  tool.mesh = tube(R, 0, z1 - z0 + 2 * rmax, 96);
  scene.tools.push_back(tool);
  s.tool_pose.assign(1, ToolPose{});
  s.tool_pose[0].position = {0, 0, z0};
  scene.region.enabled = true;
  scene.region.min = {-Rb - 2 * rmax, -Rb - 2 * rmax, -rmax};
  scene.region.max = {Rb + 2 * rmax, Rb + 2 * rmax, z1 + 100 * d};
  validate_state(scene, s);
  Engine engine(scene);
  const double dt = scene.dt;
  auto pin = [&]() {
    for (std::size_t i = 0; i < s.size(); ++i)
      if (s.id[i] < nbase) {
        s.x[i] = base_x[static_cast<std::size_t>(s.id[i])];
        s.v[i] = s.u[i] = Vec3{};
        if (!s.w.empty()) s.w[i] = s.wu[i] = Vec3{};  // the rotating model: the base does not spin
      }
  };
  // Kinetic energy per free grain; with the rotating model the spins count (a grain rolling
  // down the heap is not at rest).
  auto free_ke = [&]() {
    double e = 0;
    long n = 0;
    for (std::size_t i = 0; i < s.size(); ++i)
      if (s.id[i] >= nbase) {
        e += 0.5 * s.mass[i] * norm2(s.v[i]);
        if (!s.w.empty())
          e += 0.5 * moment_of_inertia(s.mass[i], s.radius[i]) * norm2(s.w[i]);
        ++n;
      }
    return n ? e / static_cast<double>(n) : 0.0;
  };
  auto settle_stage = [&](const std::string& what, double min_time) {
    double t = 0;
    while (true) {
      for (int k = 0; k < 200; ++k) {
        engine.step(s);
        pin();
      }
      t += 200 * dt;
      const double e = free_ke();
      if (t >= min_time && e < ke) break;
      if (t >= o.max_time) {
        if (progress) progress(what + ": not settled after repose.max_time; measuring anyway");
        break;
      }
    }
    if (progress) {
      std::ostringstream line;
      line << what << ": settled after " << t << " s (KE per grain " << free_ke() << " J)";
      progress(line.str());
    }
  };
  settle_stage("fill", std::sqrt(2 * fill_h / g) + 0.1);
  // Lift until the cylinder's bottom edge is above every grain.
  while (true) {
    double top = 0;
    for (std::size_t i = 0; i < s.size(); ++i) top = std::max(top, s.x[i].z + s.radius[i]);
    if (s.tool_pose[0].position.z > top + rmax) break;
    for (int k = 0; k < 100; ++k) {
      s.tool_pose[0].velocity = {0, 0, lift};
      s.tool_pose[0].position.z += lift * dt;
      engine.step(s);
      pin();
    }
  }
  // Take the cylinder away (far above) and let the heap come to rest.
  s.tool_pose[0].velocity = {};
  s.tool_pose[0].position.z += 1000 * R;
  settle_stage("heap", 0.2);
  ReposeResult res;
  std::vector<Vec3> x;
  std::vector<double> r;
  for (std::size_t i = 0; i < s.size(); ++i)
    if (s.id[i] >= nbase) {
      x.push_back(s.x[i]);
      r.push_back(s.radius[i]);
    }
  res = fit_heap(x, r, base_top, d, o.sectors);
  res.count = static_cast<long>(x.size());
  res.lost = o.count - res.count;
  res.base = base_top;
  res.cylinder_radius = R;
  res.grains = x;
  res.radius = r;
  return res;
}

}  // namespace dem::lab
