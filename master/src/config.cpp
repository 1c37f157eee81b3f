#include "config.hpp"

#include "ssp_import.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace master {

namespace cfg = cosim::config;
using cfg::ConfigError;

const char* use_name(Use use) { return use == Use::End ? "end" : "average"; }

const ParticipantSpec& Config::participant(const std::string& name) const {
  for (const auto& p : participants)
    if (p.name == name) return p;
  throw ConfigError("no participant named '" + name + "'");
}

namespace {

Endpoint parse_endpoint(const YAML::Node& node, const std::string& path, const std::string& key,
                        const Config& c) {
  const std::string text = cfg::get_string(node, path, key);
  const auto dot = text.find('.');
  const std::string where = cfg::join_path(path, key);
  if (dot == std::string::npos || text.find('.', dot + 1) != std::string::npos)
    throw ConfigError(where + ": '" + text + "' must be participant.signal");
  Endpoint e{text.substr(0, dot), text.substr(dot + 1)};
  std::string names;
  bool known = false;
  for (const auto& p : c.participants) {
    known = known || p.name == e.participant;
    names += (names.empty() ? "" : ", ") + p.name;
  }
  if (!known)
    throw ConfigError(where + ": no participant '" + e.participant + "' (participants: " + names + ")");
  if (!cosim::valid_name(e.signal))
    throw ConfigError(where + ": '" + e.signal + "' is not a valid signal name");
  return e;
}

PredictorSpec parse_predictor(const YAML::Node& node, const std::string& path) {
  cfg::check_keys(node, path, {"order", "samples"});
  PredictorSpec p;
  const long long order = cfg::get_int(node, path, "order");
  if (order < 0 || order > cosim::kMaxPolynomialOrder)
    throw ConfigError(path + ".order: " + std::to_string(order) + " is not allowed (allowed: 0, 1, 2, 3)");
  p.order = static_cast<int>(order);
  const long long samples = cfg::get_int_or(node, path, "samples", order + 1);
  if (samples < order + 1 || samples > 16)
    throw ConfigError(path + ".samples: " + std::to_string(samples) + " is not allowed (allowed: " +
                      std::to_string(order + 1) + " to 16; more than order + 1 gives a least-squares fit)");
  p.samples = static_cast<int>(samples);
  return p;
}

double seconds_key(const YAML::Node& n, const std::string& path, const std::string& key) {
  return cfg::get_double(n, path, key);
}

// --- One parser per section; an absent optional key keeps its field's initialiser.

void parse_time(const YAML::Node& time, Config& c) {
  if (!time) throw ConfigError("time: missing (expected a map with start, end, macro_step)");
  cfg::check_keys(time, "time", {"start", "end", "macro_step"});
  c.t_start = cosim::seconds_to_time_point(
      cfg::get_double_or(time, "time", "start", cosim::to_seconds(c.t_start)), "time.start");
  c.t_end = cosim::seconds_to_time_point(seconds_key(time, "time", "end"), "time.end");
  c.macro_step = cosim::seconds_to_duration(seconds_key(time, "time", "macro_step"), "time.macro_step");
  if (c.macro_step <= Duration::zero()) throw ConfigError("time.macro_step: must be > 0");
  if (c.t_end <= c.t_start) throw ConfigError("time.end: must be after time.start");
  if ((c.t_end - c.t_start) % c.macro_step != Duration::zero())
    throw ConfigError("time.end: end - start must be a whole number of macro steps (time.macro_step = " +
                      std::to_string(cosim::to_seconds(c.macro_step)) + " s)");
}

// scheme, startup_iterations, connect_timeout: top-level scalars.
void parse_run_options(const YAML::Node& root, Config& c) {
  const std::string scheme = cfg::get_choice(root, "", "scheme", {"jacobi", "gauss_seidel"},
                                             c.scheme == Scheme::Jacobi ? "jacobi" : "gauss_seidel");
  c.scheme = scheme == "jacobi" ? Scheme::Jacobi : Scheme::GaussSeidel;
  const long long iters = cfg::get_int_or(root, "", "startup_iterations", c.startup_iterations);
  if (iters < 0 || iters > 20)
    throw ConfigError("startup_iterations: " + std::to_string(iters) + " is not allowed (allowed: 0 to 20)");
  c.startup_iterations = static_cast<int>(iters);
  c.connect_timeout = cfg::get_positive_or(root, "", "connect_timeout", c.connect_timeout);
}

// participants.<name>.mpi: the launched program as an MPI job (docs/mpi.md, "Launched by the
// master"). `launch` names the program every rank runs; mpirun itself is not in it.
MpiLaunchSpec parse_mpi(const YAML::Node& node, const std::string& path, const std::vector<std::string>& launch) {
  MpiLaunchSpec m;
  if (!node || node.IsNull()) return m;
  if (!node.IsMap())
    throw ConfigError(path + ": expected a map {ranks: N, mpirun: PROGRAM, args: [OPTION, ...]}");
  cfg::check_keys(node, path, {"ranks", "mpirun", "args"});
  if (!node["ranks"])
    throw ConfigError(path + ".ranks: missing (the number of MPI ranks, e.g. mpi: {ranks: 2})");
  const long long ranks = cfg::get_int(node, path, "ranks");
  if (ranks < 1 || ranks > 65536)
    throw ConfigError(path + ".ranks: " + std::to_string(ranks) +
                      " is not allowed (allowed: 1 to 65536; 1 runs the program under mpirun as one process)");
  m.ranks = static_cast<int>(ranks);
  m.mpirun = cfg::get_string_or(node, path, "mpirun", m.mpirun);
  if (m.mpirun.empty()) throw ConfigError(path + ".mpirun: empty (the MPI launcher, default mpirun)");
  if (YAML::Node a = node["args"]; a && !a.IsNull()) {
    if (!a.IsSequence()) throw ConfigError(path + ".args: expected a list of mpirun options, e.g. [--oversubscribe]");
    for (const auto& v : a) {
      if (!v.IsScalar()) throw ConfigError(path + ".args: every entry must be a string");
      const std::string o = v.Scalar();
      for (const char* n : {"-np", "-n", "--np", "--n", "-c"})
        if (o == n)
          throw ConfigError(path + ".args: '" + o + "' sets the rank count, which is mpi.ranks (" +
                            std::to_string(m.ranks) + "); remove it from args");
      m.args.push_back(o);
    }
  }
  if (launch.empty())
    throw ConfigError(path + ": needs launch, the program every rank runs (e.g. launch: [dem_service, "
                      "scene.yaml] with mpi: {ranks: 2}); a job started by hand has neither");
  return m;
}

ParticipantSpec parse_participant(const std::string& name, const YAML::Node& value) {
  ParticipantSpec p;
  p.name = name;
  const std::string path = "participants." + p.name;
  if (!cosim::valid_name(p.name) || p.name == "master")
    throw ConfigError(path + ": '" + p.name + "' is not a valid participant name (1 to 32 characters of A-Z, a-z, 0-9, _; not 'master')");
  const YAML::Node node = value.IsNull() ? YAML::Node(YAML::NodeType::Map) : value;
  cfg::check_keys(node, path, {"launch", "mpi", "timeout", "retries", "parameters"});
  if (node["launch"] && !node["launch"].IsNull()) {  // null: started by the user
    if (!node["launch"].IsSequence() || node["launch"].size() == 0)
      throw ConfigError(path + ".launch: expected a non-empty list [program, arg, ...]");
    for (const auto& a : node["launch"]) {
      if (!a.IsScalar()) throw ConfigError(path + ".launch: every entry must be a string");
      p.launch.push_back(a.Scalar());
    }
    // mpirun in launch would get the run's key as an inherited descriptor, which it does not
    // pass on to its ranks: the job is declared with mpi: instead, and the master hands it the key.
    const std::string prog = p.launch[0].substr(p.launch[0].rfind('/') + 1);
    for (const char* l : {"mpirun", "mpiexec", "orterun", "srun", "mpirun.openmpi", "mpiexec.openmpi",
                          "mpiexec.hydra", "mpirun.mpich", "mpiexec.mpich"})
      if (prog == l)
        throw ConfigError(path + ".launch: starts '" + prog + "', which would not pass the run's bus key on "
                          "to its ranks: give the program itself in launch and the ranks in mpi, e.g. launch: "
                          "[dem_service, scene.yaml] with mpi: {ranks: 2, args: [--oversubscribe]} (docs/mpi.md)");
  }
  p.mpi = parse_mpi(node["mpi"], path + ".mpi", p.launch);
  p.link.timeout_s = cfg::get_positive_or(node, path, "timeout", p.link.timeout_s);
  const long long retries = cfg::get_int_or(node, path, "retries", p.link.retries);
  if (retries < 0 || retries > 100)
    throw ConfigError(path + ".retries: " + std::to_string(retries) + " is not allowed (allowed: 0 to 100)");
  p.link.retries = static_cast<int>(retries);
  if (node["parameters"]) {
    if (!node["parameters"].IsMap() && !node["parameters"].IsNull())
      throw ConfigError(path + ".parameters: expected a map");
    YAML::Emitter out;
    out << node["parameters"];
    p.parameters_yaml = out.c_str();
  }
  return p;
}

std::vector<ParticipantSpec> parse_participants(const YAML::Node& parts) {
  if (!parts || !parts.IsMap() || parts.size() == 0)
    throw ConfigError("participants: missing (expected a map: name -> {launch, mpi, timeout, retries, parameters})");
  std::vector<ParticipantSpec> out;
  for (const auto& kv : parts) out.push_back(parse_participant(kv.first.as<std::string>(), kv.second));
  return out;
}

// The Gauss-Seidel sequence: every participant once (file order when not given).
std::vector<std::string> parse_order(const YAML::Node& n, const Config& c) {
  std::vector<std::string> order;
  if (n) {
    if (!n.IsSequence()) throw ConfigError("order: expected a list of participant names");
    for (const auto& name : n) order.push_back(name.as<std::string>());
  } else {
    for (const auto& p : c.participants) order.push_back(p.name);
  }
  std::set<std::string> in_order(order.begin(), order.end());
  if (in_order.size() != order.size() || in_order.size() != c.participants.size())
    throw ConfigError("order: must list every participant exactly once");
  for (const auto& name : order) c.participant(name);  // raises for unknown names
  return order;
}

std::map<std::string, PredictorSpec> parse_predictors(const YAML::Node& n) {
  std::map<std::string, PredictorSpec> named;
  if (!n) return named;
  if (!n.IsMap()) throw ConfigError("predictors: expected a map name -> {order, samples}");
  for (const auto& kv : n) {
    const auto name = kv.first.as<std::string>();
    named[name] = parse_predictor(kv.second, "predictors." + name);
  }
  return named;
}

const PredictorSpec& named_predictor(const std::map<std::string, PredictorSpec>& named,
                                     const std::string& name, const std::string& path) {
  const auto it = named.find(name);
  if (it != named.end()) return it->second;
  std::string names;
  for (const auto& [n, s] : named) names += (names.empty() ? "" : ", ") + n;
  throw ConfigError(path + ": unknown predictor '" + name + "' (defined under predictors: " +
                    (names.empty() ? "none" : names) + ")");
}

std::vector<ConnectionSpec> parse_connections(const YAML::Node& conns, const Config& c,
                                              const std::map<std::string, PredictorSpec>& named) {
  // An explicit empty list runs participants without coupling (one FMU on its own, say); a
  // missing key is refused.
  if (conns && conns.IsSequence() && conns.size() == 0) return {};
  if (!conns || !conns.IsSequence())
    throw ConfigError("connections: missing (expected a list of {from: p.signal, to: p.signal, predictor: ...}; "
                      "connections: [] for participants that exchange nothing)");
  std::vector<ConnectionSpec> out;
  std::set<std::string> inputs_seen;
  for (std::size_t i = 0; i < conns.size(); ++i) {
    const std::string path = "connections." + std::to_string(i);
    cfg::check_keys(conns[i], path, {"from", "to", "predictor", "use"});
    ConnectionSpec k;
    k.from = parse_endpoint(conns[i], path, "from", c);
    k.to = parse_endpoint(conns[i], path, "to", c);
    if (k.from.participant == k.to.participant)
      throw ConfigError(path + ": a participant cannot feed itself (" + k.from.str() + " -> " + k.to.str() + ")");
    if (!inputs_seen.insert(k.to.str()).second)
      throw ConfigError(path + ".to: input " + k.to.str() + " is connected twice");
    if (const YAML::Node pred = conns[i]["predictor"]) {
      if (pred.IsScalar()) k.predictor_name = pred.Scalar();
      k.predictor = pred.IsScalar() ? named_predictor(named, k.predictor_name, path + ".predictor")
                                    : parse_predictor(pred, path + ".predictor");
    }
    k.use = cfg::get_choice(conns[i], path, "use", {"end", "average"}, use_name(k.use)) == "end"
                ? Use::End
                : Use::Average;
    out.push_back(k);
  }
  return out;
}

std::vector<PowerSpec> parse_power(const YAML::Node& n, const Config& c) {
  std::vector<PowerSpec> out;
  if (!n) return out;
  if (!n.IsSequence()) throw ConfigError("power: expected a list of {name, force, velocity}");
  for (std::size_t i = 0; i < n.size(); ++i) {
    const std::string path = "power." + std::to_string(i);
    cfg::check_keys(n[i], path, {"name", "force", "velocity"});
    PowerSpec p;
    p.force = parse_endpoint(n[i], path, "force", c);
    p.velocity = parse_endpoint(n[i], path, "velocity", c);
    p.name = cfg::get_string_or(n[i], path, "name", p.force.str() + "_x_" + p.velocity.str());
    out.push_back(p);
  }
  return out;
}

OutputSpec parse_output(const YAML::Node& o) {
  OutputSpec out;
  if (!o) return out;
  cfg::check_keys(o, "output", {"file", "csv", "progress"});
  out.file = cfg::get_string_or(o, "output", "file", out.file);
  out.csv_file = cfg::get_string_or(o, "output", "csv", out.csv_file);
  out.progress = cfg::get_choice(o, "output", "progress", {"auto", "on", "off"}, out.progress);
  return out;
}

std::string number_text(double v) {
  std::ostringstream o;
  o << v;
  return o.str();
}

CheckpointSpec parse_checkpoints(const YAML::Node& n, const Config& c) {
  CheckpointSpec out;
  if (!n) return out;
  cfg::check_keys(n, "checkpoints", {"every", "folder"});
  const double every = cfg::get_double_or(n, "checkpoints", "every", cosim::to_seconds(out.every));
  if (!(every >= 0) || !std::isfinite(every))
    throw ConfigError("checkpoints.every: " + number_text(every) +
                      " is not allowed: give seconds of simulated time >= 0 (0: no checkpoints)");
  if (every > 0) {
    out.every = cosim::seconds_to_duration(every, "checkpoints.every");
    if (out.every % c.macro_step != Duration::zero())
      throw ConfigError("checkpoints.every: " + number_text(every) +
                        " s is not a whole number of macro steps (time.macro_step = " +
                        number_text(cosim::to_seconds(c.macro_step)) + " s)");
  }
  out.folder = cfg::get_string_or(n, "checkpoints", "folder", out.folder);
  return out;
}

// For tests: lose a request or reply once.
cosim::FaultPlan parse_faults(const YAML::Node& f, const Config& c) {
  cosim::FaultPlan faults;
  if (!f) return faults;
  cfg::check_keys(f, "faults", {"drop_request", "drop_reply"});
  for (const char* key : {"drop_request", "drop_reply"}) {
    if (!f[key]) continue;
    if (!f[key].IsSequence()) throw ConfigError(std::string("faults.") + key + ": expected a list of {participant, step}");
    for (std::size_t i = 0; i < f[key].size(); ++i) {
      const std::string path = std::string("faults.") + key + "." + std::to_string(i);
      cfg::check_keys(f[key][i], path, {"participant", "step"});
      const auto who = cfg::get_string(f[key][i], path, "participant");
      c.participant(who);
      const auto step = cfg::get_int(f[key][i], path, "step");
      (std::string(key) == "drop_request" ? faults.drop_request : faults.drop_reply)
          .insert({who, step});
    }
  }
  return faults;
}

const char* const kMeasures[] = {"absolute", "relative", "residual_relative", "absolute_or_relative"};
const char* const kAccelerations[] = {"none", "constant", "aitken", "iqn_ils"};

double positive_limit(const YAML::Node& n, const std::string& path, const std::string& key) {
  const double v = cfg::get_double(n, path, key);
  if (!(v > 0) || !std::isfinite(v))
    throw ConfigError(path + "." + key + ": " + number_text(v) + " is not allowed: give a finite number > 0");
  return v;
}

// coupling.adaptive: the macro step chosen by ECCO's PI controller.
AdaptiveSpec parse_adaptive(const YAML::Node& n, const Config& c) {
  AdaptiveSpec a;
  if (!n) return a;
  const std::string path = "coupling.adaptive";
  if (!n.IsMap()) throw ConfigError(path + ": expected a map {min_step, max_step, abs_tolerance, ...}");
  cfg::check_keys(n, path, {"min_step", "max_step", "abs_tolerance", "rel_tolerance", "p_gain", "i_gain",
                            "safety", "min_change", "max_change", "reject_above"});
  a.enabled = true;
  a.min_step = cosim::seconds_to_duration(positive_limit(n, path, "min_step"), path + ".min_step");
  a.max_step = cosim::seconds_to_duration(positive_limit(n, path, "max_step"), path + ".max_step");
  if (a.min_step > c.macro_step || a.max_step < c.macro_step)
    throw ConfigError(path + ": min_step " + number_text(cosim::to_seconds(a.min_step)) + " s <= time.macro_step " +
                      number_text(cosim::to_seconds(c.macro_step)) + " s (the first step) <= max_step " +
                      number_text(cosim::to_seconds(a.max_step)) + " s must hold");
  auto get = [&](const char* key, double& v, double lo, double hi, bool open_lo) {
    v = cfg::get_double_or(n, path, key, v);
    if (!(open_lo ? v > lo : v >= lo) || !(v <= hi) || !std::isfinite(v))
      throw ConfigError(path + "." + key + ": " + number_text(v) + " is not allowed (allowed: " +
                        (open_lo ? "> " : ">= ") + number_text(lo) + " and <= " + number_text(hi) + ")");
  };
  get("abs_tolerance", a.abs_tolerance, 0, 1e30, true);
  get("rel_tolerance", a.rel_tolerance, 0, 1, false);
  get("p_gain", a.p_gain, 0, 2, false);
  get("i_gain", a.i_gain, 0, 2, true);
  get("safety", a.safety, 0, 1, true);
  get("min_change", a.min_change, 0, 1, true);
  get("max_change", a.max_change, 1, 100, false);
  a.reject_above = cfg::get_double_or(n, path, "reject_above", a.reject_above);
  if (!(a.reject_above == 0 || (a.reject_above >= 1 && a.reject_above <= 1e6)))
    throw ConfigError(path + ".reject_above: " + number_text(a.reject_above) +
                      " is not allowed (allowed: 0, never reject; or an error estimate from 1, the "
                      "tolerance, to 1e6)");
  if (c.power.empty())
    throw ConfigError(path + ": the controller measures the energy residual of the power bonds, and `power` "
                      "lists none; add a {name, force, velocity} pair under power");
  return a;
}

// coupling: explicit (the default) or implicit with its iterations, convergence and acceleration.
CouplingSpec parse_coupling(const YAML::Node& n, const Config& c) {
  CouplingSpec out;
  if (!n) return out;
  if (!n.IsMap()) throw ConfigError("coupling: expected a map {type, min_iterations, max_iterations, ...}");
  cfg::check_keys(n, "coupling", {"type", "min_iterations", "max_iterations", "at_max_iterations",
                                  "convergence", "acceleration", "adaptive"});
  out.adaptive = parse_adaptive(n["adaptive"], c);
  out.type = cfg::get_choice(n, "coupling", "type", {"explicit", "implicit"}, "explicit") == "implicit"
                 ? CouplingType::Implicit
                 : CouplingType::Explicit;
  if (out.type == CouplingType::Explicit) {
    for (const char* key : {"min_iterations", "max_iterations", "at_max_iterations", "convergence", "acceleration"})
      if (n[key])
        throw ConfigError(std::string("coupling.") + key +
                          ": only for coupling.type: implicit (the explicit scheme steps once); "
                          "set coupling.type: implicit or remove the key");
    return out;
  }
  const long long lo = cfg::get_int_or(n, "coupling", "min_iterations", out.min_iterations);
  const long long hi = cfg::get_int_or(n, "coupling", "max_iterations", out.max_iterations);
  if (hi < 1 || hi > 1000)
    throw ConfigError("coupling.max_iterations: " + std::to_string(hi) + " is not allowed (allowed: 1 to 1000)");
  if (lo < 1 || lo > hi)
    throw ConfigError("coupling.min_iterations: " + std::to_string(lo) +
                      " is not allowed (allowed: 1 to coupling.max_iterations = " + std::to_string(hi) + ")");
  out.min_iterations = static_cast<int>(lo);
  out.max_iterations = static_cast<int>(hi);
  out.stop_at_max = cfg::get_choice(n, "coupling", "at_max_iterations", {"accept", "stop"}, "accept") == "stop";
  const YAML::Node conv = n["convergence"];
  if (!conv || !conv.IsSequence() || conv.size() == 0)
    throw ConfigError("coupling.convergence: missing (coupling.type: implicit needs a list of "
                      "{connection: participant.input, measure: relative, limit: 1.0e-6})");
  for (std::size_t i = 0; i < conv.size(); ++i) {
    const std::string path = "coupling.convergence." + std::to_string(i);
    if (!conv[i].IsMap()) throw ConfigError(path + ": expected a map {connection, measure, limit}");
    const std::string measure = cfg::get_choice(conv[i], path, "measure",
                                                {kMeasures[0], kMeasures[1], kMeasures[2], kMeasures[3]});
    ConvergenceSpec cs;
    if (measure == "absolute_or_relative") {
      cfg::check_keys(conv[i], path, {"connection", "measure", "absolute", "relative", "suffices"});
      cs.measure = Measure::AbsoluteOrRelative;
      cs.limit = positive_limit(conv[i], path, "absolute");
      cs.relative_limit = positive_limit(conv[i], path, "relative");
    } else {
      cfg::check_keys(conv[i], path, {"connection", "measure", "limit", "suffices"});
      cs.measure = measure == "absolute" ? Measure::Absolute
                   : measure == "relative" ? Measure::Relative
                                           : Measure::ResidualRelative;
      cs.limit = positive_limit(conv[i], path, "limit");
    }
    cs.suffices = cfg::get_bool_or(conv[i], path, "suffices", false);
    const std::string to = cfg::get_string(conv[i], path, "connection");
    std::string inputs;
    bool found = false;
    for (std::size_t k = 0; k < c.connections.size(); ++k) {
      inputs += (k ? ", " : "") + c.connections[k].to.str();
      if (c.connections[k].to.str() == to) cs.connection = k, found = true;
    }
    if (!found)
      throw ConfigError(path + ".connection: '" + to + "' is not the input of a connection (give the "
                        "connection's `to`, one of: " + inputs + ")");
    out.convergence.push_back(cs);
  }
  const YAML::Node a = n["acceleration"];
  if (a) {
    if (!a.IsMap()) throw ConfigError("coupling.acceleration: expected a map {type, relaxation, ...}");
    const std::string type = cfg::get_choice(a, "coupling.acceleration", "type",
                                             {kAccelerations[0], kAccelerations[1], kAccelerations[2], kAccelerations[3]});
    auto& acc = out.acceleration;
    acc.type = type == "none" ? AccelerationType::None
               : type == "constant" ? AccelerationType::Constant
               : type == "aitken"   ? AccelerationType::Aitken
                                    : AccelerationType::IqnIls;
    if (acc.type == AccelerationType::None) cfg::check_keys(a, "coupling.acceleration", {"type"});
    else if (acc.type == AccelerationType::IqnIls)
      cfg::check_keys(a, "coupling.acceleration", {"type", "relaxation", "reuse", "max_columns", "filter"});
    else cfg::check_keys(a, "coupling.acceleration", {"type", "relaxation"});
    if (acc.type != AccelerationType::None) {
      acc.relaxation = cfg::get_double_or(a, "coupling.acceleration", "relaxation", acc.relaxation);
      if (!(acc.relaxation > 0 && acc.relaxation <= 1))
        throw ConfigError("coupling.acceleration.relaxation: " + number_text(acc.relaxation) +
                          " is not allowed (allowed: > 0 and <= 1; 1 is no relaxation)");
    }
    if (acc.type == AccelerationType::IqnIls) {
      const long long reuse = cfg::get_int_or(a, "coupling.acceleration", "reuse", acc.reuse);
      if (reuse < 0 || reuse > 100)
        throw ConfigError("coupling.acceleration.reuse: " + std::to_string(reuse) + " is not allowed (allowed: 0 to 100 past macro steps)");
      const long long cols = cfg::get_int_or(a, "coupling.acceleration", "max_columns", acc.max_columns);
      if (cols < 1 || cols > 1000)
        throw ConfigError("coupling.acceleration.max_columns: " + std::to_string(cols) + " is not allowed (allowed: 1 to 1000)");
      acc.reuse = static_cast<int>(reuse);
      acc.max_columns = static_cast<int>(cols);
      acc.filter = cfg::get_double_or(a, "coupling.acceleration", "filter", acc.filter);
      if (!(acc.filter >= 0 && acc.filter < 1))
        throw ConfigError("coupling.acceleration.filter: " + number_text(acc.filter) +
                          " is not allowed (allowed: 0 <= filter < 1; 0 keeps every column)");
    }
  }
  return out;
}

}  // namespace

