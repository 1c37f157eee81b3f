// dem_run CONFIG.yaml [--set dotted.key=value ...] [--output FILE.h5]
// Standalone DEM run: optional settling, prescribed tool motion, HDF5 + XDMF output, and a
// LAMMPS-style timing table at the end. Under `mpirun -np N` (N > 1) the scene is decomposed
// over the ranks (dem/mpi/decomposed.hpp, docs/mpi.md); one rank is the program as without mpirun.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cosim/resources.hpp"
#include "cosim/stopwatch.hpp"
#include "cosim/timer.hpp"
#include "cosim/yaml_config.hpp"
#include "dem/app_main.hpp"
#include "dem/bed.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/mpi/decomposed.hpp"
#include "dem/output.hpp"
#include "dem/packing.hpp"
#include "dem/stability.hpp"
#include "dem/thread_wait.hpp"

namespace {

void usage() {
  std::cerr << "usage: dem_run CONFIG.yaml [--set dotted.key=value ...] [--output FILE.h5]\n"
               "  Runs the DEM scene of CONFIG.yaml; see docs/dem.md for the schema.\n";
}

void set_tool_poses(const dem::Scene& scene, dem::State& s) {
  for (std::size_t m = 0; m < scene.tools.size(); ++m)
    s.tool_pose[m] = scene.tools[m].motion.evaluate(s.step * scene.dt);
}

// The tools where they are at the state's time (s.tool_pose holds them at the last step's force
// time, one step earlier): what a particle snapshot shows.
std::vector<dem::ToolPose> poses_now(const dem::Scene& scene, const dem::State& s) {
  std::vector<dem::ToolPose> p(scene.tools.size());
  for (std::size_t m = 0; m < scene.tools.size(); ++m)
    p[m] = scene.tools[m].motion.evaluate(s.step * scene.dt);
  return p;
}

// Where the particles are: the box around the centres (the front of a pile is its smallest x).
std::string extent(const dem::State& s) {
  if (s.x.empty()) return "no particles";
  dem::Vec3 lo = s.x[0], hi = s.x[0];
  for (const dem::Vec3& x : s.x) {
    lo = {std::min(lo.x, x.x), std::min(lo.y, x.y), std::min(lo.z, x.z)};
    hi = {std::max(hi.x, x.x), std::max(hi.y, x.y), std::max(hi.z, x.z)};
  }
  char buf[160];
  std::snprintf(buf, sizeof buf, "centres x [%.3f, %.3f] y [%.3f, %.3f] z [%.3f, %.3f] m", lo.x,
                hi.x, lo.y, hi.y, lo.z, hi.z);
  return buf;
}

// The run's length in steps and the output's cadences in steps (particle frames: 0 = none).
struct Cadence {
  long long steps, wrench_every, snap_every;
};
Cadence cadence(const dem::RunConfig& rc, const dem::Scene& scene) {
  const long long snap_every =
      rc.output.particles_every > 0 ? std::max(1LL, std::llround(rc.output.particles_every / scene.dt))
                                    : 0;
  return {std::llround(rc.duration / scene.dt),
          std::max(1LL, std::llround(rc.output.wrenches_every / scene.dt)), snap_every};
}

// Per thread, the seconds each of the three parallel sections kept it working, and the share
// of the cores the section used (sum of the busy times over threads x its wall time): where a
// share is well below 1 the work was not split evenly, or the machine took a core away.
std::string threads_busy_summary(const dem::Engine& engine) {
  const int T = engine.threads();
  if (T < 2) return "";
  std::string line = "Threads busy [s] (share of the cores):";
  const char* sep = " ";
  for (const std::size_t sec : {dem::section::pair_forces, dem::section::mesh_contacts,
                                dem::section::integration}) {
    const double wall = engine.timing().seconds(sec);
    double sum = 0;
    line += sep + engine.timing().name(sec) + " ";
    for (int t = 0; t < T; ++t) {
      const double b = engine.thread_busy(sec, t);
      sum += b;
      char v[32];
      std::snprintf(v, sizeof v, "%s%.2f", t ? " / " : "", b);
      line += v;
    }
    char share[32];
    std::snprintf(share, sizeof share, " (%.2f)", wall > 0 ? sum / (T * wall) : 0.0);
    line += share;
    sep = ", ";
  }
  return line;
}

void print_timing(const dem::Engine& engine, const dem::State& s, double sim_time, long long steps,
                  double wall, long long rebuilds, long long early, double asleep_share) {
  if (steps == 0) {
    // A settle-only run (run.duration 0, e.g. a pile preparation): a table of zeros and a
    // "real-time factor 0" would read as a measurement.
    std::printf("\nNo run steps (run.duration is 0): no loop timing. Memory: %.0f B per particle "
                "in State, peak resident %.0f MB\n",
                static_cast<double>(dem::bytes(s)) / std::max<double>(1.0, s.size()),
                static_cast<double>(cosim::peak_resident_bytes()) / 1e6);
    return;
  }
  std::vector<cosim::TimingRow> rows = engine.timing().rows();
  rows.push_back({"other", std::max(0.0, wall - engine.timing().sum())});
  char title[160], rtf[96], rate[96], phases[192];
  std::snprintf(title, sizeof title, "Loop time of %.3f s for %lld steps with %zu particles on %d thread(s)",
                wall, steps, s.size(), engine.threads());
  std::snprintf(rtf, sizeof rtf, "Real-time factor (wall / simulated): %.3g",
                sim_time > 0 ? wall / sim_time : 0.0);
  std::snprintf(rate, sizeof rate, "Particle-steps/s: %.4g",
                wall > 0 ? static_cast<double>(s.size()) * steps / wall : 0.0);
  std::snprintf(phases, sizeof phases,
                "Broad phases: %lld (early rebuilds by the guard: %lld; steps its far-mover "
                "check spared one: %lld)",
                rebuilds, early, static_cast<long long>(engine.guard_cleared()));
  char memory[160];
  const double n = std::max<double>(1.0, static_cast<double>(s.size()));
  std::snprintf(memory, sizeof memory,
                "Memory: %.0f B per particle in State, %.0f B in workspace; peak resident %.0f MB",
                static_cast<double>(dem::bytes(s)) / n,
                static_cast<double>(engine.workspace_bytes()) / n,
                static_cast<double>(cosim::peak_resident_bytes()) / 1e6);
  std::vector<std::string> notes{rtf, rate, phases, memory};
  const dem::Scene& scene = engine.scene();
  if (const std::string close = dem::close_pairs_summary(engine, steps); !close.empty())
    notes.push_back(close);
  if (const std::string busy = threads_busy_summary(engine); !busy.empty()) notes.push_back(busy);
  if (const std::string sleep = dem::sleeping_summary(engine, asleep_share, steps); !sleep.empty())
    notes.push_back(sleep);
  if (scene.region.enabled) {
    char line[160];
    std::snprintf(line, sizeof line, "Left the region of interest: %lld particles, %.6g kg",
                  static_cast<long long>(s.removed_count), s.removed_mass);
    notes.emplace_back(line);
  }
  cosim::print_timing_table(std::cout, title, rows, wall, notes);
  // Where broad_phase went, stage by stage (docs/performance.md).
  cosim::print_timing_table(std::cout, "Broad phase by stage", engine.broad_phase_stages().rows(),
                            wall);
}

// Stores the bed's largest overlap (so it reloads whatever the overlap tolerance) and, when the
// bed is large enough for an inner region, its packing in the checkpoint's /bed group; prints
// the packing.
void record_bed(const dem::Scene& scene, const dem::State& s, const std::string& path,
                double margin, const char* stage,
                const std::optional<dem::PackingStats>& known = std::nullopt) {
  std::optional<dem::PackingStats> p = known;
  if (!p) {
    try {
      p = dem::measure_packing(scene, s, dem::inner_region(s, margin));
    } catch (const std::invalid_argument& e) {
      std::fprintf(stderr, "%s: no packing measured: %s\n", stage, e.what());
    }
  }
  if (p) std::fprintf(stderr, "%s: %s\n", stage, dem::describe(*p).c_str());
  dem::write_bed_record(path, p ? p->max_overlap_ratio : dem::max_overlap_ratio(scene, s), p);
}

// prepare: the deposition and the freeze (docs/soil.md), then the bed's packing.
void prepare(dem::RunConfig& rc) {
  const dem::Scene& scene = rc.scene;
  dem::State& s = rc.state;
  set_tool_poses(scene, s);
  const cosim::Stopwatch wall;
  const long long every = std::max(100LL, 100 * std::llround(0.5 / scene.dt / 100));
  std::fprintf(stderr, "prepare: deposition of %zu grains with friction %g, then frozen with the "
                       "scene's laws\n", s.size(), rc.prepare.deposition_friction);
  const dem::PrepareResult r = dem::prepare_bed(
      scene, s, rc.prepare, [&](const char* stage, double t, double ke) {
        if (s.step % every == 0)
          std::fprintf(stderr, "prepare: %s t = %.3f s, KE/particle %.3g J, %s\n", stage, t, ke,
                       extent(s).c_str());
      });
  std::fprintf(stderr, "prepare: deposition %s after %.3f s, freeze %s after %.3f s (%.0f s wall), %s\n",
               r.deposition_converged ? "at rest" : "NOT at rest (prepare.max_time reached)",
               r.deposition_time, r.freeze_converged ? "at rest" : "NOT at rest (prepare.max_time reached)",
               r.freeze_time, wall.seconds(), extent(s).c_str());
  std::printf("Prepared bed: %s\n", dem::describe(r.packing).c_str());
  if (!rc.prepare.checkpoint.empty()) {
    dem::save_checkpoint(s, rc.prepare.checkpoint);
    record_bed(scene, s, rc.prepare.checkpoint, rc.prepare.margin, "prepare", r.packing);
    std::fprintf(stderr, "prepare: saved %s\n", rc.prepare.checkpoint.c_str());
  }
}

// The run on N > 1 ranks (docs/mpi.md): every rank loaded the same config; rank 0 writes the
// output (the particles gathered, the wrenches summed over the ranks in rank order) and prints.
int run_decomposed(dem::RunConfig& rc, const dem::EngineOptions& options,
                   const dem::mpi::Options& mpi_options, int rank, int ranks) {
  const bool lead = rank == 0;
  dem::Scene& scene = rc.scene;
  // The refusals first, agreed by every rank (the same config: the same answer).
  int code = 0;
  std::string refusal;
  std::unique_ptr<dem::Engine> engine;
  std::unique_ptr<dem::mpi::Decomposed> dec;
  dem::State s;
  try {
    dem::mpi::check_supported(rc, options, ranks);
    engine = std::make_unique<dem::Engine>(scene, options);
    dec = std::make_unique<dem::mpi::Decomposed>(scene, *engine, mpi_options);
    set_tool_poses(scene, rc.state);
    dec->start(rc.state, s);
  } catch (const std::invalid_argument& e) {
    code = 2;
    refusal = e.what();
  }
  if (dem::mpi::Session::max_over_ranks(code) != 0) {
    if (lead) std::cerr << "dem_run: refused: " << refusal << "\n";
    return 2;
  }
  rc.state = dem::State{};  // every rank held the whole scene until here
  if (lead)
    std::fprintf(stderr, "dem_run: %d ranks, slabs along %c; rank 0 owns %lld particles and %lld ghosts\n",
                 ranks, "xyz"[dec->axis()], static_cast<long long>(dec->halo().owned),
                 static_cast<long long>(dec->halo().ghosts));
  std::unique_ptr<dem::RunOutput> out;
  if (lead) out = std::make_unique<dem::RunOutput>(rc.output.file, scene, rc.config_text);
  const Cadence run = cadence(rc, scene);
  const long long steps = run.steps, wrench_every = run.wrench_every, snap_every = run.snap_every;
  const double t0 = s.step * scene.dt;
  const long long rebuilds0 = s.rebuilds, early0 = s.early_rebuilds;
  const cosim::Stopwatch loop;
  cosim::Stopwatch since_progress;
  cosim::Stopwatch output;
  auto snapshot = [&](double time) {
    const dem::State g = dec->gather(s);
    if (lead) out->snapshot(g, time, poses_now(scene, s));
  };
  snapshot(t0);
  engine->timing().lap(dem::section::output, output);
  std::vector<dem::Wrench> tools;
  std::vector<dem::Vec3> walls;
  for (long long k = 1; k <= steps; ++k) {
    set_tool_poses(scene, s);
    const double t_force = s.step * scene.dt;
    dec->step(s);
    output.restart();
    if (k % wrench_every == 0) {
      dec->reduce_boundary(tools, walls);
      if (lead) out->sample_wrenches(s, tools, walls, t_force);
    }
    if (snap_every && k % snap_every == 0 && k != steps) snapshot(s.step * scene.dt);
    engine->timing().lap(dem::section::output, output);
    if (lead && since_progress.seconds() >= rc.output.progress_every) {
      since_progress.restart();
      const double rate = k / loop.seconds();
      std::fprintf(stderr, "t = %.4f s  step %lld/%lld  %.0f steps/s  ETA %.0f s\n",
                   s.step * scene.dt, k, steps, rate, (steps - k) / rate);
    }
  }
  output.restart();
  snapshot(s.step * scene.dt);
  if (!rc.output.checkpoint.empty()) {
    const dem::State c = dec->gather_with_lists(s);
    if (lead) dem::save_checkpoint(c, rc.output.checkpoint);
  }
  engine->timing().lap(dem::section::output, output);
  const double wall = loop.seconds();
  const std::string halo = dec->halo_summary();
  if (!lead) return 0;
  out->write_summary(engine->timing(), s, s.step * scene.dt - t0);
  std::fprintf(stderr, "dem_run: wrote %s and %s\n", rc.output.file.c_str(),
               out->xdmf_path().c_str());
  std::printf("%s", halo.c_str());
  std::printf("Rank 0's own share below (its owned particles and ghosts):\n");
  print_timing(*engine, s, s.step * scene.dt - t0, steps, wall, s.rebuilds - rebuilds0,
               s.early_rebuilds - early0, 0.0);
  return 0;
}

int run(int argc, char** argv) {
  std::string config_path, output_override;
  std::vector<std::string> sets;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "-h" || arg == "--help") {
      usage();
      return 0;
    } else if (arg == "--set" && a + 1 < argc) {
      sets.push_back(argv[++a]);
    } else if (arg == "--output" && a + 1 < argc) {
      output_override = argv[++a];
    } else if (!arg.empty() && arg[0] == '-') {
      std::cerr << "dem_run: unknown or incomplete option '" << arg << "'\n";
      usage();
      return 2;
    } else if (config_path.empty()) {
      config_path = arg;
    } else {
      std::cerr << "dem_run: more than one config file given ('" << arg << "')\n";
      return 2;
    }
  }
  if (config_path.empty()) {
    usage();
    return 2;
  }
  YAML::Node root = cosim::config::load_file(config_path);
  for (const auto& s : sets) cosim::config::apply_override(root, s);
  // A dem_service config runs here too: its service section is dem_service's alone.
  if (root.IsMap() && root["service"]) {
    std::fprintf(stderr, "dem_run: the config's service: section is ignored (only dem_service "
                         "reads it)\n");
    root.remove("service");
  }
  // The mpi: section (docs/mpi.md), validated on any rank count; the engine's reader never sees it.
  const dem::mpi::Options mpi_options = dem::mpi::take_options(root);
  // May execute dem_run again (once) with the OpenMP wait variables set: before any output.
  const std::string wait = dem::apply_thread_wait(dem::read_thread_wait(root), argv);
  // Started by mpirun: MPI from here on (after the re-execution above). One rank runs the plain
  // program below; more run run_decomposed.
  std::optional<dem::mpi::Session> mpi;
  if (dem::mpi::launched_by_mpirun()) mpi.emplace(&argc, &argv);
  const int rank = mpi ? mpi->rank() : 0, ranks = mpi ? mpi->size() : 1;
  if (rank != 0) std::freopen("/dev/null", "w", stderr);  // rank 0 speaks for all
  // The engine's performance options, once (a bad DEM_PAIR_KERNEL stops the run before any work).
  const dem::EngineOptions engine_options = dem::EngineOptions::from_environment();
  std::fprintf(stderr, "dem_run: idle threads wait %s\n", wait.c_str());
  const std::string base = std::filesystem::path(config_path).parent_path().string();
  dem::RunConfig rc = dem::load_config(root, base);
  if (!output_override.empty()) rc.output.file = output_override;
  // Before settling or writing anything: no output onto an input or onto another output.
  dem::check_files(rc, config_path, output_override.empty() ? "output.file" : "--output");
  dem::Scene& scene = rc.scene;
  dem::State& s = rc.state;
  dem::check_dt(scene, std::cerr);
  dem::validate_state(scene, s, !rc.continues);
  std::fprintf(stderr, "dem_run: %zu particles, %zu walls, %zu tools, dt %.3g s (largest safe %.3g s)\n",
               s.size(), scene.walls.size(), scene.tools.size(), scene.dt,
               dem::largest_safe_dt(scene));
  // Where the OpenMP threads may run (their affinity masks): every core they were given.
  std::fprintf(stderr, "dem_run: %s\n",
               dem::describe_thread_cpus(dem::thread_cpus(std::max(1, scene.threads))).c_str());

  if (ranks > 1) {
    try {
      return run_decomposed(rc, engine_options.with_config(rc.performance), mpi_options, rank, ranks);
    } catch (const std::exception& e) {
      // An error on some ranks only: the others wait in a collective, so all end here.
      std::fprintf(::stdout, "dem_run: rank %d stopped: %s\n", rank, e.what());
      std::fflush(::stdout);
      dem::mpi::Session::abort(dynamic_cast<const dem::SimulationError*>(&e) ? 3 : 1);
    }
  }
  if (rc.prepare.enabled) prepare(rc);
  dem::Engine engine(scene, engine_options.with_config(rc.performance));
  if (rc.settle.enabled) {
    set_tool_poses(scene, s);
    const cosim::Stopwatch settle_wall;
    // Progress every 0.5 s simulated (at least every 100 steps, the settle check's stride).
    const long long every = std::max(100LL, 100 * std::llround(0.5 / scene.dt / 100));
    const auto r = dem::settle(engine, s, rc.settle.ke_per_particle, rc.settle.max_time,
                               [&](const dem::SettleResult& p) {
                                 if (s.step % every == 0)
                                   std::fprintf(stderr, "settle: t = %.3f s, KE/particle %.3g J, %s\n",
                                                p.time, p.ke_per_particle, extent(s).c_str());
                               });
    std::fprintf(stderr, "settle: %s after %.3f s (%.0f s wall), KE/particle %.3g J, %s\n",
                 r.converged ? "at rest" : "NOT at rest (settle.max_time reached)", r.time,
                 settle_wall.seconds(), r.ke_per_particle, extent(s).c_str());
    if (!rc.settle.checkpoint.empty()) {
      dem::save_checkpoint(s, rc.settle.checkpoint);
      record_bed(scene, s, rc.settle.checkpoint, dem::kPackingMarginDiameters, "settle");
      std::fprintf(stderr, "settle: saved %s\n", rc.settle.checkpoint.c_str());
    }
    engine.timing().reset();  // the tables below are for the run itself
    engine.reset_thread_busy();
    engine.broad_phase_stages().reset();
  }

  dem::RunOutput out(rc.output.file, scene, rc.config_text);
  const Cadence run = cadence(rc, scene);
  const long long steps = run.steps, wrench_every = run.wrench_every, snap_every = run.snap_every;
  const double t0 = s.step * scene.dt;
  const long long rebuilds0 = s.rebuilds, early0 = s.early_rebuilds;
  const cosim::Stopwatch loop;
  double asleep_steps = 0, particle_steps = 0;  // sleeping share of the run
  cosim::Stopwatch since_progress;
  cosim::Stopwatch output;
  out.snapshot(s, t0, poses_now(scene, s));
  engine.timing().lap(dem::section::output, output);
  for (long long k = 1; k <= steps; ++k) {
    set_tool_poses(scene, s);
    const double t_force = s.step * scene.dt;
    engine.step(s);
    asleep_steps += static_cast<double>(engine.sleeping());
    particle_steps += static_cast<double>(s.size());
    output.restart();
    if (k % wrench_every == 0) out.sample_wrenches(s, engine, t_force);
    if (snap_every && k % snap_every == 0 && k != steps)
      out.snapshot(s, s.step * scene.dt, poses_now(scene, s));
    engine.timing().lap(dem::section::output, output);
    if (since_progress.seconds() >= rc.output.progress_every) {
      since_progress.restart();
      const double rate = k / loop.seconds();
      if (scene.sleep.enabled || scene.region.enabled)
        std::fprintf(stderr,
                     "t = %.4f s  step %lld/%lld  %.0f steps/s  ETA %.0f s  asleep %lld/%zu  "
                     "removed %lld\n",
                     s.step * scene.dt, k, steps, rate, (steps - k) / rate,
                     static_cast<long long>(engine.sleeping()), s.size(),
                     static_cast<long long>(s.removed_count));
      else
        std::fprintf(stderr, "t = %.4f s  step %lld/%lld  %.0f steps/s  ETA %.0f s\n",
                     s.step * scene.dt, k, steps, rate, (steps - k) / rate);
    }
  }
  output.restart();
  out.snapshot(s, s.step * scene.dt, poses_now(scene, s));
  if (!rc.output.checkpoint.empty()) dem::save_checkpoint(s, rc.output.checkpoint);
  engine.timing().lap(dem::section::output, output);
  const double wall = loop.seconds();
  out.write_summary(engine.timing(), s, s.step * scene.dt - t0);
  std::fprintf(stderr, "dem_run: wrote %s and %s\n", rc.output.file.c_str(),
               out.xdmf_path().c_str());
  print_timing(engine, s, s.step * scene.dt - t0, steps, wall, s.rebuilds - rebuilds0,
               s.early_rebuilds - early0, particle_steps > 0 ? asleep_steps / particle_steps : 0.0);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return dem::app_main("dem_run", argc, argv, run); }
