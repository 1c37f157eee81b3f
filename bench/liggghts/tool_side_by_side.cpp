// Our side of the tool side-by-side benchmark against LIGGGHTS (bench/liggghts/
// tool_side_by_side.sh drives it; not a test; method and results in docs/performance.md,
// "Tool scene against LIGGGHTS"). Two subcommands:
//
//   dem_tool_side_by_side prepare --bed STEM --dir DIR
//       Reads the settled bed of the LAMMPS side-by-side (STEM.h5 and STEM.box, written by
//       `dem_side_by_side prepare --kind bed`), writes the bucket as an ASCII STL in the world
//       frame at t = 0 (DIR/bucket.stl, the same file both codes load), removes the spheres
//       that the bucket's shell would overlap at t = 0 (closer than r + 1 % to a triangle)
//       and writes the rest for both codes: DIR/tool_bed.h5 (our checkpoint), DIR/tool_bed.data
//       (LIGGGHTS `read_data`, atom_style granular) and DIR/tool_bed.box (walls, contact
//       parameters, the bucket's reference point and velocity; read by the driver).
//   dem_tool_side_by_side run --dir DIR --threads T --interval I --steps S --warmup W --block B
//       Loads the scene, steps W times (lists, caches; the bucket already moves), then times S
//       steps and prints one line "rate <particle-steps/s> seconds <wall> simulated <s>
//       rebuilds <n> threads <t> cpu_share <share> n <particles>", one line "phases <section>
//       <seconds> ..." (the engine's timer over the timed steps), then one line per block of
//       B timed steps "F <t_end> <mean Fx> <mean Fy> <mean Fz>" (force on the bucket, N,
//       averaged over every step of the block; the sums cost nothing measurable).
//       --interval 0 rebuilds only when needed (the skin guard). --shift D moves the bucket's
//       path by D metres in y (default 0): a perturbed start, for the spread of our own results.
//
// The bucket: an open box (floor, back, two sides; open to +y and to the top) of
// W x L x H = 0.24 x 0.16 x 0.12 m, cut into 1 cm squares (2 triangles each), centred in x,
// its floor 0.10 m below the bed's top sphere and its back at y = 0.08 m; it moves at a constant
// 1 m/s in +y (horizontal, into the bed) from t = 0, no rotation. Contact law: the one of
// bench/lammps/side_by_side.cpp (linear spring-dashpot, k_N = 2e5 N/m, dashpot m* gamma_n for
// e = 0.3, k_T = 2/7 k_N, eta_T = eta_N / 2, mu = 0.5, attractive part not clipped), with
// m* = m for walls and the bucket; no rotation.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "../common/anchor.hpp"
#include "../common/cli.hpp"
#include "dem/checkpoint.hpp"
#include "dem/engine.hpp"
#include "dem/mesh.hpp"
#include "dem/mesh_contact.hpp"
#include "dem/scene.hpp"

