// Two variants of one DEM run (the same config with different --set overrides) stepped in one
// process, in alternating blocks of steps, each on its own copy of the state: the A/B of a
// config knob or engine option that this VM's drifting speed leaves possible (a 30-40 % swing
// between minutes hides a 5 % change between two runs; within a block pair both see the same
// machine). Prints per-variant medians of the blocks' wall times, their ratio, how often B was
// faster, each variant's seconds per section of the engine's timing table (where a difference
// lies), and whether the two final states are the same bit for bit. Not a test
// (docs/performance.md, "Close pairs").
//
//   build/bin/engine_ab CONFIG [--set KEY=VALUE ...] --a KEY=VALUE [--a ...] --b KEY=VALUE
//                       [--b ...] [--steps 1000] [--block 50]
//
// Besides config keys, --a and --b take the engine switches engine.awake_list=true|false (the
// sleepers' awake list, EngineOptions::awake_list), engine.pair_passes=auto|one|two (the pair
// stream in one pass or two, EngineOptions::pair_passes), engine.queued_rows=true|false (with two
// passes, the rows with sleeping rules queued too, EngineOptions::queued_rows) and
// engine.one_region=true|false (a step in one parallel region, EngineOptions::one_region),
// engine.pair_kernel=vector|scalar|avx2 (the pair forces' kernel, EngineOptions::pair_kernel); config
// keys include scene.thread_wait (yield: the step on the engine's own threads). Beside the wall time of the blocks, the
// process's CPU seconds (every thread's) and its voluntary context switches (threads going to
// sleep) during each variant's blocks are printed.
//
// Tools follow their motion as in dem_run; nothing is written.
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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
#include "dem/stability.hpp"
#include "dem/thread_wait.hpp"

namespace {

// The engine's performance options, filled once from the environment as dem_run does
// (DEM_PAIR_KERNEL, DEM_PAIR_CHUNKS; a bad value stops the bench).
const dem::EngineOptions& bench_engine_options() {
  static const dem::EngineOptions options = dem::EngineOptions::from_environment();
  return options;
}

void usage() {
  std::fprintf(stderr,
               "usage: engine_ab CONFIG [--set KEY=VALUE ...] --a KEY=VALUE [--a ...] --b "
               "KEY=VALUE [--b ...] [--steps 1000] [--block 50]\n"
               "  Steps the run of CONFIG twice in one process, with A's and B's overrides,\n"
               "  in alternating blocks, and prints the blocks' median times and B/A.\n");
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

long parse_count(const char* text, const char* what) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || v < 1) {
    std::fprintf(stderr, "engine_ab: %s must be a whole number >= 1 (got '%s')\n", what, text);
    std::exit(2);
  }
  return v;
}

double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double voluntary_switches() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_nvcsw);
}

struct Variant {
  std::vector<std::string> sets;
  dem::EngineOptions options;  // with the engine.* keys below
  dem::RunConfig rc;
  std::vector<double> block_seconds, block_cpu;
  double switches = 0;
};

