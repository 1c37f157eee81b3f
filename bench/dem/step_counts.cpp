// step_counts: the work a DEM step does, counted, beside the seconds it took: steps a config
// (e.g. bench/dem/main_job.yaml from a checkpoint in the digging window) and prints, averaged
// over the steps, the pair candidates and contacts per grain, the particles with tool-mesh
// candidates, the candidate triangles per such particle, how many of those are within contact
// reach, the boundary contacts, the bucket mesh's triangle count, and the engine's seconds per
// section turned into nanoseconds per unit of work (per contact, per triangle test, per
// particle), and the threads' context switches per step (with bench/dem/omp_count.c preloaded,
// the OpenMP regions and barriers too). docs/performance.md, "The main job".
//
//   build/bin/step_counts CONFIG [--set KEY=VALUE ...] [--steps 1000]
//
// The counts are read from the State between steps (the lists the next step uses); the
// triangle distances are recomputed here with dem::closest_on_triangle, outside the timed steps.
#include <dlfcn.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "cosim/stopwatch.hpp"
#include "cosim/timer.hpp"
#include "cosim/yaml_config.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/mesh_contact.hpp"
#include "dem/stability.hpp"
#include "dem/thread_wait.hpp"

namespace {

void usage() {
  std::fprintf(stderr,
               "usage: step_counts CONFIG [--set KEY=VALUE ...] [--steps 1000]\n"
               "  Steps CONFIG and prints the work per step (contacts, candidates, triangle\n"
               "  tests) beside the engine's seconds per section.\n");
}

long parse_count(const char* text, const char* what) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || v < 1) {
    std::fprintf(stderr, "step_counts: %s must be a whole number >= 1 (got '%s')\n", what, text);
    std::exit(2);
  }
  return v;
}

double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// The process's context switches so far (every thread's): voluntary ones are a thread going to
// sleep (an idle OpenMP thread at a barrier or between regions with OMP_WAIT_POLICY=PASSIVE).
struct Switches {
  double voluntary = 0, involuntary = 0;
};
Switches switches() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return {static_cast<double>(u.ru_nvcsw), static_cast<double>(u.ru_nivcsw)};
}

// bench/dem/omp_count.c's counters when it is preloaded (regions, barrier calls, single calls),
// else nullptr.
using OmpCountRead = void (*)(long*, long*, long*);
OmpCountRead omp_count_reader() {
  return reinterpret_cast<OmpCountRead>(dlsym(RTLD_DEFAULT, "omp_count_read"));
}

struct Counts {
  double pair_candidates = 0, particle_contacts = 0, boundary_contacts = 0, wall_slots = 0, tool_slots = 0, slot_blocks = 0;
  double mesh_particles = 0, triangle_tests = 0, triangles_touching = 0, awake = 0;
};

