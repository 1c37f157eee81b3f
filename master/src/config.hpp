// The master's configuration: read once from YAML (+ --set overrides), validated strictly,
// then checked against what the participants declare before the first step. A field's
// initialiser is the default of its key (the parser falls back to it; docs/config.md lists
// them, tests/master checks the two agree).
#pragma once

#include <cosim/link.hpp>
#include <cosim/time.hpp>
#include <cosim/yaml_config.hpp>

#include <map>
#include <string>
#include <vector>

namespace master {

using cosim::Duration;
using cosim::TimePoint;

enum class Scheme { Jacobi, GaussSeidel };

struct PredictorSpec {
  int order = 0;    // 0..3
  int samples = 1;  // past samples used; order + 1 interpolates, more is a least-squares fit
};

struct Endpoint {
  std::string participant, signal;
  std::string str() const { return participant + "." + signal; }
};

// What a connection hands over from its source: the output at each macro time point (End), or
// its mean over each macro step (Average: the source is asked for interval averages and the
// predictor fits them by histopolation; scalars and wrenches only).
enum class Use { End, Average };
const char* use_name(Use use);  // "end", "average"

struct ConnectionSpec {
  Endpoint from, to;
  PredictorSpec predictor;
  std::string predictor_name;  // named predictor it uses, or "" for inline
  Use use = Use::End;
};

struct PowerSpec {
  std::string name;
  Endpoint force, velocity;
};

// A launched participant that runs as an MPI job (participants.<name>.mpi, docs/mpi.md): the
// master starts `mpirun -np ranks [-x COSIM_KEY_FILE] args... program launch-args...`.
struct MpiLaunchSpec {
  int ranks = 0;                    // 0: not an MPI job
  std::string mpirun = "mpirun";    // looked up on PATH (or a path)
  std::vector<std::string> args;    // more options for mpirun (--oversubscribe, --hostfile F, ...)
};

struct ParticipantSpec {
  std::string name;
  std::vector<std::string> launch;  // empty: started by the user
  MpiLaunchSpec mpi;                // launch under mpirun (needs launch)
  cosim::LinkSettings link;
  std::string parameters_yaml;
};

struct OutputSpec {
  std::string file;      // HDF5; "" for none
  std::string csv_file;  // "" for none
  std::string progress = "auto";  // auto (when stderr is a terminal), on, off
};

// Checkpoints every participant writes at common macro times, so that a stopped run can be
// continued with cosim_master --resume (docs/protocol.md#checkpoints-and-resume).
struct CheckpointSpec {
  Duration every{};    // zero: none; else a whole number of macro steps
  std::string folder;  // on each participant's host; "" : the output file's name + ".checkpoints"
};

// Implicit coupling (docs/coupling.md): the coupling signals of a macro step iterated until they
// converge, every participant rolled back to the step's start between iterations.
enum class CouplingType { Explicit, Implicit };
// preCICE's convergence measures of a connection's residual r = x - x_in (its source's value at the
// step's end minus the value in place for it when the iteration began), x its new value:
// Absolute ||r|| <= limit; Relative ||r|| <= limit ||x||; ResidualRelative ||r|| <= limit ||r_0||
// (r_0: the step's first iteration); AbsoluteOrRelative: either of the first two.
enum class Measure { Absolute, Relative, ResidualRelative, AbsoluteOrRelative };
const char* measure_name(Measure m);

struct ConvergenceSpec {
  std::size_t connection = 0;  // index into Config::connections
  Measure measure = Measure::Relative;
  double limit = 0;           // Absolute, Relative, ResidualRelative; AbsoluteOrRelative: absolute
  double relative_limit = 0;  // AbsoluteOrRelative only
  bool suffices = false;      // converged when this one is met, whatever the others say
};

enum class AccelerationType { None, Constant, Aitken, IqnIls };
const char* acceleration_name(AccelerationType t);

struct AccelerationSpec {
  AccelerationType type = AccelerationType::None;
  double relaxation = 0.5;  // constant: the factor; aitken, iqn_ils: the first iteration's
  int reuse = 8;            // iqn_ils: past macro steps whose columns are kept
  int max_columns = 100;    // iqn_ils
  double filter = 1e-2;     // iqn_ils: QR filter, a column whose new part is below filter x its norm is dropped
};

// Adaptive macro step (docs/coupling.md#adaptive-macro-step): ECCO's PI controller on the power
// bonds' energy residual (Sadjina et al. 2017), bounded, a whole multiple of every inner step.
struct AdaptiveSpec {
  bool enabled = false;
  Duration min_step{}, max_step{};  // required when enabled
  double abs_tolerance = 1e-6;      // J
  double rel_tolerance = 1e-3;      // of the energy through the bond over the step
  double p_gain = 0.2, i_gain = 0.15;
  double safety = 0.8;
  double min_change = 0.2, max_change = 1.5;  // of the step, per step
  // A step whose error estimate exceeds reject_above is rolled back and redone shorter (unless it
  // is at min_step already); 0: every step is accepted. Needs participants that can repeat a step.
  double reject_above = 0;
};

struct CouplingSpec {
  CouplingType type = CouplingType::Explicit;
  AdaptiveSpec adaptive;
  int min_iterations = 1;
  int max_iterations = 50;
  bool stop_at_max = false;  // at_max_iterations: stop (else accept with a warning)
  std::vector<ConvergenceSpec> convergence;
  AccelerationSpec acceleration;
};

struct Config {
  std::string bus_url;
  // false: an unauthenticated bus, by explicit choice (the recorded config says so). true: a
  // key from the environment, else a fresh key for the run when the master launches every
  // participant (docs/security.md#the-default-a-key-per-run).
  bool authenticate = true;
  TimePoint t_start{}, t_end{};
  Duration macro_step{};
  Scheme scheme = Scheme::Jacobi;
  std::vector<std::string> order;  // Gauss-Seidel sequence
  int startup_iterations = 2;
  double connect_timeout = 30;
  std::vector<ParticipantSpec> participants;
  std::vector<ConnectionSpec> connections;
  std::vector<PowerSpec> power;
  OutputSpec output;
  CheckpointSpec checkpoints;
  CouplingSpec coupling;
  cosim::FaultPlan faults;
  std::string source_text;     // the file as read
  std::string effective_yaml;  // after --set

  const ParticipantSpec& participant(const std::string& name) const;
};

// Parses and validates everything that does not need the participants. source_text is stored
// verbatim in the output. Raises cosim::config::ConfigError naming the key.
Config parse_config(const YAML::Node& root, const std::string& source_text);
// Reads the file, applies overrides ("a.b=value"), parses.
Config load_config(const std::string& path, const std::vector<std::string>& overrides);

// Checks connections, power pairs and the macro step against the participants' declarations.
void check_wiring(const Config& config,
                  const std::map<std::string, cosim::ParticipantInfo>& participants);

}  // namespace master