// The engine's switches that are no config key (engine.NAME=VALUE), each setting one of
// dem::EngineOptions.
struct EngineSwitch {
  const char* text;
  void (*set)(dem::EngineOptions&);
};
using PK = dem::EngineOptions::PairKernel;
using PP = dem::EngineOptions::PairPasses;
const EngineSwitch kEngineSwitches[] = {
    {"engine.awake_list=true", [](dem::EngineOptions& o) { o.awake_list = true; }},
    {"engine.awake_list=false", [](dem::EngineOptions& o) { o.awake_list = false; }},
    {"engine.one_region=true", [](dem::EngineOptions& o) { o.one_region = true; }},
    {"engine.one_region=false", [](dem::EngineOptions& o) { o.one_region = false; }},
    {"engine.queued_rows=true", [](dem::EngineOptions& o) { o.queued_rows = true; }},
    {"engine.queued_rows=false", [](dem::EngineOptions& o) { o.queued_rows = false; }},
    {"engine.pair_kernel=vector", [](dem::EngineOptions& o) { o.pair_kernel = PK::vector; }},
    {"engine.pair_kernel=scalar", [](dem::EngineOptions& o) { o.pair_kernel = PK::scalar; }},
    {"engine.pair_kernel=avx2", [](dem::EngineOptions& o) { o.pair_kernel = PK::avx2; }},
    {"engine.pair_passes=auto", [](dem::EngineOptions& o) { o.pair_passes = PP::automatic; }},
    {"engine.pair_passes=one", [](dem::EngineOptions& o) { o.pair_passes = PP::one; }},
    {"engine.pair_passes=two", [](dem::EngineOptions& o) { o.pair_passes = PP::two; }},
    {"engine.vector_triangle_test=true",
     [](dem::EngineOptions& o) { o.vector_triangle_test = true; }},
    {"engine.vector_triangle_test=false",
     [](dem::EngineOptions& o) { o.vector_triangle_test = false; }},
};

