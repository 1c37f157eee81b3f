#include "dem/service.hpp"

#include <cmath>
#include <filesystem>
#include <cstdio>
#include <exception>
#include <iostream>
#include <sstream>

#include "cosim/yaml_config.hpp"
#include "dem/checkpoint.hpp"
#include "dem/coupling.hpp"
#include "dem/stability.hpp"

namespace dem {

namespace cfg = cosim::config;
using cosim::Duration;
using cosim::TimePoint;

namespace {

// An output interval: zero for none, else at least one inner step.
Duration every(double seconds, const std::string& key, Duration inner) {
  if (seconds <= 0) return Duration::zero();
  const Duration t = cosim::seconds_to_duration(seconds, key);
  return std::max(t, inner);
}

}  // namespace

ServiceOptions read_service_options(YAML::Node& root) {
  ServiceOptions o;
  const YAML::Node n = root["service"];
  if (n) {
    cfg::check_keys(n, "service", {"snapshot", "checkpoint_every", "checkpoint", "report_every"});
    o.snapshot = cfg::get_bool_or(n, "service", "snapshot", o.snapshot);
    o.checkpoint_every = cfg::get_double_or(n, "service", "checkpoint_every", o.checkpoint_every);
    if (!(o.checkpoint_every >= 0))
      throw cfg::ConfigError("service.checkpoint_every: must be >= 0 s (0 = no checkpoints)");
    o.checkpoint = cfg::get_string_or(n, "service", "checkpoint", o.checkpoint);
    if (o.checkpoint_every > 0 && o.checkpoint.empty())
      throw cfg::ConfigError("service.checkpoint: missing; checkpoint_every needs a file to write");
    o.report_every = cfg::get_positive_or(n, "service", "report_every", o.report_every);
    root.remove("service");
  }
  if (const YAML::Node st = root["settle"]) {
    throw cfg::ConfigError(
        "settle: dem_service does not settle beds (the master would time out waiting); settle "
        "with dem_run and load the result with particles.checkpoint");
  }
  if (root["prepare"])
    throw cfg::ConfigError(
        "prepare: dem_service does not prepare beds (the master would time out waiting); prepare "
        "with dem_run (prepare.checkpoint) and load the result with particles.checkpoint");
  return o;
}

ToolPose tool_pose_from(const cosim::Kinematics& k) {
  ToolPose p = to_tool_pose(k);
  p.orientation = normalized(p.orientation);
  return p;
}

ServiceModel::ServiceModel(YAML::Node root, std::string base_dir, std::string config_path,
                           const EngineOptions& engine)
    : root_(YAML::Clone(root)),
      base_dir_(std::move(base_dir)),
      config_path_(std::move(config_path)),
      engine_options_(engine) {
  build(YAML::Clone(root_), "config", true);  // fail at start-up, not when the master connects
}

ServiceModel::~ServiceModel() = default;

void ServiceModel::build(YAML::Node root, const std::string& what, bool startup) {
  options_ = read_service_options(root);
  auto rc = std::make_unique<RunConfig>(load_config(root, base_dir_));
  if (rc->scene.tools.empty())
    throw cfg::ConfigError(what + ": tools: the scene has no tool, so nothing couples to the "
                                  "co-simulation; add a tool (docs/dem.md)");
  std::ostringstream warn;
  check_dt(rc->scene, warn);
  if (!warn.str().empty()) std::cerr << "dem_service: " << warn.str();
  validate_state(rc->scene, rc->state, !rc->continues);
  check_files(*rc, config_path_, "output.file", {{"service.checkpoint", options_.checkpoint}},
              !startup);
  inner_step_ = cosim::seconds_to_duration(rc->scene.dt, "scene.dt");
  if (std::abs(cosim::to_seconds(inner_step_) - rc->scene.dt) > 1e-12 * rc->scene.dt)
    throw cfg::ConfigError("scene.dt: " + std::to_string(rc->scene.dt) +
                           " s is not a whole number of nanoseconds; the co-simulation counts "
                           "time in ns, choose e.g. 1e-4 or 2.5e-5");
  rc_ = std::move(rc);
}

void ServiceModel::configure(const YAML::Node& parameters, const cosim::RunInfo& run) {
  // The start-up build already holds this config's scene and initial state, unless the master
  // amends it or an earlier session advanced the state: build again only then.
  if (!pristine_ || (parameters && parameters.size() > 0)) {
    YAML::Node root = YAML::Clone(root_);
    cfg::apply_overrides(root, parameters, "participants." + run.participant + ".parameters");
    build(root, "participants." + run.participant + ".parameters");
    const ThreadWaitInForce w = thread_wait_in_force();
    if (w.known && !w.from_user_environment && w.policy != rc_->scene.thread_wait)
      std::fprintf(stderr,
                   "dem_service: warning: participants.%s.parameters: scene.thread_wait '%s' "
                   "cannot take effect, the threads' wait is fixed when dem_service starts "
                   "('%s'); set it in the config file or with --set in the launch command\n",
                   run.participant.c_str(), thread_wait_name(rc_->scene.thread_wait),
                   thread_wait_name(w.policy));
  } else {
    // The config file's own paths are final: now their folders must exist.
    check_files(*rc_, config_path_, "output.file", {{"service.checkpoint", options_.checkpoint}});
  }
  check_ranks();  // the master's parameters may have changed what N > 1 refuses
  pristine_ = false;
  run_ = run;
  const Scene& scene = rc_->scene;
  // Kept aside until the ranks' start: the last session's decomposition, ended there, unhooks
  // itself from the last engine, which must still exist then.
  auto engine = std::make_unique<Engine>(scene, engine_options_.with_config(rc_->performance));
  out_.reset();
  finished_ = false;
  const OutputOptions& o = rc_->output;
  particles_every_ = every(o.particles_every, "output.particles_every", inner_step_);
  wrenches_every_ = every(o.wrenches_every, "output.wrenches_every", inner_step_);
  checkpoint_every_ = every(options_.checkpoint_every, "service.checkpoint_every", inner_step_);
  t_now_ = run.t_start;
  next_particles_ = run.t_start;
  next_checkpoint_ = run.t_start + checkpoint_every_;
  last_particles_.reset();
  steps_done_ = 0;
  snapshot_seconds_ = 0;
  asleep_steps_ = particle_steps_ = 0;
  snapshot_.reset();
  for (std::size_t m = 0; m < scene.tools.size(); ++m)
    rc_->state.tool_pose[m] = scene.tools[m].motion.evaluate(cosim::to_seconds(run.t_start));
  end_poses_ = rc_->state.tool_pose;
  // Several ranks: every rank keeps its share of the scene from here on (collective).
  if (ranks_) ranks_->start(scene, *engine, rc_->state);
  engine_ = std::move(engine);
  std::string output_file = o.file;
  if (!output_file.empty() && run.resume_steps_done > 0) {
    // The interrupted session's file keeps the steps before; this one holds the rest.
    std::filesystem::path p(output_file);
    output_file = (p.parent_path() / (p.stem().string() + "_from_step" +
                                      std::to_string(run.resume_steps_done) + p.extension().string()))
                      .string();
    std::fprintf(stderr, "dem_service: resuming after %lld steps (t = %.6g s): output goes to %s, %s is left as it was\n",
                 static_cast<long long>(run.resume_steps_done), cosim::to_seconds(run.resume_time),
                 output_file.c_str(), o.file.c_str());
  }
  // Several ranks: rank 0 writes the file; every rank takes part in its gathers.
  if (!output_file.empty() && (!ranks_ || ranks_->lead()))
    out_ = std::make_unique<RunOutput>(output_file, scene, rc_->config_text);
  session_wall_.restart();
  since_report_.restart();
  std::fprintf(stderr,
               "dem_service: %zu particles, %zu walls, %zu tools, dt %.3g s (largest safe %.3g s), "
               "%d thread(s), output %s\n",
               rc_->state.size(), scene.walls.size(), scene.tools.size(), scene.dt,
               largest_safe_dt(scene), scene.threads, o.file.empty() ? "none" : o.file.c_str());
}

cosim::Ports ServiceModel::inputs() const {
  cosim::Ports p;
  for (const Tool& t : rc_->scene.tools) p.push_back({t.name, cosim::SignalKind::Kinematics});
  return p;
}

cosim::Ports ServiceModel::outputs() const {
  cosim::Ports p;
  for (const Tool& t : rc_->scene.tools) p.push_back({t.name, cosim::SignalKind::Wrench});
  return p;
}

cosim::Signals ServiceModel::initial_outputs() {
  // No force has been evaluated before the first step: the soil's wrench starts at zero,
  // about the tool's initial reference point.
  cosim::Signals s;
  const auto& tools = rc_->scene.tools;
  for (std::size_t m = 0; m < tools.size(); ++m) {
    const Vec3 r = rc_->state.tool_pose[m].position;
    s[tools[m].name] = {cosim::SignalKind::Wrench, to_wrench(Wrench{}, r).to_value()};
  }
  return s;
}

std::vector<ToolPose> ServiceModel::tool_poses(const cosim::StepInputs& in, TimePoint t) const {
  const auto& tools = rc_->scene.tools;
  std::vector<ToolPose> poses(tools.size());
  for (std::size_t m = 0; m < tools.size(); ++m) {
    const cosim::Value v = in.at(tools[m].name, t);
    for (double x : v)
      if (!std::isfinite(x))
        throw cosim::InputError("tool '" + tools[m].name + "': its pose polynomial gives NaN or "
                                "infinity at t = " + std::to_string(cosim::to_seconds(t)) + " s");
    poses[m] = tool_pose_from(cosim::Kinematics::from_value(v));
  }
  return poses;
}

std::vector<std::vector<ToolPose>> ServiceModel::step_poses(const cosim::StepInputs& in) const {
  const std::int64_t n = in.length() / inner_step_;
  std::vector<std::vector<ToolPose>> poses;
  poses.reserve(static_cast<std::size_t>(n) + 1);
  for (std::int64_t k = 0; k < n; ++k) poses.push_back(tool_poses(in, in.t_start() + k * inner_step_));
  poses.push_back(tool_poses(in, in.t_end()));
  return poses;
}

void ServiceModel::set_ranks(RankDriver* ranks) {
  ranks_ = ranks && ranks->ranks() > 1 ? ranks : nullptr;
  check_ranks();
}

void ServiceModel::check_ranks() const {
  if (!ranks_) return;
  ranks_->check_supported(*rc_, engine_options_.with_config(rc_->performance));
  // output.file, output.checkpoint, service.checkpoint_every and the master's checkpoints run
  // on several ranks: rank 0 writes what the ranks' gathers collect (docs/mpi.md).
}

void ServiceModel::save_snapshot() {
  const cosim::Stopwatch watch;
  if (out_) out_->flush_if_older_than(2.0);  // the previous step is accepted: its rows may go
  snapshot_ = rc_->state;  // copy-assignment reuses the snapshot's capacity
  if (ranks_) ranks_->save_snapshot();
  snapshot_rows_ = out_ ? out_->buffered_rows() : 0;
  snapshot_seconds_ += watch.seconds();
}

void ServiceModel::skip_snapshot() {
  const cosim::Stopwatch watch;
  if (out_) out_->flush_if_older_than(2.0);  // the previous step is accepted: its rows may go
  snapshot_.reset();  // of an earlier step's start: never to be restored now
  // No copy: the table's "snapshot" row holds copies only; the flush is output.
  if (engine_) engine_->timing().add(section::output, watch.seconds());
}

void ServiceModel::restore_snapshot() {
  if (!snapshot_) throw std::logic_error("dem_service: restore_snapshot without a snapshot");
  const cosim::Stopwatch watch;
  rc_->state = *snapshot_;
  if (ranks_) ranks_->restore_snapshot();
  if (out_) out_->discard_rows_after(snapshot_rows_);  // samples of the abandoned attempt
  snapshot_seconds_ += watch.seconds();
}

void ServiceModel::save_checkpoint(const std::string& path) {
  const cosim::Stopwatch w;
  if (out_) out_->flush_if_older_than(2.0);  // the step is accepted: its rows may go
  if (ranks_) {
    // Several ranks (collective): rank 0 writes the whole scene gathered with its springs.
    const State whole = ranks_->gather_checkpoint(rc_->state);
    if (ranks_->lead()) dem::save_checkpoint(whole, path);
  } else {
    dem::save_checkpoint(rc_->state, path);
  }
  if (engine_) engine_->timing().add(section::output, w.seconds());
}

void ServiceModel::load_checkpoint(const std::string& path) {
  State s = dem::load_checkpoint(path);
  if (s.tool_pose.size() != rc_->scene.tools.size())
    throw std::runtime_error("it holds " + std::to_string(s.tool_pose.size()) + " tool(s), the scene has " +
                             std::to_string(rc_->scene.tools.size()) + ": it is of another scene");
  validate_state(rc_->scene, s, false);
  rc_->state = std::move(s);
  end_poses_ = rc_->state.tool_pose;
  // Several ranks (collective; every rank loaded the same file): the slabs cut anew.
  if (ranks_) ranks_->start(rc_->scene, *engine_, rc_->state);
  // Outputs and reports continue from the resume time.
  t_now_ = run_.resume_time;
  auto first_at_or_after = [&](cosim::Duration every) {
    if (every <= Duration::zero()) return run_.resume_time;
    const Duration since = run_.resume_time - run_.t_start;
    return run_.t_start + every * ((since + every - cosim::nanoseconds(1)) / every);
  };
  next_particles_ = first_at_or_after(particles_every_);
  next_checkpoint_ = first_at_or_after(checkpoint_every_);
  if (next_checkpoint_ == run_.resume_time) next_checkpoint_ += checkpoint_every_;
}

void ServiceModel::recut_from_checkpoint(const std::string& path) {
  if (!ranks_) return;
  State s = dem::load_checkpoint(path);
  validate_state(rc_->scene, s, false);
  rc_->state = std::move(s);
  ranks_->recut(rc_->scene, *engine_, rc_->state);
}

cosim::StepResult ServiceModel::step(const cosim::StepInputs& in, bool want_average) {
  return step_with_poses(in.t_start(), in.t_end(), step_poses(in), want_average);
}

cosim::StepResult ServiceModel::step_with_poses(TimePoint t_start, TimePoint t_end,
                                                const std::vector<std::vector<ToolPose>>& poses,
                                                bool want_average) {
  const Scene& scene = rc_->scene;
  State& s = rc_->state;
  Engine& engine = *engine_;
  const cosim::Stopwatch wall_step;
  const Timing before = engine.timing();
  const std::int64_t early0 = s.early_rebuilds, rebuilds0 = s.rebuilds;
  const std::size_t ntools = scene.tools.size();
  // Interval sums for the average: force, and torque about each tool's reference point at the
  // step's start (each DEM step's torque is about that step's own reference point, which moves).
  std::vector<Wrench> sum(ntools);
  std::vector<Vec3> r0(ntools);
  for (std::size_t m = 0; m < ntools; ++m) r0[m] = s.tool_pose[m].position;
  std::vector<Vec3> at_force(ntools);  // the reference points of the current DEM step
  const std::int64_t n = (t_end - t_start) / inner_step_;
  if (poses.size() != static_cast<std::size_t>(n) + 1)
    throw std::logic_error("dem_service: a step's poses do not match its length");
  std::vector<Wrench> reduced;  // several ranks: the tools' wrenches summed over the ranks
  auto tool_wrenches = [&]() -> const std::vector<Wrench>& {
    if (!ranks_) return engine.tool_wrenches();
    reduced = ranks_->tool_wrenches();
    return reduced;
  };
  double max_overlap = 0, max_ratio = 0;
  // Several ranks: every rank takes part in the gathers of the output (the same decision on
  // every rank); rank 0 alone writes, and an error of its writing is raised after the step, once
  // every rank has done its collectives.
  const bool output = out_ || (ranks_ && !rc_->output.file.empty());
  std::exception_ptr write_failed;
  auto write = [&](auto&& f) {
    if (!ranks_) return f();
    if (write_failed) return;
    try {
      f();
    } catch (...) {
      write_failed = std::current_exception();
    }
  };
  // Particle snapshots only at a step's start: that state is accepted (a repeat starts from it).
  if (output && particles_every_ > Duration::zero() && t_start >= next_particles_ && t_start != last_particles_) {
    const cosim::Stopwatch w;
    // The tools where this step's inputs put them at its start (the state holds the poses of
    // the last DEM step's force time, one inner step earlier).
    if (ranks_) {
      const State whole = ranks_->gather(s);
      if (out_) write([&] { out_->snapshot(whole, cosim::to_seconds(t_start), poses.front()); });
    } else {
      out_->snapshot(s, cosim::to_seconds(t_start), poses.front());  // flushes the accepted rows too
    }
    if (out_) snapshot_rows_ = out_->buffered_rows();
    last_particles_ = t_start;
    next_particles_ += particles_every_ * ((t_start - next_particles_) / particles_every_ + 1);
    engine.timing().add(section::output, w.seconds());
  }
  for (std::int64_t k = 0; k < n; ++k) {
    const TimePoint t = t_start + k * inner_step_;
    for (std::size_t m = 0; m < ntools; ++m) s.tool_pose[m] = poses[static_cast<std::size_t>(k)][m];
    for (std::size_t m = 0; m < ntools; ++m) at_force[m] = s.tool_pose[m].position;
    if (ranks_)
      ranks_->step(s);  // the whole scene over the ranks
    else
      engine.step(s);  // forces at t with the poses at t, then positions to t + dt
    asleep_steps_ += static_cast<double>(engine.sleeping());
    particle_steps_ += static_cast<double>(s.size());
    // Several ranks: the reduction only where a sum needs it (want_average is every rank's).
    if (want_average || !ranks_) {
      const std::vector<Wrench>& tw = tool_wrenches();
      for (std::size_t m = 0; m < ntools; ++m) {
        const Wrench& w = tw[m];
        sum[m].force += w.force;
        sum[m].torque += w.torque + cross(at_force[m] - r0[m], w.force);
      }
    }
    const ContactStats& c = engine.contact_stats();
    max_overlap = std::max(max_overlap, c.max_overlap);
    max_ratio = std::max(max_ratio, c.max_overlap_ratio);
    if (output && wrenches_every_ > Duration::zero() &&
        (t - run_.t_start) % wrenches_every_ == Duration::zero()) {
      const cosim::Stopwatch w;
      if (ranks_) {
        if (!want_average) tool_wrenches();  // else summed above for this DEM step
        const std::vector<Vec3> walls = ranks_->wall_forces();
        if (out_) write([&] { out_->sample_wrenches(s, reduced, walls, cosim::to_seconds(t)); });
      } else {
        out_->sample_wrenches(s, engine, cosim::to_seconds(t));
      }
      engine.timing().add(section::output, w.seconds());
    }
  }
  t_now_ = t_end;
  end_poses_ = poses.back();  // for the session's last snapshot
  ++steps_done_;
  if (ranks_ && !want_average) tool_wrenches();  // the last DEM step's, summed over the ranks

  cosim::StepResult r;
  const double inv_n = 1.0 / static_cast<double>(n);
  for (std::size_t m = 0; m < ntools; ++m) {
    const cosim::Wrench w =
        to_wrench(ranks_ ? reduced[m] : engine.tool_wrenches()[m], s.tool_pose[m].position);
    r.outputs[scene.tools[m].name] = {cosim::SignalKind::Wrench, w.to_value()};
  }
  if (want_average) {
    cosim::Signals avg;
    for (std::size_t m = 0; m < ntools; ++m) {
      // Mean torque about the start point, moved to the end point like the sample's.
      const Vec3 F = inv_n * sum[m].force;
      const Wrench mean{F, inv_n * sum[m].torque - cross(s.tool_pose[m].position - r0[m], F)};
      const cosim::Wrench w = to_wrench(mean, s.tool_pose[m].position);
      avg[scene.tools[m].name] = {cosim::SignalKind::Wrench, w.to_value()};
    }
    r.average = std::move(avg);
  }
  if (checkpoint_every_ > Duration::zero() && t_now_ >= next_checkpoint_) {
    const cosim::Stopwatch w;
    if (ranks_) {
      const State whole = ranks_->gather_checkpoint(s);
      if (ranks_->lead()) write([&] { dem::save_checkpoint(whole, options_.checkpoint); });
    } else {
      dem::save_checkpoint(s, options_.checkpoint);
    }
    next_checkpoint_ += checkpoint_every_ * ((t_now_ - next_checkpoint_) / checkpoint_every_ + 1);
    engine.timing().add(section::output, w.seconds());
  }
  if (write_failed) std::rethrow_exception(write_failed);  // rank 0's, after every collective
  const ContactStats& c = engine.contact_stats();
  if (ranks_) {
    // Several ranks: the whole scene's sums; the per-contact figures and the payload are each
    // rank's own (a ghost's pairs count on two ranks) and are not reported (docs/mpi.md).
    double particles = 0, energy = 0;
    ranks_->totals(s, particles, energy);
    r.diagnostics = {
        {"kinetic_energy", energy},
        {"broad_phases", static_cast<double>(s.rebuilds - rebuilds0)},
        {"early_rebuilds", static_cast<double>(s.early_rebuilds - early0)},
        {"particles", particles},
    };
  } else {
    r.diagnostics = {
        {"particle_contacts", static_cast<double>(c.particle_contacts)},
        {"boundary_contacts", static_cast<double>(c.boundary_contacts)},
        {"kinetic_energy", kinetic_energy(s)},
        {"max_overlap", max_overlap},
        {"max_overlap_ratio", max_ratio},
        {"broad_phases", static_cast<double>(s.rebuilds - rebuilds0)},
        {"early_rebuilds", static_cast<double>(s.early_rebuilds - early0)},
        {"sleeping", static_cast<double>(engine.sleeping())},
        {"particles", static_cast<double>(s.size())},
        {"removed", static_cast<double>(s.removed_count)},
        {"removed_mass", s.removed_mass},
    };
    for (std::size_t m = 0; m < ntools; ++m)
      r.diagnostics.emplace_back("payload_" + scene.tools[m].name,
                                 payload_mass(s, scene.tools[m].mesh, s.tool_pose[m]));
  }
  for (const cosim::TimingRow& row : engine.timing().rows_since(before))
    r.diagnostics.emplace_back("seconds_" + row.section, row.seconds);
  r.diagnostics.emplace_back("seconds_step", wall_step.seconds());
  if (since_report_.seconds() >= options_.report_every) {
    since_report_.restart();
    const double sim = cosim::to_seconds(t_now_ - run_.t_start);
    const double left = cosim::to_seconds(run_.t_end - t_now_);
    const double wall = session_wall_.seconds();
    std::fprintf(stderr, "dem_service: t = %.4f s, %lld macro steps, RTF %.3g, ETA %.0f s\n",
                 cosim::to_seconds(t_now_), static_cast<long long>(steps_done_),
                 sim > 0 ? wall / sim : 0.0, sim > 0 ? left * wall / sim : 0.0);
  }
  return r;
}

void ServiceModel::finish(std::ostream& report) {
  if (finished_ || !engine_) return;
  finished_ = true;
  const State& s = rc_->state;
  const Timing& t = engine_->timing();
  const double sim = cosim::to_seconds(t_now_ - run_.t_start);
  const double wall = session_wall_.seconds();
  if (ranks_) {
    // Several ranks (collective, every rank finishes): both gathers before rank 0 writes.
    State whole, checkpoint;
    if (!rc_->output.file.empty() && t_now_ != last_particles_) whole = ranks_->gather(s);
    if (!rc_->output.checkpoint.empty()) checkpoint = ranks_->gather_checkpoint(s);
    if (out_) {
      if (t_now_ != last_particles_) out_->snapshot(whole, cosim::to_seconds(t_now_), end_poses_);
      out_->write_summary(t, s, sim);
      out_->flush();
    }
    if (!rc_->output.checkpoint.empty() && ranks_->lead())
      dem::save_checkpoint(checkpoint, rc_->output.checkpoint);
  } else {
    if (out_) {
      if (t_now_ != last_particles_) out_->snapshot(s, cosim::to_seconds(t_now_), end_poses_);
      out_->write_summary(t, s, sim);
      out_->flush();
    }
    if (!rc_->output.checkpoint.empty()) dem::save_checkpoint(s, rc_->output.checkpoint);
  }
  std::vector<cosim::TimingRow> rows = t.rows();
  rows.push_back({"snapshot", snapshot_seconds_});
  rows.push_back({"other", std::max(0.0, wall - t.sum() - snapshot_seconds_)});
  char title[200], rtf[96], phases[192];
  std::snprintf(title, sizeof title, "dem_service: %lld macro steps, %.4g s simulated, %.3f s wall, %zu particles, %d thread(s)",
                static_cast<long long>(steps_done_), sim, wall, s.size(), engine_->threads());
  std::snprintf(rtf, sizeof rtf, "Real-time factor (wall / simulated): %.3g", sim > 0 ? wall / sim : 0.0);
  std::snprintf(phases, sizeof phases,
                "Broad phases: %lld (early rebuilds by the guard: %lld; steps its far-mover "
                "check spared one: %lld)",
                static_cast<long long>(s.rebuilds), static_cast<long long>(s.early_rebuilds),
                static_cast<long long>(engine_->guard_cleared()));
  std::vector<std::string> notes{"snapshot: state copies for repeated steps; other: waiting for "
                                 "the master (bus) and the rest",
                                 rtf, phases};
  if (const std::string close = dem::close_pairs_summary(*engine_, steps_done_); !close.empty())
    notes.push_back(close);
  if (const std::string sleep = dem::sleeping_summary(
          *engine_, particle_steps_ > 0 ? asleep_steps_ / particle_steps_ : 0.0, steps_done_);
      !sleep.empty())
    notes.push_back(sleep);
  if (rc_->scene.region.enabled) {
    char line[160];
    std::snprintf(line, sizeof line, "Left the region of interest: %lld particles, %.6g kg",
                  static_cast<long long>(s.removed_count), s.removed_mass);
    notes.emplace_back(line);
  }
  cosim::print_timing_table(report, title, rows, wall, notes);
  if (out_) report << "dem_service: wrote " << rc_->output.file << " and " << out_->xdmf_path() << "\n";
}

}  // namespace dem
