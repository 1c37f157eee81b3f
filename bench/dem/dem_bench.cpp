// Throughput benchmark (not a test): particle-steps per second on a settled bed at several
// sizes, thread counts and broad-phase intervals. Scene parameters follow the LAMMPS anchor
// in facts.md: monodisperse r = 5 mm, k = 2e5 N/m, e = 0.3, mu = 0.5, dt = 1e-5 s, skin 0.5 r.
//
//   dem_bench [--sizes 10000,50000,150000] [--threads 1,2] [--intervals 1,5] [--steps 200]
//             [--cache DIR]
//
// Settled beds are cached as checkpoints in DIR (default results/bench_dem) so later runs
// skip the settling.
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "cosim/stopwatch.hpp"
#include "../common/tiled_bed.hpp"
#include "dem/bed.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/stability.hpp"

namespace {

// The engine's performance options, filled once from the environment as dem_run does
// (DEM_PAIR_KERNEL, DEM_PAIR_CHUNKS; a bad value stops the bench).
const dem::EngineOptions& bench_engine_options() {
  static const dem::EngineOptions options = dem::EngineOptions::from_environment();
  return options;
}

constexpr double kR = 0.005;

using bench::kTile;  // larger beds are tiles of the settled 10k bed (bench/common/tiled_bed.hpp)
double tile_side() { return bench::tile_side(kR); }

dem::Scene bench_scene(long n, int threads, int interval) {
  dem::Scene s;
  dem::Species sp;
  sp.name = "grain";
  sp.density = 2500;
  sp.radius.min = sp.radius.max = kR;
  s.species.push_back(sp);
  dem::ContactLaw law;
  law.stiffness_per_length = false;
  law.normal_stiffness = 2e5;
  law.restitution = 0.3;
  law.tangential_stiffness_ratio = 2.0 / 7.0;  // LAMMPS gran/hooke/history: kt = 2/7 kn
  law.tangential_damping_ratio = 0.5;          // LAMMPS default gamma_t = gamma_n / 2
  law.friction = 0.5;
  dem::finalize(law, "bench");
  s.particle_particle = s.particle_wall = law;
  s.dt = 1e-5;
  s.skin = 0.5;
  s.threads = threads;
  s.broad_phase_interval = interval;
  s.stability.min_steps_per_contact = 15;
  const auto [tx, ty] = bench::tiling(n);
  const double sx = tx * tile_side(), sy = ty * tile_side();
  s.walls = {{"floor", {0, 0, 0}, {0, 0, 1}},
             {"x0", {0, 0, 0}, {1, 0, 0}},
             {"x1", {sx, 0, 0}, {-1, 0, 0}},
             {"y0", {0, 0, 0}, {0, 1, 0}},
             {"y1", {0, sy, 0}, {0, -1, 0}}};
  return s;
}

dem::State settled_bed(long n, const std::string& cache) {
  const std::string file = cache + "/bed_" + std::to_string(n) + ".h5";
  if (std::filesystem::exists(file)) return dem::load_checkpoint(file);
  dem::Scene scene = bench_scene(n, omp_get_max_threads(), 5);
  // Settle without friction: with friction and no rotation, spheres that land on each other
  // stay stacked in columns (2 contacts each); frictionless they pack densely.
  scene.particle_particle.friction = scene.particle_wall.friction = 0;
  dem::State st;
  double max_time = 0.4;
  if (n > kTile && n % kTile == 0) {
    // Copies of the settled 10k bed side by side; the seams relax below.
    st = bench::tiled_bed(settled_bed(kTile, cache), n, kR);
    max_time = 0.05;
  } else {
    dem::FillRegion r;
    r.min = {0, 0, 0};
    r.max = {scene.walls[2].point.x, scene.walls[4].point.y, 10.0};
    r.count = n;
    r.seed = 42;
    dem::fill_region(scene, r, st);
  }
  dem::Engine engine(scene, bench_engine_options());
  std::fprintf(stderr, "settling %ld particles (cached in %s) ...\n", n, file.c_str());
  const auto res = dem::settle(engine, st, 1e-7, max_time, [&](const dem::SettleResult& p) {
    if (st.step % 5000 == 0)
      std::fprintf(stderr, "  t = %.3f s  KE/particle %.3g J\n", p.time, p.ke_per_particle);
  });
  std::fprintf(stderr, "  settled: %.3f s, KE/particle %.3g J\n", res.time, res.ke_per_particle);
  std::filesystem::create_directories(cache);
  dem::save_checkpoint(st, file);
  return st;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<long> sizes{10000, 50000, 150000};
  std::vector<int> thread_counts{1, 2}, intervals{1, 5};
  auto parse_ints = [](const char* text) {
    std::vector<int> out;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(std::stoi(item));
    return out;
  };
  int steps = 200;
  std::string cache = "results/bench_dem";
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--sizes" && a + 1 < argc) {
      sizes.clear();
      std::stringstream ss(argv[++a]);
      std::string item;
      while (std::getline(ss, item, ',')) sizes.push_back(std::stol(item));
    } else if (arg == "--threads" && a + 1 < argc) {
      thread_counts = parse_ints(argv[++a]);
    } else if (arg == "--intervals" && a + 1 < argc) {
      intervals = parse_ints(argv[++a]);
    } else if (arg == "--steps" && a + 1 < argc) {
      steps = std::stoi(argv[++a]);
    } else if (arg == "--cache" && a + 1 < argc) {
      cache = argv[++a];
    } else {
      std::fprintf(stderr, "usage: dem_bench [--sizes 10000,50000,150000] [--threads 1,2] "
                           "[--intervals 1,5] [--steps 200] [--cache DIR]\n");
      return 2;
    }
  }
  std::printf("%10s %8s %9s %14s %12s %10s %8s   wall ns per particle-step:\n", "particles",
              "threads", "interval", "part-steps/s", "core-ns/p-s", "contacts", "early");
  std::printf("%76s broad  pair  wall  integ\n", "");
  for (long n : sizes) {
    const dem::State bed = settled_bed(n, cache);
    for (int interval : intervals)
      for (int threads : thread_counts) {
        dem::Scene scene = bench_scene(n, threads, interval);
        dem::State st = bed;
        st.lists_valid = false;  // lists are rebuilt for this thread count
        dem::Engine engine(scene, bench_engine_options());
        for (int k = 0; k < 20; ++k) engine.step(st);  // warm-up: lists, caches, buffers
        const long long early0 = st.early_rebuilds;
        engine.timing().reset();
        const cosim::Stopwatch watch;
        for (int k = 0; k < steps; ++k) engine.step(st);
        const double wall = watch.seconds();
        const double rate = static_cast<double>(n) * steps / wall;
        const dem::Timing& t = engine.timing();
        const double per = 1e9 / (static_cast<double>(n) * steps);  // ns per particle-step
        std::printf("%10ld %8d %9d %14.4g %12.1f %10zu %8lld   %5.1f %5.1f %5.1f %5.1f\n", n,
                    threads, interval, rate, 1e9 * threads / rate,
                    engine.particle_contacts(st).size(),
                    static_cast<long long>(st.early_rebuilds - early0), t.seconds(dem::section::broad_phase) * per,
                    t.seconds(dem::section::pair_forces) * per,
                    t.seconds(dem::section::mesh_contacts) * per,
                    t.seconds(dem::section::integration) * per);
        std::fflush(stdout);
      }
  }
  return 0;
}