// Sets the switch `s` names; false if it names none.
bool apply_engine_switch(const std::string& s, dem::EngineOptions& o) {
  for (const EngineSwitch& e : kEngineSwitches)
    if (s == e.text) {
      e.set(o);
      return true;
    }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  std::string config;
  std::vector<std::string> common;
  Variant v[2];
  long steps = 1000, block = 50;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    const bool has_value = a + 1 < argc;
    if (arg == "-h" || arg == "--help") {
      usage();
      return 0;
    } else if (arg == "--set" && has_value) {
      common.push_back(argv[++a]);
    } else if (arg == "--a" && has_value) {
      v[0].sets.push_back(argv[++a]);
    } else if (arg == "--b" && has_value) {
      v[1].sets.push_back(argv[++a]);
    } else if (arg == "--steps" && has_value) {
      steps = parse_count(argv[++a], "--steps");
    } else if (arg == "--block" && has_value) {
      block = parse_count(argv[++a], "--block");
    } else if (!arg.empty() && arg[0] == '-') {
      std::fprintf(stderr, "engine_ab: unknown or incomplete option '%s'\n", arg.c_str());
      usage();
      return 2;
    } else if (config.empty()) {
      config = arg;
    } else {
      std::fprintf(stderr, "engine_ab: more than one config file given ('%s')\n", arg.c_str());
      return 2;
    }
  }
  if (config.empty() || (v[0].sets.empty() && v[1].sets.empty())) {
    usage();
    return 2;
  }
  try {
    const std::string base = std::filesystem::path(config).parent_path().string();
    for (Variant& x : v) {
      YAML::Node root = cosim::config::load_file(config);
      x.options = bench_engine_options();
      for (const auto& s : common) cosim::config::apply_override(root, s);
      for (const auto& s : x.sets) {
        if (s.rfind("engine.", 0) == 0) {
          if (apply_engine_switch(s, x.options)) continue;
          std::string known;
          for (const EngineSwitch& e : kEngineSwitches)
            known += std::string(known.empty() ? "" : ", ") + e.text;
          std::fprintf(stderr, "engine_ab: unknown engine switch '%s' (known: %s)\n", s.c_str(),
                       known.c_str());
          return 2;
        }
        cosim::config::apply_override(root, s);
      }
      if (&x == &v[0]) dem::apply_thread_wait(dem::read_thread_wait(root), argv);
      x.rc = dem::load_config(root, base);
      dem::validate_state(x.rc.scene, x.rc.state, !x.rc.continues);
    }
    if (v[0].rc.state.size() != v[1].rc.state.size()) {
      std::fprintf(stderr, "engine_ab: A and B start from different particle sets (%zu and %zu)\n",
                   v[0].rc.state.size(), v[1].rc.state.size());
      return 2;
    }
    dem::Engine engine_a(v[0].rc.scene, v[0].options.with_config(v[0].rc.performance)),
        engine_b(v[1].rc.scene, v[1].options.with_config(v[1].rc.performance));
    dem::Engine* engines[2] = {&engine_a, &engine_b};
    int b_faster = 0, blocks = 0;
    for (long done = 0; done < steps; done += block, ++blocks) {
      const long n = std::min(block, steps - done);
      for (int k = 0; k < 2; ++k) {
        dem::State& s = v[k].rc.state;
        const dem::Scene& scene = v[k].rc.scene;
        const cosim::Stopwatch watch;
        const double cpu0 = cpu_seconds(), sw0 = voluntary_switches();
        for (long q = 0; q < n; ++q) {
          for (std::size_t m = 0; m < scene.tools.size(); ++m)
            s.tool_pose[m] = scene.tools[m].motion.evaluate(s.step * scene.dt);
          engines[k]->step(s);
        }
        v[k].block_seconds.push_back(watch.seconds());
        v[k].block_cpu.push_back(cpu_seconds() - cpu0);
        v[k].switches += voluntary_switches() - sw0;
      }
      b_faster += v[1].block_seconds.back() < v[0].block_seconds.back();
      if ((blocks + 1) % 10 == 0)
        std::fprintf(stderr, "engine_ab: %ld of %ld steps\n", done + n, steps);
    }
    double total[2] = {0, 0}, cpu[2] = {0, 0};
    for (int k = 0; k < 2; ++k) {
      for (double t : v[k].block_seconds) total[k] += t;
      for (double t : v[k].block_cpu) cpu[k] += t;
    }
    const double ma = median(v[0].block_seconds), mb = median(v[1].block_seconds);
    std::printf("%zu particles, %ld steps in blocks of %ld, %d thread(s)\n",
                v[0].rc.state.size(), steps, block, engine_a.threads());
    for (int k = 0; k < 2; ++k) {
      std::string s;
      for (const auto& x : v[k].sets) s += " " + x;
      std::printf("%c:%s\n   median block %.4f s, total %.3f s; CPU median block %.4f s, total "
                  "%.3f s (%.1f us per step); %.2f voluntary context switches per step\n",
                  k ? 'B' : 'A', s.empty() ? " (no overrides)" : s.c_str(), k ? mb : ma,
                  total[k], median(v[k].block_cpu), cpu[k], 1e6 * cpu[k] / static_cast<double>(steps),
                  v[k].switches / static_cast<double>(steps));
    }
    // Seconds per section, A then B (both timers ran over the same alternating blocks).
    const std::vector<cosim::TimingRow> ra = engine_a.timing().rows(), rb = engine_b.timing().rows();
    std::printf("   %-16s %9s %9s %7s\n", "section", "A [s]", "B [s]", "B/A");
    for (std::size_t r = 0; r < ra.size() && r < rb.size(); ++r)
      std::printf("   %-16s %9.3f %9.3f %7.3f\n", ra[r].section.c_str(), ra[r].seconds,
                  rb[r].seconds, ra[r].seconds > 0 ? rb[r].seconds / ra[r].seconds : 0.0);
    std::printf("B/A %.3f (medians), %.3f (totals); B faster in %d of %d blocks\n",
                ma > 0 ? mb / ma : 0.0, total[0] > 0 ? total[1] / total[0] : 0.0, b_faster,
                blocks);
    const double ca = median(v[0].block_cpu), cb = median(v[1].block_cpu);
    std::printf("CPU B/A %.3f (medians), %.3f (totals)\n", ca > 0 ? cb / ca : 0.0,
                cpu[0] > 0 ? cpu[1] / cpu[0] : 0.0);
    const std::string diff = dem::differing_arrays(v[0].rc.state, v[1].rc.state);
    std::printf("final states: %s\n", diff.empty() ? "identical" : ("differ in" + diff).c_str());
    if (const std::string c = dem::close_pairs_summary(engine_b, steps); !c.empty())
      std::printf("B: %s\n", c.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "engine_ab: %s\n", e.what());
    return 2;
  }
  return 0;
}