const char* measure_name(Measure m) { return kMeasures[static_cast<int>(m)]; }
const char* acceleration_name(AccelerationType t) { return kAccelerations[static_cast<int>(t)]; }

Config parse_config(const YAML::Node& root, const std::string& source_text) {
  Config c;
  c.source_text = source_text;
  {
    YAML::Emitter out;
    out << root;
    c.effective_yaml = out.c_str();
  }
  cfg::check_keys(root, "", {"bus", "time", "scheme", "order", "startup_iterations",
                              "connect_timeout", "participants", "predictors", "connections",
                              "power", "output", "checkpoints", "faults", "coupling"});
  if (root["bus"]) {
    cfg::check_keys(root["bus"], "bus", {"url", "authenticate"});
    c.bus_url = cfg::get_string_or(root["bus"], "bus", "url", c.bus_url);
    c.authenticate = cfg::get_bool_or(root["bus"], "bus", "authenticate", c.authenticate);
  }
  parse_time(root["time"], c);
  parse_run_options(root, c);
  c.participants = parse_participants(root["participants"]);
  c.order = parse_order(root["order"], c);
  c.connections = parse_connections(root["connections"], c, parse_predictors(root["predictors"]));
  c.power = parse_power(root["power"], c);
  c.output = parse_output(root["output"]);
  c.checkpoints = parse_checkpoints(root["checkpoints"], c);
  c.faults = parse_faults(root["faults"], c);
  c.coupling = parse_coupling(root["coupling"], c);
  return c;
}