// The lists as the next step will use them (after the previous step's broad phase, if any).
void count_lists(const dem::Scene& scene, const dem::State& s, Counts& c) {
  c.pair_candidates += static_cast<double>(s.pair_j.size());
  const std::size_t n = s.size();
  // The boundary contacts the last step kept, by body kind (slot keys of each particle's block).
  double blocks = 0;
  for (std::size_t i = 0; i < n && i < s.slot_count.size(); ++i) {
    if (s.slot_block[i] < 0) continue;
    blocks += 1;
    for (int q = 0; q < s.slot_count[i]; ++q) {
      const std::uint64_t key = s.slot_key[static_cast<std::size_t>(s.slot_block[i]) * dem::kBoundarySlots + q];
      (dem::key_kind(key) == dem::FeatureKind::wall ? c.wall_slots : c.tool_slots) += 1;
    }
  }
  c.slot_blocks += blocks;
  if (s.tri_offset.size() != n + 1) return;
  std::vector<std::vector<dem::Vec3>> wv(scene.tools.size());
  for (std::size_t m = 0; m < scene.tools.size(); ++m) {
    const dem::Mat3 R = dem::to_matrix(s.tool_pose[m].orientation);
    for (const dem::Vec3& v : scene.tools[m].mesh.vertices)
      wv[m].push_back(s.tool_pose[m].position + R * v);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::int32_t k0 = s.tri_offset[i], k1 = s.tri_offset[i + 1];
    if (k1 > k0) c.mesh_particles += 1;
    for (std::int32_t k = k0; k < k1; ++k) {
      const std::int32_t m = s.tri_tool[k];
      const dem::TriangleHit h =
          dem::closest_on_triangle(scene.tools[m].mesh, wv[m].data(), s.tri_index[k], s.x[i]);
      c.triangle_tests += 1;
      if (h.dist2 < s.radius[i] * s.radius[i]) c.triangles_touching += 1;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string config;
  std::vector<std::string> sets;
  long steps = 1000;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    const bool has_value = a + 1 < argc;
    if (arg == "-h" || arg == "--help") {
      usage();
      return 0;
    } else if (arg == "--set" && has_value) {
      sets.push_back(argv[++a]);
    } else if (arg == "--steps" && has_value) {
      steps = parse_count(argv[++a], "--steps");
    } else if (!arg.empty() && arg[0] == '-') {
      std::fprintf(stderr, "step_counts: unknown or incomplete option '%s'\n", arg.c_str());
      usage();
      return 2;
    } else if (config.empty()) {
      config = arg;
    } else {
      std::fprintf(stderr, "step_counts: more than one config file given ('%s')\n", arg.c_str());
      return 2;
    }
  }
  if (config.empty()) {
    usage();
    return 2;
  }
  try {
    YAML::Node root = cosim::config::load_file(config);
    for (const auto& s : sets) cosim::config::apply_override(root, s);
    dem::apply_thread_wait(dem::read_thread_wait(root), argv);
    dem::RunConfig rc = dem::load_config(root, std::filesystem::path(config).parent_path().string());
    dem::validate_state(rc.scene, rc.state, !rc.continues);
    const dem::EngineOptions options = dem::EngineOptions::from_environment();
    dem::Engine engine(rc.scene, options.with_config(rc.performance));
    dem::State& s = rc.state;
    const dem::Scene& scene = rc.scene;
    Counts c;
    const std::int64_t rebuilds0 = s.rebuilds;
    double step_seconds = 0, step_cpu = 0;
    Switches sw;
    const OmpCountRead omp_read = omp_count_reader();
    long omp_regions = 0, omp_barriers = 0, omp_singles = 0;
    for (long q = 0; q < steps; ++q) {
      for (std::size_t m = 0; m < scene.tools.size(); ++m)
        s.tool_pose[m] = scene.tools[m].motion.evaluate(s.step * scene.dt);
      const cosim::Stopwatch watch;
      const double cpu0 = cpu_seconds();
      const Switches sw0 = switches();
      long r0 = 0, b0 = 0, s0 = 0;
      if (omp_read) omp_read(&r0, &b0, &s0);
      engine.step(s);
      step_cpu += cpu_seconds() - cpu0;
      const Switches sw1 = switches();
      sw.voluntary += sw1.voluntary - sw0.voluntary;
      sw.involuntary += sw1.involuntary - sw0.involuntary;
      if (omp_read) {
        long r1 = 0, b1 = 0, s1 = 0;
        omp_read(&r1, &b1, &s1);
        omp_regions += r1 - r0;
        omp_barriers += b1 - b0;
        omp_singles += s1 - s0;
      }
      step_seconds += watch.seconds();
      const dem::ContactStats& st = engine.contact_stats();
      c.particle_contacts += static_cast<double>(st.particle_contacts);
      c.boundary_contacts += static_cast<double>(st.boundary_contacts);
      c.awake += static_cast<double>(s.size() - engine.sleeping());
      count_lists(scene, s, c);
    }
    const double n = static_cast<double>(s.size()), ns = static_cast<double>(steps);
    std::size_t triangles = 0;
    for (const auto& t : scene.tools) triangles += t.mesh.triangles.size();
    std::printf("%zu particles, %ld steps from t = %.4f s, dt %.3g s, %d thread(s); %zu tool "
                "triangles; %lld broad phases\n",
                s.size(), steps, (static_cast<double>(s.step) - ns) * scene.dt, scene.dt,
                engine.threads(), triangles, static_cast<long long>(s.rebuilds - rebuilds0));
    const double pc = c.particle_contacts / ns, cand = c.pair_candidates / ns;
    const double mp = c.mesh_particles / ns, tt = c.triangle_tests / ns, touch = c.triangles_touching / ns;
    std::printf("per step: pair candidates %.0f (%.2f per grain), particle contacts %.0f (%.2f per "
                "grain, %.1f %% of the candidates), awake %.0f\n",
                cand, 2 * cand / n, pc, 2 * pc / n, cand > 0 ? 100 * pc / cand : 0.0, c.awake / ns);
    std::printf("per step: particles with mesh candidates %.0f, candidate triangles %.0f (%.1f per "
                "such particle), within a radius %.0f (%.1f %%), boundary contacts %.0f (with "
                "walls %.0f, with tool features %.0f) of %.0f particles with a slot block\n",
                mp, tt, mp > 0 ? tt / mp : 0.0, touch, tt > 0 ? 100 * touch / tt : 0.0,
                c.boundary_contacts / ns, c.wall_slots / ns, c.tool_slots / ns, c.slot_blocks / ns);
    // A shared host stretches wall time; the unit costs are the process's CPU seconds split by
    // the sections' shares of the wall time.
    const double cpu_scale = step_seconds > 0 ? step_cpu / step_seconds : 1.0;
    std::printf("%-16s %10s %8s  %s\n", "section", "wall s", "%", "CPU ns per unit of work");
    for (const cosim::TimingRow& r : engine.timing().rows()) {
      const double per_step = r.seconds * cpu_scale / ns * 1e9;
      std::string unit;
      char buf[160];
      if (r.section == "pair_forces" && pc > 0) {
        std::snprintf(buf, sizeof buf, "%.1f per contact, %.1f per candidate", per_step / pc, per_step / cand);
        unit = buf;
      } else if (r.section == "mesh_contacts" && c.slot_blocks > 0) {
        // Walls and tool meshes: every particle with a slot block is visited.
        std::snprintf(buf, sizeof buf, "%.1f per particle with a slot block, %.1f per boundary contact",
                      per_step / (c.slot_blocks / ns), per_step / (c.boundary_contacts / ns));
        unit = buf;
      } else if (r.section == "integration") {
        std::snprintf(buf, sizeof buf, "%.2f per particle", per_step / n);
        unit = buf;
      } else if (r.section == "broad_phase") {
        std::snprintf(buf, sizeof buf, "%.2f per particle-step", per_step / n);
        unit = buf;
      }
      std::printf("%-16s %10.3f %8.2f  %s\n", r.section.c_str(), r.seconds,
                  step_seconds > 0 ? 100 * r.seconds / step_seconds : 0.0, unit.c_str());
    }
    std::printf("step: wall %.3f s, CPU %.3f s in all (%.2f cores); CPU %.1f us per step, %.1f ns "
                "per particle-step\n",
                step_seconds, step_cpu, step_seconds > 0 ? step_cpu / step_seconds : 0.0,
                step_cpu / ns * 1e6, step_cpu / ns / n * 1e9);
    std::printf("threads: %.2f voluntary and %.2f involuntary context switches per step",
                sw.voluntary / ns, sw.involuntary / ns);
    if (omp_read)
      std::printf("; %.2f parallel regions, %.2f barrier calls, %.2f single calls per step "
                  "(bench/dem/omp_count.c)",
                  static_cast<double>(omp_regions) / ns, static_cast<double>(omp_barriers) / ns,
                  static_cast<double>(omp_singles) / ns);
    std::printf("\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "step_counts: %s\n", e.what());
    return 2;
  }
  return 0;
}
