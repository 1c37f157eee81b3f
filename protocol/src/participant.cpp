#include "cosim/participant_core.hpp"

#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <new>

#include "cosim/bus.hpp"
#include "cosim/stopwatch.hpp"
#include "cosim/yaml_config.hpp"

namespace cosim {

Value StepInputs::at(const std::string& name, TimePoint t) const {
  const double s = static_cast<double>(to_ns(t - t_start_)) / static_cast<double>(to_ns(length()));
  return polynomial(name).evaluate(s);
}

const InputPolynomial& StepInputs::polynomial(const std::string& name) const {
  auto it = inputs_.find(name);
  if (it == inputs_.end()) throw std::out_of_range("no input named '" + name + "'");
  return it->second;
}

ParticipantCore::ParticipantCore(std::string name, Model& model)
    : name_(std::move(name)), model_(model) {
  require_valid_name(name_, "participant name");
}

void ParticipantCore::set_identity(int64_t instance, std::string host, int32_t pid) {
  instance_ = instance;
  host_ = std::move(host);
  pid_ = pid;
}

ready_t ParticipantCore::refusal(const configure_t& m, const std::string& error) const {
  ready_t r{};
  r.protocol_version = kProtocolVersion;
  r.session_id = m.session_id;
  r.participant = name_;
  r.instance_id = instance_;
  r.host = host_;
  r.pid = pid_;
  r.ok = false;
  r.error = error;
  return r;
}

std::optional<ready_t> ParticipantCore::configure(const configure_t& m) {
  if (m.participant != name_) return std::nullopt;
  if (m.instance_id != 0 && instance_ != 0 && m.instance_id != instance_) return std::nullopt;
  const std::string who = "participant '" + name_ + "' (pid " + std::to_string(pid_) + " on " +
                          (host_.empty() ? std::string("?") : host_) + ")";
  if (bound()) {
    if (m.session_id == session_ && ready_) return ready_;  // the master resent: same answer
    ++ignored_;
    ready_t r = refusal(m, who + " is already in session " + id_hex(session_) +
                               " of another master; start another instance for this run");
    r.bound_session_id = session_;
    return r;
  }
  if (reserved_ != 0 && m.session_id != reserved_) {
    ++ignored_;
    return refusal(m, who + " was started for session " + id_hex(reserved_) +
                          " (--session) and takes no other");
  }
  ready_t r = refusal(m, "");
  try {
    if (m.protocol_version != kProtocolVersion)
      throw ProtocolError("protocol version " + std::to_string(m.protocol_version) +
                          " from the master, this participant speaks " +
                          std::to_string(kProtocolVersion) + ": rebuild both from one source");
    if (m.session_id == 0) throw ProtocolError("session id 0 is reserved");
    if (m.macro_step_ns <= 0 || m.t_end_ns <= m.t_start_ns || m.t_start_ns < 0)
      throw ProtocolError("configure: times must satisfy 0 <= t_start < t_end and macro_step > 0");
    YAML::Node params;
    try {
      params = m.parameters_yaml.empty() ? YAML::Node(YAML::NodeType::Map)
                                         : YAML::Load(m.parameters_yaml);
    } catch (const YAML::Exception& e) {
      throw config::ConfigError(std::string("parameters are not valid YAML: ") + e.what());
    }
    if (params.IsNull()) params = YAML::Node(YAML::NodeType::Map);
    run_ = RunInfo{name_, time_point_ns(m.t_start_ns), time_point_ns(m.t_end_ns),
                   nanoseconds(m.macro_step_ns)};
    if (m.resume_steps_done < 0)
      throw ProtocolError("configure: resume_steps_done " + std::to_string(m.resume_steps_done) +
                          " is negative");
    if (m.resume_steps_done > 0) {
      // Any time inside the run: an adaptive macro step's resume time is no multiple of
      // macro_step (the master's record says where its steps ended).
      if (m.resume_t_ns <= m.t_start_ns || m.resume_t_ns >= m.t_end_ns)
        throw ProtocolError("configure: resume after " + std::to_string(m.resume_steps_done) + " steps at " +
                            std::to_string(m.resume_t_ns) + " ns, which is not inside the run (" +
                            std::to_string(m.t_start_ns) + ", " + std::to_string(m.t_end_ns) + ") ns");
      run_.resume_steps_done = m.resume_steps_done;
      run_.resume_time = time_point_ns(m.resume_t_ns);
      if (m.checkpoint_folder.empty())
        throw ProtocolError("configure: a resume needs the checkpoint folder");
    }
    model_.configure(params, run_);
    inputs_ = model_.inputs();
    outputs_ = model_.outputs();
    const Duration inner = model_.inner_step();
    if (inner <= Duration::zero()) throw ProtocolError("model reports a non-positive inner step");
    const Signals initial = model_.initial_outputs();
    check_against_ports(initial, outputs_, "initial outputs");
    for (const auto& [n, s] : initial) validate_value(s.kind, s.value, "initial output '" + n + "'");
    r.inner_step_ns = to_ns(inner);
    r.can_repeat = model_.can_repeat();
    if (!r.can_repeat) r.error = model_.repeat_note();
    r.can_checkpoint = model_.can_checkpoint();
    checkpoint_folder_ = m.checkpoint_folder;
    run_id_ = m.run_id;
    checkpoints_.clear();
    resumed_from_.clear();
    if (!checkpoint_folder_.empty() && model_.can_checkpoint()) {
      std::error_code ec;
      std::filesystem::create_directories(checkpoint_folder_, ec);
      if (ec || !std::filesystem::is_directory(checkpoint_folder_))
        throw ProtocolError("checkpoints.folder: cannot create '" + checkpoint_folder_ + "' on " +
                            (host_.empty() ? std::string("this host") : host_) + ": " +
                            (ec ? ec.message() : std::string("not a folder")) +
                            " (the folder is on each participant's host; choose one every "
                            "participant can write)");
    }
    if (m.resume_steps_done > 0) restore_checkpoint(m);
    r.inputs = to_message(inputs_);
    r.n_inputs = static_cast<int32_t>(r.inputs.size());
    r.outputs = to_message(outputs_);
    r.n_outputs = static_cast<int32_t>(r.outputs.size());
    r.initial_outputs = to_message(initial);
    r.ok = true;
    session_ = m.session_id;
    t_now_ = t_before_last_ = run_.t_start;
    last_step_ = -1;
    last_iteration_ = -1;
    if (m.resume_steps_done > 0) {
      // As if step n-1 had just been done here; it cannot be redone (no snapshot of its start):
      // a redo would have to start at t_before_last_ = the resume time, which none does.
      t_now_ = t_before_last_ = run_.resume_time;
      last_step_ = m.resume_steps_done - 1;
      last_iteration_ = 0;
    }
    start_kept_ = false;
    start_note_ = m.resume_steps_done > 0 ? "the run was resumed from a checkpoint after it" : "";
    cached_.reset();
    done_iteration_ = last_iteration_;
    done_step_ = last_step_;
    ready_ = r;
  } catch (const std::exception& e) {
    r.error = e.what();
  }
  return r;
}

std::string ParticipantCore::checkpoint_path(const std::string& folder, const std::string& participant,
                                             int64_t run_id, int64_t steps_done) {
  return (std::filesystem::path(folder) /
          (participant + "_" + id_hex(run_id) + "_" + std::to_string(steps_done) + ".ckpt"))
      .string();
}

void ParticipantCore::restore_checkpoint(const configure_t& m) {
  const std::string who = "participant '" + name_ + "' (pid " + std::to_string(pid_) + " on " +
                          (host_.empty() ? std::string("?") : host_) + ")";
  if (!model_.can_checkpoint())
    throw ProtocolError(who + " cannot resume a run: this model does not save checkpoints, so "
                              "its state at the resume time cannot be restored");
  const std::string path = checkpoint_path(m.checkpoint_folder, name_, m.run_id, m.resume_steps_done);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw ProtocolError(who + " has no checkpoint after " + std::to_string(m.resume_steps_done) +
                        " steps of run " + id_hex(m.run_id) + ": '" + path +
                        "' is missing. Start the participant on the host (and in the working "
                        "directory) where it ran before, so that it sees the checkpoint folder");
  try {
    model_.load_checkpoint(path);
  } catch (const std::exception& e) {
    throw ProtocolError(who + ": checkpoint '" + path + "' cannot be restored: " + e.what());
  }
  // This run's other checkpoints of this participant are of no use now: older ones are
  // superseded, later ones (written before the others had checkpointed) will be rewritten.
  const std::string prefix = name_ + "_" + id_hex(m.run_id) + "_";
  for (const auto& entry : std::filesystem::directory_iterator(m.checkpoint_folder, ec)) {
    const std::string file = entry.path().filename().string();
    if (file.rfind(prefix, 0) == 0 && entry.path().string() != path &&
        (entry.path().extension() == ".ckpt" || entry.path().extension() == ".tmp"))
      std::filesystem::remove(entry.path(), ec);
  }
  checkpoints_.push_back(path);
  resumed_from_ = path;
}

void ParticipantCore::write_checkpoint() {
  const std::string path = checkpoint_path(checkpoint_folder_, name_, run_id_, last_step_ + 1);
  const std::string temp = path + ".tmp";
  model_.save_checkpoint(temp);
  std::error_code ec;
  std::filesystem::rename(temp, path, ec);  // complete or absent, never half written
  if (ec) throw std::runtime_error("cannot rename '" + temp + "' to '" + path + "': " + ec.message());
  if (checkpoints_.empty() || checkpoints_.back() != path) checkpoints_.push_back(path);
  // The master records a checkpoint once every participant has written it, before it asks for
  // the next one: the previous one is the oldest it may still resume from.
  // The one this session resumed from stays too (resumed_from_).
  while (checkpoints_.size() > (resumed_from_.empty() ? 2u : 3u)) {
    auto oldest = checkpoints_.begin();
    if (*oldest == resumed_from_) ++oldest;
    std::filesystem::remove(*oldest, ec);
    checkpoints_.erase(oldest);
  }
}

void ParticipantCore::end_session(bool finished) {
  if (!finished || checkpoints_.empty()) return;
  std::error_code ec;
  for (const auto& path : checkpoints_) std::filesystem::remove(path, ec);
  checkpoints_.clear();
  std::filesystem::remove(checkpoint_folder_, ec);  // only if it is empty now
}

step_reply_t ParticipantCore::refuse(const step_request_t& q, int8_t status,
                                     const std::string& message) {
  step_reply_t r{};
  r.session_id = session_;
  r.participant = name_;
  r.instance_id = instance_;
  r.step_index = q.step_index;
  r.iteration = q.iteration;
  r.attempt = q.attempt;
  r.t_start_ns = q.t_start_ns;
  r.t_end_ns = q.t_end_ns;
  r.status = status;
  r.message = message;
  return r;
}

std::optional<step_reply_t> ParticipantCore::handle(const step_request_t& q) {
  if (!bound() || q.session_id != session_ || q.participant != name_) {
    ++ignored_;
    return std::nullopt;
  }
  // A repeated request for the step just done: answer from the cache, never step twice.
  if (cached_ && q.step_index == last_step_ && q.iteration == last_iteration_) {
    step_reply_t r = *cached_;
    r.attempt = q.attempt;
    return r;
  }
  if (cached_ && cached_->status == step_reply_t::ENDED)
    return refuse(q, step_reply_t::REJECTED,
                  "the model ended itself at t = " + std::to_string(to_seconds(t_now_)) +
                      " s (" + cached_->message + "); it takes no further step");
  const bool next = q.step_index == last_step_ + 1;
  const bool redo = q.step_index == last_step_ && q.iteration > last_iteration_;
  if (q.step_index < last_step_ || (q.step_index == last_step_ && q.iteration < last_iteration_)) {
    ++ignored_;  // a late duplicate of something already answered
    return std::nullopt;
  }
  if (!next && !redo)
    return refuse(q, step_reply_t::REJECTED,
                  "step " + std::to_string(q.step_index) + " requested, but the next step is " +
                      std::to_string(last_step_ + 1));
  if (redo && !model_.can_repeat())
    return refuse(q, step_reply_t::REJECTED, "this participant cannot repeat a step");
  if (redo && !start_kept_)
    return refuse(q, step_reply_t::REJECTED,
                  "step " + std::to_string(q.step_index) + " cannot be redone: the state at its start was not "
                  "kept (" + (start_note_.empty() ? std::string("no snapshot of it") : start_note_) + ")");
  const TimePoint expected_start = redo ? t_before_last_ : t_now_;
  const TimePoint t_start = time_point_ns(q.t_start_ns), t_end = time_point_ns(q.t_end_ns);
  if (t_start != expected_start || t_end <= t_start || t_end > run_.t_end)
    return refuse(q, step_reply_t::REJECTED,
                  "step " + std::to_string(q.step_index) + " spans [" +
                      std::to_string(q.t_start_ns) + ", " + std::to_string(q.t_end_ns) +
                      "] ns but must start at " + std::to_string(to_ns(expected_start)) +
                      " ns and end after it, no later than " + std::to_string(to_ns(run_.t_end)));
  if ((t_end - t_start) % model_.inner_step() != Duration::zero())
    return refuse(q, step_reply_t::REJECTED,
                  "step length " + std::to_string(q.t_end_ns - q.t_start_ns) +
                      " ns is not a multiple of the inner step " +
                      std::to_string(to_ns(model_.inner_step())) + " ns");
  return run_step(q);
}

step_reply_t ParticipantCore::run_step(const step_request_t& q) {
  Polynomials inputs;
  try {
    inputs = from_message(q.inputs, "step " + std::to_string(q.step_index));
    Signals kinds;  // check names and kinds against the declaration
    for (const auto& [n, p] : inputs) kinds[n] = Signal{p.kind, {}};
    check_against_ports(kinds, inputs_, "step " + std::to_string(q.step_index) + " inputs");
  } catch (const ProtocolError& e) {
    return refuse(q, step_reply_t::REJECTED, e.what());
  }
  const bool redo = q.step_index == last_step_;
  busy_iteration_ = q.iteration;
  busy_step_ = q.step_index;
  const Stopwatch started;
  StepResult result;
  // Whether the state at this step's start is kept now (a redo's snapshot is the one kept).
  bool kept = redo;
  try {
    if (redo) {
      model_.restore_snapshot();
    } else if (model_.can_repeat()) {
      if (q.no_redo) {
        model_.skip_snapshot();  // the master will not redo it: nothing to keep
      } else {
        model_.save_snapshot();
        kept = true;
      }
    }
    const StepInputs in(time_point_ns(q.t_start_ns), time_point_ns(q.t_end_ns), inputs);
    result = model_.step(in, q.want_average);
    check_against_ports(result.outputs, outputs_, "outputs");
    for (const auto& [n, s] : result.outputs) validate_value(s.kind, s.value, "output '" + n + "'");
    if (q.want_average && result.average) {
      check_against_ports(*result.average, outputs_, "averages");
      for (const auto& [n, s] : *result.average) validate_value(s.kind, s.value, "average '" + n + "'");
    }
    for (const auto& [n, v] : result.diagnostics)
      if (!valid_name(n)) throw ProtocolError("diagnostic name '" + n + "' is not valid");
    if (result.ended_at && (*result.ended_at < in.t_start() || *result.ended_at > in.t_end()))
      throw ProtocolError("the model says it ended at " + std::to_string(to_ns(*result.ended_at)) +
                          " ns, outside the step");
  } catch (const InputError& e) {
    busy_step_ = -1;
    if (model_.can_repeat() && !kept) {
      // no_redo: the state at the step's start was not kept, so it cannot be put back.
      start_kept_ = false;
      return refuse(q, step_reply_t::FAILED,
                    std::string(e.what()) + "; the step was sent with no_redo, so its start was not "
                    "kept and the participant cannot go back to it");
    }
    if (model_.can_repeat()) model_.restore_snapshot();
    // The snapshot is of this refused step's start now, not of the last step's.
    if (!redo) {
      start_kept_ = false;
      start_note_ = "a refused step replaced it";
    }
    return refuse(q, step_reply_t::REJECTED, e.what());
  } catch (const std::bad_alloc&) {
    busy_step_ = -1;
    return refuse(q, step_reply_t::FAILED,
                  "out of memory (std::bad_alloc) in the step of participant '" + name_ + "'");
  } catch (const std::exception& e) {
    busy_step_ = -1;
    return refuse(q, step_reply_t::FAILED, e.what());
  }
  const double seconds = started.seconds();
  step_reply_t r = refuse(q, step_reply_t::OK, "");
  r.outputs = to_message(result.outputs);
  r.has_average = q.want_average && result.average.has_value();
  if (r.has_average) r.average = to_message(*result.average);
  for (const auto& [n, v] : result.diagnostics) r.diagnostics.push_back({n, v});
  r.n_diagnostics = static_cast<int32_t>(r.diagnostics.size());
  r.compute_seconds = seconds;
  if (!redo) {
    t_before_last_ = time_point_ns(q.t_start_ns);
    start_kept_ = kept;
    start_note_ = kept ? "" : model_.can_repeat() ? "the master sent it with no_redo" : "";
  }
  t_now_ = time_point_ns(q.t_end_ns);
  if (result.ended_at) {  // the model ended itself: the reply says where, and no step follows
    r.status = step_reply_t::ENDED;
    r.message = result.ended_reason;
    r.t_end_ns = to_ns(*result.ended_at);
    t_now_ = *result.ended_at;
  }
  last_step_ = q.step_index;
  last_iteration_ = q.iteration;
  if (q.checkpoint) {
    try {
      if (checkpoint_folder_.empty() || !model_.can_checkpoint())
        throw std::runtime_error(checkpoint_folder_.empty()
                                     ? "no checkpoint folder was configured"
                                     : "this participant does not save checkpoints");
      write_checkpoint();
      r.checkpointed = true;
    } catch (const std::exception& e) {
      r = refuse(q, step_reply_t::FAILED,
                 "the checkpoint after step " + std::to_string(q.step_index) + " failed: " + e.what());
    }
  }
  cached_ = r;
  done_iteration_ = last_iteration_;
  done_step_ = last_step_;
  busy_step_ = -1;
  return r;
}

ParticipantArgs parse_participant_args(int argc, char** argv, bool require_config) {
  ParticipantArgs a;
  a.rest.push_back(argv[0]);
  std::vector<std::string> sets;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--set") {
      if (i + 1 >= argc) throw config::ConfigError("--set needs dotted.key=value");
      sets.push_back(argv[++i]);
    } else if (arg == "--name" || arg == "--bus" || arg == "--session" || arg == "--idle-timeout" ||
               arg == "--wait") {
      a.rest.push_back(argv[i]);
      if (i + 1 < argc) a.rest.push_back(argv[++i]);  // run_participant checks the value
    } else if (!arg.empty() && arg[0] == '-') {
      a.rest.push_back(argv[i]);  // --help, or an unknown option run_participant names
    } else if (a.config_path.empty()) {
      a.config_path = arg;
    } else {
      throw config::ConfigError("more than one config file given ('" + a.config_path + "', '" + arg + "')");
    }
  }
  if (a.config_path.empty() && require_config)
    throw config::ConfigError("no config file given (the first argument: CONFIG.yaml)");
  a.config = a.config_path.empty() ? YAML::Node(YAML::NodeType::Map) : config::load_file(a.config_path);
  if (!a.config || a.config.IsNull()) a.config = YAML::Node(YAML::NodeType::Map);
  for (const auto& s : sets) config::apply_override(a.config, s);
  if (!a.config_path.empty())
    a.config_dir = std::filesystem::path(a.config_path).parent_path().string();
  return a;
}

std::string out_of_memory_message(const std::string& program) {
  return program + ": out of memory (std::bad_alloc): the process stops; give it more memory (a "
                   "host or limit with more free memory, or a smaller model, mesh or input)";
}

int participant_main(const std::string& program, const std::function<int()>& body) {
  try {
    return body();
  } catch (const std::bad_alloc&) {
    std::cerr << out_of_memory_message(program) << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << program << ": error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace cosim