namespace {

// Replaces ${config_dir} in every string under node (launch arguments and parameters name
// files beside the config, wherever the master is started from).
void substitute_config_dir(YAML::Node node, const std::string& dir) {
  if (node.IsScalar()) {
    std::string v = node.Scalar();
    const std::string key = "${config_dir}";
    bool changed = false;
    for (auto at = v.find(key); at != std::string::npos; at = v.find(key, at + dir.size())) {
      v.replace(at, key.size(), dir);
      changed = true;
    }
    if (changed) node = v;
  } else if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i) substitute_config_dir(node[i], dir);
  } else if (node.IsMap()) {
    for (auto it = node.begin(); it != node.end(); ++it) substitute_config_dir(it->second, dir);
  }
}

}  // namespace

Config load_config(const std::string& path, const std::vector<std::string>& overrides) {
  std::string text;  // an SSP system (.ssp, .ssd, or a YAML with ssp:) becomes the generated YAML
  YAML::Node root = ssp::load_root(path, &text);  // refuses folders, scalars, duplicate keys
  for (const auto& o : overrides) cfg::apply_override(root, o);
  if (YAML::Node parts = root["participants"]; parts && parts.IsMap()) {
    const std::string dir = std::filesystem::absolute(path).parent_path().lexically_normal().string();
    for (auto it = parts.begin(); it != parts.end(); ++it)
      if (it->second.IsMap()) {
        if (YAML::Node l = it->second["launch"]) substitute_config_dir(l, dir);
        if (YAML::Node m = it->second["mpi"]) substitute_config_dir(m, dir);
        if (YAML::Node p = it->second["parameters"]) substitute_config_dir(p, dir);
      }
  }
  return parse_config(root, text);
}

