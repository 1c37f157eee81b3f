// Our side of the LAMMPS side-by-side benchmark (bench/lammps/side_by_side.sh drives it; not a
// test). Four subcommands, all on the scenes of docs/performance.md:
//
//   dem_side_by_side prepare --kind bed|gas --n N --dir DIR
//       Builds the scene once and writes it for both codes: DIR/<kind>_<n>.h5 (our checkpoint:
//       positions, velocities, radii, masses, no contact history), DIR/<kind>_<n>.data (the
//       same particles as a LAMMPS `read_data` file, atom_style sphere) and DIR/<kind>_<n>.box
//       (the walls, read by the driver to write the LAMMPS input). Existing files are kept.
//   dem_side_by_side run --kind K --n N --dir DIR --threads T --interval I --steps S
//       Loads the scene, steps 20 times (lists, caches), then times S steps and prints
//       "rate <particle-steps/s> seconds <wall> rebuilds <broad phases in the timed steps>
//       threads <used> cpu_share <process CPU time / (wall * threads)>".
//       --interval 0 rebuilds only when needed (the skin guard), like LAMMPS `check yes`.
//   dem_side_by_side passes --kind K --n N --dir DIR --threads T --interval I --steps S
//       The pair stream in one pass against two (EngineOptions::pair_passes) in one process, in
//       blocks of 20 steps taken in turn; prints the times, their ratio, the blocks two passes
//       won and whether the final states are identical (exit 1 if not).
//   dem_side_by_side kernels (the same options as passes)
//       The same with the scalar pair loop against the AVX2 kernel (EngineOptions::PairKernel::
//       avx2, what the vector kernel runs all awake without AVX-512).
//   run and trace take --thread-wait passive|brief|spin|yield (default: scene.thread_wait's default),
//   applied as dem_run applies scene.thread_wait (docs/dem.md); OMP_WAIT_POLICY or
//   GOMP_SPINCOUNT in the environment win over it. --pair-kernel vector|scalar (default vector)
//   picks the pair forces' AVX-512 kernel (where the processor has it) or the scalar loop; both
//   give the same bits (dem/pair_kernel.hpp), the option is there to time one against the other.
//   dem_side_by_side trace --kind K --n N --dir DIR --threads T --interval I
//                          --duration D --every E
//       Prints "t kinetic_energy contacts_per_particle" at t = 0, E, 2E, ... D (contacts: touching
//       particle pairs, counted twice, over N, like LAMMPS compute contact/atom).
//
// Contact law on both sides: linear spring-dashpot with the dashpot given as a coefficient
// (LAMMPS gran/hooke/history: m* gamma_n), attractive part not clipped, k_T = 2/7 k_N,
// eta_T = eta_N / 2, mu = 0.5; no rotation (LAMMPS fix nve).
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "../common/anchor.hpp"
#include "../common/cli.hpp"
#include "../common/tiled_bed.hpp"
#include "cosim/resources.hpp"
#include "dem/bed.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/scene.hpp"

