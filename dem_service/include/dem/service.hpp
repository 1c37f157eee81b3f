// The DEM as a co-simulation participant (a cosim::Model): one kinematic input and one wrench
// output per tool, macro steps run as whole numbers of DEM steps with the tool poses taken from
// the master's input polynomials at every inner step, an in-memory snapshot for repeated steps,
// and the service's own HDF5/XDMF output. The engine itself knows nothing of the bus.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cosim/participant.hpp"
#include "cosim/stopwatch.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/output.hpp"

namespace dem {

// The `service` section of the DEM config (docs/dem_service.md).
struct ServiceOptions {
  bool snapshot = true;         // copy the State at each macro step start (repeatable steps)
  double checkpoint_every = 0;  // s of co-simulation time between HDF5 checkpoints; 0 = none
  std::string checkpoint;       // checkpoint file (overwritten each time); "" = none
  double report_every = 10;     // wall-clock seconds between progress lines on stderr
};

// Reads and removes the `service` section of a DEM config (absent keys keep the initialisers
// above, the one place the defaults are written; docs/dem_service.md lists them and a test
// compares); refuses a `settle` section. Raises config::ConfigError.
ServiceOptions read_service_options(YAML::Node& root);

// The scene on several MPI ranks (dem_service under mpirun -np N, docs/mpi.md): what the
// service calls instead of the engine. Every member is collective (every rank calls it in the
// same order). Implemented with MPI in dem_service/src/mpi/service_ranks.cpp; this header names
// no MPI type.
class RankDriver {
 public:
  virtual ~RankDriver() = default;
  virtual int ranks() const = 0;
  // What N > 1 does not run (std::invalid_argument naming the key, the reason and the fix).
  virtual void check_supported(const RunConfig& rc, const EngineOptions& options) const = 0;
  // A session's start: `s`, the whole scene (the same on every rank), becomes this rank's share.
  virtual void start(const Scene& scene, Engine& engine, State& s) = 0;
  // As start, within a session (after a checkpoint of the master): the slabs cut anew from the
  // whole scene `s`. A restore_snapshot() of a snapshot taken before goes back to the old cut.
  virtual void recut(const Scene& scene, Engine& engine, State& s) = 0;
  // One DEM step of the whole scene.
  virtual void step(State& s) = 0;
  // The tools' wrenches of the last step, summed over the ranks in rank order.
  virtual std::vector<Wrench> tool_wrenches() = 0;
  // The walls' forces summed by the last tool_wrenches() (not collective).
  virtual std::vector<Vec3> wall_forces() const = 0;
  // Rank 0 writes the output and the checkpoints (not collective).
  virtual bool lead() const = 0;
  // Rank 0: the whole scene's particles sorted by id (an output snapshot); the others: an
  // empty state.
  virtual State gather(const State& s) = 0;
  // Rank 0: the whole scene with its lists and every spring (a checkpoint); the others: an
  // empty state.
  virtual State gather_checkpoint(const State& s) = 0;
  // The whole scene's particle count and kinetic energy (sums in rank order).
  virtual void totals(const State& s, double& particles, double& kinetic_energy) = 0;
  // Everything besides the State that a repeated step needs to start bit for bit where the
  // snapshot was taken (the ghost mask, the exchange lists, the cuts, the guard's tally).
  virtual void save_snapshot() = 0;
  virtual void restore_snapshot() = 0;
};

class ServiceModel final : public cosim::Model {
 public:
  // root: the DEM config (the dem_run schema plus `service`), after --set; base_dir resolves its
  // relative paths. The config is checked here in full, so a bad file fails at start-up.
  // config_path (if given) is the file root came from: no output may overwrite it. engine: how
  // each run's Engine computes (dem_service fills it once from its environment).
  ServiceModel(YAML::Node root, std::string base_dir, std::string config_path = {},
               const EngineOptions& engine = {});
  ~ServiceModel() override;