namespace {

// The engine's performance options, filled once from the environment as dem_run does
// (DEM_PAIR_KERNEL, DEM_PAIR_CHUNKS; a bad value stops the bench).
const dem::EngineOptions& bench_engine_options() {
  static const dem::EngineOptions options = dem::EngineOptions::from_environment();
  return options;
}

// The bed's parameters: the LAMMPS side-by-side's (bench/common/anchor.hpp; checked against
// the .box).
using namespace bench;

// The bucket and its motion.
constexpr double kWidth = 0.24;    // x, m
constexpr double kLength = 0.16;   // y (floor, back to cutting edge), m
constexpr double kHeight = 0.12;   // z, m
constexpr double kElement = 0.01;  // m, side of the squares the faces are cut into
constexpr double kDepth = 0.10;    // floor below the bed's top sphere centre, m
constexpr double kBackY = 0.08;    // m
constexpr double kSpeed = 1.0;     // m/s, +y

using KV = std::map<std::string, std::string>;

KV read_kv(const std::string& file) {
  std::ifstream f(file);
  if (!f) throw std::runtime_error(file + " missing");
  KV kv;
  std::string k, v;
  while (f >> k >> v) kv[k] = v;
  return kv;
}

double num(const KV& kv, const std::string& k) {
  const auto it = kv.find(k);
  if (it == kv.end()) throw std::runtime_error("key '" + k + "' missing in a .box file");
  return std::stod(it->second);
}

// The bucket's triangles in the world frame at t = 0. Faces share their grid lines exactly
// (the same expressions), so shared corners are bit-identical and weld.
std::vector<std::array<dem::Vec3, 3>> bucket_triangles(dem::Vec3 ref) {
  const int nx = static_cast<int>(std::lround(kWidth / kElement));
  const int ny = static_cast<int>(std::lround(kLength / kElement));
  const int nz = static_cast<int>(std::lround(kHeight / kElement));
  auto X = [&](int i) { return ref.x - kWidth / 2 + kWidth * i / nx; };
  auto Y = [&](int j) { return ref.y + kLength * j / ny; };
  auto Z = [&](int k) { return ref.z + kHeight * k / nz; };
  std::vector<std::array<dem::Vec3, 3>> t;
  auto quad = [&](dem::Vec3 a, dem::Vec3 b, dem::Vec3 c, dem::Vec3 d) {
    t.push_back({a, b, c});
    t.push_back({a, c, d});
  };
  for (int i = 0; i < nx; ++i)  // floor, normal +z
    for (int j = 0; j < ny; ++j)
      quad({X(i), Y(j), Z(0)}, {X(i + 1), Y(j), Z(0)}, {X(i + 1), Y(j + 1), Z(0)},
           {X(i), Y(j + 1), Z(0)});
  for (int i = 0; i < nx; ++i)  // back, normal +y
    for (int k = 0; k < nz; ++k)
      quad({X(i), Y(0), Z(k)}, {X(i), Y(0), Z(k + 1)}, {X(i + 1), Y(0), Z(k + 1)},
           {X(i + 1), Y(0), Z(k)});
  for (int j = 0; j < ny; ++j)  // sides, normals inward
    for (int k = 0; k < nz; ++k) {
      quad({X(0), Y(j), Z(k)}, {X(0), Y(j + 1), Z(k)}, {X(0), Y(j + 1), Z(k + 1)},
           {X(0), Y(j), Z(k + 1)});
      quad({X(nx), Y(j), Z(k)}, {X(nx), Y(j), Z(k + 1)}, {X(nx), Y(j + 1), Z(k + 1)},
           {X(nx), Y(j + 1), Z(k)});
    }
  return t;
}

void write_stl(const std::vector<std::array<dem::Vec3, 3>>& tris, const std::string& file) {
  std::FILE* f = std::fopen(file.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + file);
  std::fprintf(f, "solid bucket\n");
  for (const auto& t : tris) {
    const dem::Vec3 a = t[1] - t[0], b = t[2] - t[0];
    dem::Vec3 n{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
    const double len = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    n = (1.0 / len) * n;
    std::fprintf(f, " facet normal %.9g %.9g %.9g\n  outer loop\n", n.x, n.y, n.z);
    for (const auto& v : t) std::fprintf(f, "   vertex %.17g %.17g %.17g\n", v.x, v.y, v.z);
    std::fprintf(f, "  endloop\n endfacet\n");
  }
  std::fprintf(f, "endsolid bucket\n");
  std::fclose(f);
}

void write_data(const dem::State& st, double sx, double sy, double ztop, const std::string& file) {
  // Type 2 is for the walls and the bucket; IDs by index (the bucket's spheres were removed).
  write_data_file(st, sx, sy, ztop, "soilcosim tool side-by-side bed (bench/liggghts)",
                  DataFormat{2, false, "Atoms"}, file);
}

void prepare(const std::string& bed, const std::string& dir) {
  const std::string stem = dir + "/tool_bed";
  if (std::filesystem::exists(stem + ".box")) return;  // written last
  std::filesystem::create_directories(dir);
  const KV box = read_kv(bed + ".box");
  if (box.at("kind") != "bed" || std::abs(num(box, "radius") - kR) > 1e-12 ||
      std::abs(num(box, "stiffness") - kStiffness) > 1e-6 || std::abs(num(box, "dt") - kDt) > 1e-15)
    throw std::runtime_error(bed + ".box is not a settled bed of this benchmark's parameters");
  const double sx = num(box, "sx"), sy = num(box, "sy"), ztop = num(box, "ztop");
  const dem::State in = dem::load_checkpoint(bed + ".h5");
  double zmax = 0;
  for (const auto& x : in.x) zmax = std::max(zmax, x.z);
  const dem::Vec3 ref{sx / 2, kBackY, zmax - kDepth};  // back-bottom centre of the bucket
  const auto tris = bucket_triangles(ref);
  write_stl(tris, dir + "/bucket.stl");
  // Spheres the shell overlaps at t = 0 go (the same ones for both codes).
  std::vector<dem::Vec3> corners;
  for (const auto& t : tris) corners.insert(corners.end(), t.begin(), t.end());
  const dem::Mesh mesh = dem::build_mesh(corners, "bucket");
  const double reach = kR * 1.01;
  dem::State st;
  std::int64_t removed = 0;
  std::vector<std::size_t> order(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (in.id[i] < 0 || static_cast<std::size_t>(in.id[i]) >= in.size())
      throw std::runtime_error(bed + ".h5: particle ids are not 0..n-1");
    order[static_cast<std::size_t>(in.id[i])] = i;
  }
  for (const std::size_t i : order) {
    const dem::Vec3 c = in.x[i];
    bool hit = false;
    if (c.x > ref.x - kWidth / 2 - reach && c.x < ref.x + kWidth / 2 + reach &&
        c.y > ref.y - reach && c.y < ref.y + kLength + reach && c.z > ref.z - reach &&
        c.z < ref.z + kHeight + reach)
      for (std::int32_t t = 0; t < static_cast<std::int32_t>(mesh.triangles.size()) && !hit; ++t)
        hit = dem::closest_on_triangle(mesh, mesh.vertices.data(), t, c).dist2 < reach * reach;
    if (hit) {
      ++removed;
      continue;
    }
    dem::add_particle(st, c, in.v[i], in.radius[i], in.mass[i], 0,
                      static_cast<std::int64_t>(st.size()));
  }
  dem::save_checkpoint(st, stem + ".h5");
  write_data(st, sx, sy, ztop, stem + ".data");
  std::ofstream f(stem + ".box");
  f.precision(17);
  f << "n " << st.size() << "\nremoved " << removed << "\nsx " << sx << "\nsy " << sy
    << "\nztop " << ztop << "\nradius " << kR << "\ndensity " << kDensity << "\nmass "
    << sphere_mass() << "\nstiffness " << kStiffness << "\ngamma_n " << gamma_n()
    << "\nfriction " << kFriction << "\ndt " << kDt << "\nskin " << kSkin * kR << "\nref_x "
    << ref.x << "\nref_y " << ref.y << "\nref_z " << ref.z << "\nvx 0\nvy " << kSpeed
    << "\nvz 0\ntriangles " << mesh.triangles.size() << "\n";
  if (!f) throw std::runtime_error("cannot write " + stem + ".box");
  std::fprintf(stderr, "tool bed: %zu spheres (%lld removed where the bucket is), bucket %zu "
                       "triangles, reference point (%.4f, %.4f, %.4f)\n",
               st.size(), static_cast<long long>(removed), mesh.triangles.size(), ref.x, ref.y,
               ref.z);
}

dem::Scene make_scene(const KV& box, const std::string& dir, int threads, int interval,
                      double shift) {
  dem::Scene s;
  dem::Species sp;
  sp.name = "grain";
  sp.density = kDensity;
  sp.radius.min = sp.radius.max = kR;
  s.species.push_back(sp);
  dem::ContactLaw law;
  law.stiffness_per_length = false;
  law.normal_stiffness = kStiffness;
  law.damping_from_restitution = false;
  law.clip_attractive = false;
  law.tangential_stiffness_ratio = 2.0 / 7.0;
  law.tangential_damping_ratio = 0.5;
  law.friction = kFriction;
  dem::ContactLaw pp = law, pw = law;
  pp.normal_damping = sphere_mass() / 2 * gamma_n();
  pw.normal_damping = sphere_mass() * gamma_n();  // walls and the bucket: m* = m
  dem::finalize(pp, "tool_side_by_side.particle_particle");
  dem::finalize(pw, "tool_side_by_side.particle_wall");
  s.particle_particle = pp;
  s.particle_wall = pw;
  s.dt = kDt;
  s.skin = kSkin;
  s.threads = threads;
  s.broad_phase_interval = interval > 0 ? interval : 1 << 30;
  s.guard = dem::GuardMode::rebuild;
  s.stability.min_steps_per_contact = 15;
  s.gravity = {0, 0, -9.81};
  const double sx = num(box, "sx"), sy = num(box, "sy");
  s.walls = {{"floor", {0, 0, 0}, {0, 0, 1}},
             {"x0", {0, 0, 0}, {1, 0, 0}},
             {"x1", {sx, 0, 0}, {-1, 0, 0}},
             {"y0", {0, 0, 0}, {0, 1, 0}},
             {"y1", {0, sy, 0}, {0, -1, 0}}};
  const dem::Vec3 ref{num(box, "ref_x"), num(box, "ref_y"), num(box, "ref_z")};
  const dem::Vec3 path{0, shift, 0};  // --shift: the whole path moved by this much in y
  const dem::Vec3 vel{num(box, "vx"), num(box, "vy"), num(box, "vz")};
  dem::Tool tool;
  tool.name = "bucket";
  tool.mesh = dem::load_mesh(dir + "/bucket.stl", 1.0, ref);
  const double t_end = 10.0;  // s; far beyond any run
  dem::Keyframe k0, k1;
  k0.time = 0;
  k0.position = {ref.x, ref.y + path.y, ref.z};
  k1.time = t_end;
  k1.position = {ref.x + vel.x * t_end, ref.y + path.y + vel.y * t_end, ref.z + vel.z * t_end};
  tool.motion.keyframes = {k0, k1};
  dem::validate_keyframes(tool.motion.keyframes, "tool_side_by_side.bucket");
  s.tools.push_back(std::move(tool));
  return s;
}


int run(const std::string& dir, int threads, int interval, int steps, int warmup, int block,
        double shift) {
  const KV box = read_kv(dir + "/tool_bed.box");
  const dem::Scene scene = make_scene(box, dir, threads, interval, shift);
  dem::State st = dem::load_checkpoint(dir + "/tool_bed.h5");
  st.tool_pose.assign(scene.tools.size(), {});
  dem::Engine engine(scene, bench_engine_options());
  auto advance = [&] {
    for (std::size_t m = 0; m < scene.tools.size(); ++m)
      st.tool_pose[m] = scene.tools[m].motion.evaluate(st.step * scene.dt);
    engine.step(st);
  };
  for (int k = 0; k < warmup; ++k) advance();
  const auto rebuilds0 = st.rebuilds;
  engine.timing().reset();
  std::vector<dem::Vec3> sums((steps + block - 1) / block);
  const double cpu0 = bench::cpu_seconds();
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < steps; ++k) {
    advance();
    sums[k / block] += engine.tool_wrenches()[0].force;
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double share = (bench::cpu_seconds() - cpu0) / (wall * engine.threads());
  std::printf("rate %.6g seconds %.6g simulated %.6g rebuilds %lld threads %d cpu_share %.3f "
              "n %zu\n",
              static_cast<double>(st.size()) * steps / wall, wall, steps * kDt,
              static_cast<long long>(st.rebuilds - rebuilds0), engine.threads(), share,
              st.size());
  std::printf("phases");  // seconds per section of the engine's timer, timed steps only
  for (const auto& row : engine.timing().rows())
    std::printf(" %s %.4g", row.section.c_str(), row.seconds);
  std::printf("\n");
  for (std::size_t b = 0; b < sums.size(); ++b) {
    const int n = std::min(block, steps - static_cast<int>(b) * block);
    if (n != block) break;  // whole blocks only (LIGGGHTS fix ave/time writes those)
    const dem::Vec3 f = (1.0 / n) * sums[b];
    std::printf("F %.6f %.8g %.8g %.8g\n", (warmup + (b + 1) * block) * kDt, f.x, f.y, f.z);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: dem_tool_side_by_side prepare --bed STEM --dir DIR\n"
                         "       dem_tool_side_by_side run --dir DIR --threads T --interval I "
                         "--steps S --warmup W --block B\n"
                         "(see the header of bench/liggghts/tool_side_by_side.cpp)\n");
    return 2;
  }
  const std::string cmd = argv[1];
  std::map<std::string, std::string> opt{{"--bed", "results/bench_lammps/bed_150000"},
                                         {"--dir", "results/bench_liggghts"},
                                         {"--threads", "1"}, {"--interval", "0"},
                                         {"--steps", "1000"}, {"--warmup", "100"},
                                         {"--block", "100"}, {"--shift", "0"}};
  if (!bench::parse_options(argc, argv, 2, "dem_tool_side_by_side", opt)) return 2;
  try {
    if (cmd == "prepare") {
      prepare(opt["--bed"], opt["--dir"]);
      return 0;
    }
    if (cmd == "run")
      return run(opt["--dir"], std::stoi(opt["--threads"]), std::stoi(opt["--interval"]),
                 std::stoi(opt["--steps"]), std::stoi(opt["--warmup"]),
                 std::stoi(opt["--block"]), std::stod(opt["--shift"]));
    std::fprintf(stderr, "dem_tool_side_by_side: unknown command %s\n", cmd.c_str());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dem_tool_side_by_side: %s\n", e.what());
    return 1;
  }
}