namespace {

// The engine's performance options (--pair-kernel), filled once in main.
dem::EngineOptions g_engine_options;

using namespace bench;  // the shared scene's parameters (bench/common/anchor.hpp)
using bench::kTile;  // beds above 10k are tiles of the settled 10k bed (bench/common/tiled_bed.hpp)
constexpr double kGasFraction = 0.1;  // solid volume fraction of the gas
constexpr double kGasSpeed = 1.0;     // m/s, standard deviation of each velocity component

// The walls of a scene: planes at the faces of [0,sx] x [0,sy] x [0,sz]; the bed has no lid
// (sz = 0 means none). gravity: -z or off.
struct Box {
  std::string kind;
  long n = 0;
  double sx = 0, sy = 0, sz = 0;
  double ztop = 0;  // LAMMPS box top (above every particle)
  bool gravity = true;
};

void write_box(const Box& b, const std::string& file) {
  std::ofstream f(file);
  f.precision(17);
  f << "kind " << b.kind << "\nn " << b.n << "\nsx " << b.sx << "\nsy " << b.sy << "\nsz "
    << b.sz << "\nztop " << b.ztop << "\ngravity " << (b.gravity ? 1 : 0) << "\nradius " << kR
    << "\ndensity " << kDensity << "\nstiffness " << kStiffness << "\ngamma_n " << gamma_n()
    << "\nfriction " << kFriction << "\ndt " << kDt << "\nskin " << kSkin * kR << "\n";
  if (!f) throw std::runtime_error("cannot write " + file);
}

Box read_box(const std::string& file) {
  std::ifstream f(file);
  if (!f) throw std::runtime_error(file + " missing: run `dem_side_by_side prepare` first");
  std::map<std::string, std::string> kv;
  std::string k, v;
  while (f >> k >> v) kv[k] = v;
  Box b;
  b.kind = kv.at("kind");
  b.n = std::stol(kv.at("n"));
  b.sx = std::stod(kv.at("sx"));
  b.sy = std::stod(kv.at("sy"));
  b.sz = std::stod(kv.at("sz"));
  b.ztop = std::stod(kv.at("ztop"));
  b.gravity = kv.at("gravity") == "1";
  return b;
}

// --close-margin: performance.close_margin of our runs (0: every candidate read, the default).
double g_close_margin = 0;
dem::ThreadWait g_thread_wait = dem::Scene{}.thread_wait;  // --thread-wait

// interval 0: rebuild only when the skin guard fires.
dem::Scene make_scene(const Box& b, int threads, int interval, bool friction = true) {
  dem::Scene s;
  s.thread_wait = g_thread_wait;  // yield: the step on the engine's own threads
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
  law.friction = friction ? kFriction : 0.0;
  dem::ContactLaw pp = law, pw = law;
  pp.normal_damping = sphere_mass() / 2 * gamma_n();  // LAMMPS: same gamma_n, m* = m/2 ...
  pw.normal_damping = sphere_mass() * gamma_n();      // ... and m* = m against a wall
  dem::finalize(pp, "side_by_side.particle_particle");
  dem::finalize(pw, "side_by_side.particle_wall");
  s.particle_particle = pp;
  s.particle_wall = pw;
  s.dt = kDt;
  s.skin = kSkin;
  g_engine_options.close_margin = g_close_margin;
  s.threads = threads;
  s.broad_phase_interval = interval > 0 ? interval : 1 << 30;
  s.guard = dem::GuardMode::rebuild;
  s.stability.min_steps_per_contact = 15;  // t_c / dt is about 19 for the pair
  s.gravity = b.gravity ? dem::Vec3{0, 0, -9.81} : dem::Vec3{0, 0, 0};
  s.walls = {{"floor", {0, 0, 0}, {0, 0, 1}},
             {"x0", {0, 0, 0}, {1, 0, 0}},
             {"x1", {b.sx, 0, 0}, {-1, 0, 0}},
             {"y0", {0, 0, 0}, {0, 1, 0}},
             {"y1", {0, b.sy, 0}, {0, -1, 0}}};
  if (b.sz > 0) s.walls.push_back({"lid", {0, 0, b.sz}, {0, 0, -1}});
  return s;
}

double tile_side() { return bench::tile_side(kR); }

// A copy with particles only (no lists, no contact history), in id order.
dem::State fresh(const dem::State& st) {
  std::vector<std::size_t> order(st.size());
  for (std::size_t i = 0; i < st.size(); ++i) order[static_cast<std::size_t>(st.id[i])] = i;
  dem::State out;
  for (std::size_t k = 0; k < order.size(); ++k) {
    const std::size_t i = order[k];
    dem::add_particle(out, st.x[i], st.v[i], st.radius[i], st.mass[i], 0,
                      static_cast<std::int64_t>(k));
  }
  return out;
}

std::string base(const std::string& dir, const std::string& kind, long n) {
  return dir + "/" + kind + "_" + std::to_string(n);
}

void settle(const Box& b, dem::State& st, double max_time) {
  // Frictionless: with friction and no rotation, landing spheres stay stacked in columns.
  const dem::Scene scene = make_scene(b, 1, 5, false);  // 1 thread: fine on a busy machine
  dem::Engine engine(scene, g_engine_options);
  std::fprintf(stderr, "settling %ld particles for up to %.2f s ...\n", b.n, max_time);
  const auto res = dem::settle(engine, st, 1e-7, max_time, [&](const dem::SettleResult& p) {
    if (st.step % 5000 == 0)
      std::fprintf(stderr, "  t = %.3f s  KE/particle %.3g J\n", p.time, p.ke_per_particle);
  });
  std::fprintf(stderr, "  settled: %.3f s, KE/particle %.3g J\n", res.time, res.ke_per_particle);
}

dem::State load(const std::string& dir, const std::string& kind, long n) {
  return dem::load_checkpoint(base(dir, kind, n) + ".h5");
}

void write_lammps_data(const Box& b, const dem::State& st, const std::string& file) {
  write_data_file(st, b.sx, b.sy, b.ztop,
                  "soilcosim side-by-side scene " + b.kind + " " + std::to_string(b.n) +
                      " (bench/lammps)",
                  DataFormat{}, file);
}

std::uint64_t splitmix(std::uint64_t& s) {
  std::uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}
double uniform(std::uint64_t& s) { return (splitmix(s) >> 11) * 0x1.0p-53; }
double gaussian(std::uint64_t& s) {
  const double u1 = 1 - uniform(s), u2 = uniform(s);
  return std::sqrt(-2 * std::log(u1)) * std::cos(2 * M_PI * u2);
}

// A dilute gas in a closed cube without gravity: particles on random sites of a cubic lattice,
// jittered, Gaussian velocities with zero mean.
dem::State make_gas(Box& b) {
  const double volume = b.n * 4.0 / 3.0 * M_PI * kR * kR * kR / kGasFraction;
  const double side = std::cbrt(volume);
  b.sx = b.sy = b.sz = b.ztop = side;
  b.gravity = false;
  long m = static_cast<long>(std::ceil(std::cbrt(static_cast<double>(b.n))));
  const double pitch = side / m;
  const double jitter = 0.5 * (pitch - 2 * kR * 1.02);
  if (jitter < 0) throw std::runtime_error("gas too dense for its lattice");
  std::uint64_t rng = 20261129;
  std::vector<long> sites(m * m * m);
  for (long i = 0; i < static_cast<long>(sites.size()); ++i) sites[i] = i;
  for (long i = static_cast<long>(sites.size()) - 1; i > 0; --i)
    std::swap(sites[i], sites[splitmix(rng) % static_cast<std::uint64_t>(i + 1)]);
  dem::State st;
  std::vector<dem::Vec3> v(b.n);
  dem::Vec3 mean{};
  for (long k = 0; k < b.n; ++k) {
    v[k] = {kGasSpeed * gaussian(rng), kGasSpeed * gaussian(rng), kGasSpeed * gaussian(rng)};
    mean = mean + v[k];
  }
  mean = (1.0 / b.n) * mean;
  for (long k = 0; k < b.n; ++k) {
    const long s = sites[k];
    const long i = s % m, j = (s / m) % m, l = s / (m * m);
    const dem::Vec3 c{(i + 0.5) * pitch, (j + 0.5) * pitch, (l + 0.5) * pitch};
    const dem::Vec3 d{jitter * (2 * uniform(rng) - 1), jitter * (2 * uniform(rng) - 1),
                      jitter * (2 * uniform(rng) - 1)};
    dem::add_particle(st, c + d, v[k] - mean, kR, sphere_mass(), 0, k);
  }
  return st;
}

void prepare(const std::string& kind, long n, const std::string& dir) {
  const std::string stem = base(dir, kind, n);
  if (std::filesystem::exists(stem + ".h5") && std::filesystem::exists(stem + ".data") &&
      std::filesystem::exists(stem + ".box"))
    return;
  std::filesystem::create_directories(dir);
  Box b;
  b.kind = kind;
  b.n = n;
  dem::State st;
  if (kind == "gas") {
    st = make_gas(b);
  } else if (kind == "bed") {
    if (n % kTile) throw std::runtime_error("bed sizes are multiples of 10000");
    const auto [tx, ty] = bench::tiling(n);
    b.sx = tx * tile_side();
    b.sy = ty * tile_side();
    b.sz = 0;
    if (n == kTile) {
      b.ztop = 10.0;
      const dem::Scene scene = make_scene(b, 1, 5);
      dem::FillRegion r;
      r.min = {0, 0, 0};
      r.max = {b.sx, b.sy, 10.0};
      r.count = n;
      r.seed = 42;
      dem::fill_region(scene, r, st);
      settle(b, st, 0.4);
    } else {
      // Copies of the settled 10k bed side by side; the seams relax briefly.
      prepare(kind, kTile, dir);
      st = bench::tiled_bed(load(dir, kind, kTile), n, kR);
      settle(b, st, 0.01);
    }
    double zmax = 0;
    for (const auto& x : st.x) zmax = std::max(zmax, x.z);
    b.ztop = zmax + 20 * kR;
  } else {
    throw std::runtime_error("--kind is bed or gas, not '" + kind + "'");
  }
  st = fresh(st);
  dem::save_checkpoint(st, stem + ".h5");
  write_lammps_data(b, st, stem + ".data");
  write_box(b, stem + ".box");  // last: its presence marks a complete scene
}


int run(const std::string& kind, long n, const std::string& dir, int threads, int interval,
        int steps) {
  const Box b = read_box(base(dir, kind, n) + ".box");
  const dem::Scene scene = make_scene(b, threads, interval);
  dem::State st = load(dir, kind, n);
  dem::Engine engine(scene, g_engine_options);
  for (int k = 0; k < 20; ++k) engine.step(st);  // warm-up, like LAMMPS `run 20` before
  const auto rebuilds0 = st.rebuilds;
  engine.timing().reset();
  engine.broad_phase_stages().reset();
  const double cpu0 = bench::cpu_seconds();
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < steps; ++k) engine.step(st);
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // Share of its cores the run got (LAMMPS prints the same as "% CPU use"): below 1 the
  // machine was busy with something else.
  const double share = (bench::cpu_seconds() - cpu0) / (wall * engine.threads());
  std::printf("rate %.6g seconds %.6g rebuilds %lld threads %d cpu_share %.3f\n",
              static_cast<double>(st.size()) * steps / wall, wall,
              static_cast<long long>(st.rebuilds - rebuilds0), engine.threads(), share);
  std::fprintf(stderr, "  memory: %.0f B per particle in State, %.0f B in workspace, peak resident %.0f MB\n",
               static_cast<double>(dem::bytes(st)) / st.size(),
               static_cast<double>(engine.workspace_bytes()) / st.size(),
               static_cast<double>(cosim::peak_resident_bytes()) / 1e6);
  // Where the time went (stderr: the driver reads only the line above), ns per particle-step.
  const double per = 1e9 / (static_cast<double>(st.size()) * steps);
  std::fprintf(stderr, "  candidates %.2f, touching %.2f particle pairs and %.3f boundary contacts per particle\n",
               static_cast<double>(st.pair_j.size()) / st.size(),
               static_cast<double>(engine.contact_stats().particle_contacts) / st.size(),
               static_cast<double>(engine.contact_stats().boundary_contacts) / st.size());
  for (const auto* t : {&engine.timing(), &engine.broad_phase_stages()})
    for (std::size_t k = 0; k < t->size(); ++k)
      std::fprintf(stderr, "  %-16s %8.1f ns per particle-step\n", t->name(k).c_str(),
                   t->seconds(k) * per);
  return 0;
}