  void configure(const YAML::Node& parameters, const cosim::RunInfo& run) override;
  cosim::Ports inputs() const override;
  cosim::Ports outputs() const override;
  cosim::Duration inner_step() const override { return inner_step_; }
  cosim::Signals initial_outputs() override;
  cosim::StepResult step(const cosim::StepInputs& in, bool want_average) override;
  // The tools' poses of a step at each DEM step's start and at its end (length / inner step + 1
  // entries), validated (cosim::InputError for NaN or infinity).
  std::vector<std::vector<ToolPose>> step_poses(const cosim::StepInputs& in) const;
  // The step with its poses (step() is step_poses() then this): what every rank runs.
  cosim::StepResult step_with_poses(cosim::TimePoint t_start, cosim::TimePoint t_end,
                                    const std::vector<std::vector<ToolPose>>& poses,
                                    bool want_average);
  // The scene on several ranks (dem_service under mpirun): the driver (kept by the caller)
  // steps it from now on. Refuses (std::invalid_argument) what N > 1 does not run.
  void set_ranks(RankDriver* ranks);
  bool can_repeat() const override { return options_.snapshot; }
  void save_snapshot() override;
  void restore_snapshot() override;
  // The master will not redo the step about to run (step_request_t.no_redo): no copy of the
  // state; the accepted rows may go to the file as at save_snapshot.
  void skip_snapshot() override;
  // The master's checkpoints: the whole State (dem/checkpoint.hpp), bit for bit. A resumed
  // session writes its output.file under a new name (<stem>_from_step<n><ext>) and leaves the
  // interrupted session's file alone.
  bool can_checkpoint() const override { return true; }
  void save_checkpoint(const std::string& path) override;
  void load_checkpoint(const std::string& path) override;
  // Several ranks, after save_checkpoint(path) (collective; `path` a copy of that file on this
  // rank's host): the state read back from it and the slabs cut anew, as a resume from that file
  // does, so that a resumed run repeats the uninterrupted one bit for bit (docs/mpi.md).
  void recut_from_checkpoint(const std::string& path);

  // Ends the run: final particle snapshot, checkpoint, summary; prints the timing table.
  // Safe to call more than once and without a configured session.
  void finish(std::ostream& report);

  // For tests.
  const State& state() const { return rc_->state; }
  const Scene& scene() const { return rc_->scene; }
  const ServiceOptions& options() const { return options_; }

 private:
  // startup: the config file alone; its output folders need not exist yet, because the
  // master's parameters may replace the paths (checked in configure once they are final).
  void build(YAML::Node root, const std::string& what, bool startup = false);
  // Every tool's pose from the step's input polynomials at t (refuses NaN or infinity).
  std::vector<ToolPose> tool_poses(const cosim::StepInputs& in, cosim::TimePoint t) const;
  // N > 1: refusals of what the service does not run on several ranks.
  void check_ranks() const;

  YAML::Node root_;  // as loaded, before the master's parameters
  std::string base_dir_, config_path_;
  std::unique_ptr<RunConfig> rc_;
  std::unique_ptr<Engine> engine_;
  RankDriver* ranks_ = nullptr;  // several ranks: steps the engine; null: one process
  EngineOptions engine_options_;
  std::unique_ptr<RunOutput> out_;
  ServiceOptions options_;
  cosim::Duration inner_step_{};
  cosim::RunInfo run_;
  cosim::Duration particles_every_{}, wrenches_every_{}, checkpoint_every_{};  // zero: none
  cosim::TimePoint next_particles_{}, next_checkpoint_{};
  std::optional<cosim::TimePoint> last_particles_;  // none yet
  std::optional<State> snapshot_;
  std::size_t snapshot_rows_ = 0;
  cosim::TimePoint t_now_{};
  std::vector<ToolPose> end_poses_;  // the tools at t_now_ (the last step's inputs at its end)
  std::int64_t steps_done_ = 0;
  double snapshot_seconds_ = 0;
  double asleep_steps_ = 0, particle_steps_ = 0;  // sleeping share (scene.sleep)
  bool finished_ = false;
  bool pristine_ = true;  // rc_ is the start-up build, untouched by any session
  cosim::Stopwatch session_wall_, since_report_;
};

// Pose of a tool from its kinematics input (validated by the protocol), the quaternion
// normalised.
ToolPose tool_pose_from(const cosim::Kinematics& k);

}  // namespace dem