void check_wiring(const Config& c, const std::map<std::string, cosim::ParticipantInfo>& parts) {
  auto ports_list = [](const cosim::Ports& ports) {
    std::string s;
    for (const auto& p : ports) s += (s.empty() ? "" : ", ") + p.name;
    return s.empty() ? std::string("none") : s;
  };
  auto find = [](const cosim::Ports& ports, const std::string& name) -> const cosim::PortSpec* {
    for (const auto& p : ports)
      if (p.name == name) return &p;
    return nullptr;
  };
  for (std::size_t i = 0; i < c.connections.size(); ++i) {
    const auto& k = c.connections[i];
    const std::string what = "connections." + std::to_string(i) + " (" + k.from.str() + " -> " + k.to.str() + ")";
    const auto& src = parts.at(k.from.participant);
    const auto& dst = parts.at(k.to.participant);
    const auto* out = find(src.outputs, k.from.signal);
    if (!out)
      throw ConfigError(what + ": " + k.from.participant + " has no output '" + k.from.signal +
                        "' (it has: " + ports_list(src.outputs) + ")");
    const auto* in = find(dst.inputs, k.to.signal);
    if (!in)
      throw ConfigError(what + ": " + k.to.participant + " has no input '" + k.to.signal +
                        "' (it has: " + ports_list(dst.inputs) + ")");
    if (in->kind != out->kind)
      throw ConfigError(what + ": output is " + std::string(cosim::kind_name(out->kind)) +
                        " but the input is " + std::string(cosim::kind_name(in->kind)));
    if (k.use == Use::Average && out->kind == cosim::SignalKind::Kinematics)
      throw ConfigError("connections." + std::to_string(i) + ".use: 'average' is not allowed for " +
                        k.from.str() + ", a kinematics signal (a pose has no plain average); "
                        "use: end (allowed for kinematics: end)");
  }
  for (const auto& [name, info] : parts) {
    for (const auto& in : info.inputs) {
      bool fed = false;
      for (const auto& k : c.connections) fed = fed || (k.to.participant == name && k.to.signal == in.name);
      if (!fed)
        throw ConfigError("connections: input " + name + "." + in.name +
                          " is not connected (add {from: <participant>.<output>, to: " + name + "." + in.name + "})");
    }
    if (c.macro_step % info.inner_step != Duration::zero())
      throw ConfigError("time.macro_step: " + std::to_string(cosim::to_ns(c.macro_step)) +
                        " ns is not a multiple of participant " + name + "'s inner step " +
                        std::to_string(cosim::to_ns(info.inner_step)) +
                        " ns; choose a multiple of it or change that participant's inner step");
  }
  for (std::size_t i = 0; i < c.power.size(); ++i) {
    const auto& p = c.power[i];
    const std::string what = "power." + std::to_string(i);
    const auto* f = find(parts.at(p.force.participant).outputs, p.force.signal);
    const auto* v = find(parts.at(p.velocity.participant).outputs, p.velocity.signal);
    if (!f || !v) throw ConfigError(what + ": force and velocity must be outputs of their participants");
    const bool ok = (f->kind == cosim::SignalKind::Scalar && v->kind == cosim::SignalKind::Scalar) ||
                    (f->kind == cosim::SignalKind::Wrench && v->kind == cosim::SignalKind::Kinematics);
    if (!ok) throw ConfigError(what + ": pair a scalar force with a scalar velocity, or a wrench with kinematics");
    bool f_to_v = false, v_to_f = false;
    for (const auto& k : c.connections) {
      f_to_v = f_to_v || (k.from.str() == p.force.str() && k.to.participant == p.velocity.participant);
      v_to_f = v_to_f || (k.from.str() == p.velocity.str() && k.to.participant == p.force.participant);
    }
    if (!f_to_v || !v_to_f)
      throw ConfigError(what + ": " + p.force.str() + " must feed " + p.velocity.participant + " and " +
                        p.velocity.str() + " must feed " + p.force.participant);
  }
}

}  // namespace master