// The pair stream in one pass against two (EngineOptions::pair_passes) in one process: two
// engines on two copies of the scene, blocks of 20 steps in turn (A B, B A, ...), so that the
// machine's drift hits both alike. Both give the same bits (checked at the end).
// kernels: the same with the scalar loop (A) against the AVX2 kernel (B, Kernel::avx2).
int passes(const std::string& kind, long n, const std::string& dir, int threads, int interval,
           int steps, bool kernels) {
  const Box b = read_box(base(dir, kind, n) + ".box");
  const dem::Scene scene = make_scene(b, threads, interval);
  dem::State st[2] = {load(dir, kind, n), load(dir, kind, n)};
  dem::EngineOptions o[2] = {g_engine_options, g_engine_options};
  if (kernels) {
    o[0].pair_kernel = dem::EngineOptions::PairKernel::scalar;
    o[1].pair_kernel = dem::EngineOptions::PairKernel::avx2;
  } else {
    o[0].pair_passes = dem::EngineOptions::PairPasses::one;
    o[1].pair_passes = dem::EngineOptions::PairPasses::two;
  }
  dem::Engine one(scene, o[0]), two(scene, o[1]);
  dem::Engine* engine[2] = {&one, &two};
  for (int v = 0; v < 2; ++v)
    for (int k = 0; k < 20; ++k) engine[v]->step(st[v]);
  constexpr int kBlock = 20;
  const int blocks = std::max(1, steps / kBlock);
  double total[2] = {0, 0};
  int two_faster = 0;
  for (int blk = 0; blk < blocks; ++blk) {
    double w[2];
    for (int q = 0; q < 2; ++q) {
      const int v = (blk % 2 == 0) ? q : 1 - q;
      const auto t0 = std::chrono::steady_clock::now();
      for (int k = 0; k < kBlock; ++k) engine[v]->step(st[v]);
      w[v] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      total[v] += w[v];
    }
    two_faster += w[1] < w[0];
  }
  const bool same = st[0].x.size() == st[1].x.size() &&
                    std::memcmp(st[0].x.data(), st[1].x.data(), st[0].x.size() * sizeof(dem::Vec3)) == 0 &&
                    std::memcmp(st[0].pair_spring.data(), st[1].pair_spring.data(),
                                st[0].pair_spring.size() * sizeof(dem::Vec3)) == 0;
  const char* a = kernels ? "scalar" : "one";
  const char* bn = kernels ? "avx2" : "two";
  std::printf("%s: %ld particles, %d threads, %d blocks of %d steps: %s %.4f s, %s %.4f s, "
              "%s/%s %.4f, %s faster in %d of %d blocks; final states %s\n",
              kernels ? "kernels" : "passes", n, threads, blocks, kBlock, a, total[0], bn,
              total[1], bn, a, total[1] / total[0], bn, two_faster, blocks,
              same ? "identical" : "DIFFER");
  return same ? 0 : 1;
}

int trace(const std::string& kind, long n, const std::string& dir, int threads, int interval,
          double duration, double every) {
  const Box b = read_box(base(dir, kind, n) + ".box");
  const dem::Scene scene = make_scene(b, threads, interval);
  dem::State st = load(dir, kind, n);
  dem::Engine engine(scene, g_engine_options);
  const long per = std::lround(every / kDt), total = std::lround(duration / kDt);
  for (long k = 0;; ++k) {
    if (k % per == 0) {
      engine.prepare(st);
      const double contacts = 2.0 * engine.particle_contacts(st).size() / st.size();
      std::printf("%.6f %.10g %.6g\n", k * kDt, dem::kinetic_energy(st), contacts);
      std::fflush(stdout);
    }
    if (k == total) break;
    engine.step(st);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: dem_side_by_side prepare|run|passes|kernels|trace --kind bed|gas --n N "
                         "--dir DIR [--threads T --interval I --steps S --duration D --every E]"
                         " [--thread-wait passive|brief|spin|yield] [--pair-kernel vector|avx2|scalar]"
                         " [--close-margin M]"
                         "\n(see the header of bench/lammps/side_by_side.cpp)\n");
    return 2;
  }
  const std::string cmd = argv[1];
  std::map<std::string, std::string> opt{{"--kind", "bed"}, {"--n", "10000"},
                                         {"--dir", "results/bench_lammps"},
                                         {"--threads", "1"}, {"--interval", "5"},
                                         {"--steps", "200"}, {"--duration", "0.1"},
                                         {"--every", "0.002"},
                                         {"--thread-wait",
                                          dem::thread_wait_name(dem::Scene{}.thread_wait)},
                                         {"--pair-kernel", "vector"},
                                         {"--close-margin", "0"}};
  if (!bench::parse_options(argc, argv, 2, "dem_side_by_side", opt)) return 2;
  try {
    const std::string kind = opt["--kind"], dir = opt["--dir"];
    const long n = std::stol(opt["--n"]);
    if (cmd == "prepare") {
      prepare(kind, n, dir);
      return 0;
    }
    g_close_margin = std::stod(opt["--close-margin"]);
    if (!(g_close_margin >= 0 && g_close_margin < kSkin)) {
      std::fprintf(stderr, "dem_side_by_side: --close-margin %s: use a fraction of r from 0 "
                   "(every candidate) to below the skin factor %g\n",
                   opt["--close-margin"].c_str(), kSkin);
      return 2;
    }
    const std::string kernel = opt["--pair-kernel"];
    if (kernel != "vector" && kernel != "scalar" && kernel != "avx2") {
      std::fprintf(stderr, "dem_side_by_side: --pair-kernel %s: use vector, avx2 or scalar\n",
                   kernel.c_str());
      return 2;
    }
    g_engine_options = dem::EngineOptions::from_environment();  // DEM_PAIR_PASSES, DEM_PAIR_CHUNKS
    g_engine_options.pair_kernel = kernel == "vector"   ? dem::EngineOptions::PairKernel::vector
                                   : kernel == "avx2" ? dem::EngineOptions::PairKernel::avx2
                                                        : dem::EngineOptions::PairKernel::scalar;
    // How idle OpenMP threads wait, as dem_run and dem_service do (scene.thread_wait; may
    // execute this program again, once, with the OpenMP wait variables set).
    YAML::Node scene_node;
    scene_node["scene"]["thread_wait"] = opt["--thread-wait"];
    g_thread_wait = dem::read_thread_wait(scene_node);
    const std::string wait = dem::apply_thread_wait(g_thread_wait, argv);
    std::fprintf(stderr, "dem_side_by_side: idle threads wait %s\n", wait.c_str());
    const int threads = std::stoi(opt["--threads"]), interval = std::stoi(opt["--interval"]);
    if (cmd == "run") return run(kind, n, dir, threads, interval, std::stoi(opt["--steps"]));
    if (cmd == "passes")
      return passes(kind, n, dir, threads, interval, std::stoi(opt["--steps"]), false);
    if (cmd == "kernels")
      return passes(kind, n, dir, threads, interval, std::stoi(opt["--steps"]), true);
    if (cmd == "trace")
      return trace(kind, n, dir, threads, interval, std::stod(opt["--duration"]),
                   std::stod(opt["--every"]));
    std::fprintf(stderr, "dem_side_by_side: unknown command %s\n", cmd.c_str());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dem_side_by_side: %s\n", e.what());
    return 1;
  }
}
