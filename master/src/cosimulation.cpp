#include "cosimulation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <cosim/bus.hpp>
#include <cosim/quantities.hpp>
#include <cosim/stopwatch.hpp>

namespace master {

using cosim::InputPolynomial;
using cosim::Kinematics;
using cosim::SignalKind;
using cosim::Value;
using cosim::Wrench;

namespace {

std::vector<double> deviation(SignalKind kind, const Value& predicted, const Value& received) {
  if (kind == SignalKind::Kinematics)
    return Kinematics::from_value(predicted).difference(Kinematics::from_value(received));
  std::vector<double> d(predicted.size());
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = predicted[i] - received[i];
  return d;
}

// Power of a force (scalar, or wrench) on a motion (scalar velocity, or kinematics): F v, or
// Wrench::power.
double power(SignalKind kind, const Value& F, const Value& V) {
  if (kind == SignalKind::Scalar) return F[0] * V[0];
  return Wrench::from_value(F).power(Kinematics::from_value(V));
}

}  // namespace

CoSimulation::CoSimulation(const Config& config, cosim::Transport& transport,
                           std::unique_ptr<CouplingAlgorithm> algorithm)
    : config_(config), transport_(transport), algorithm_(std::move(algorithm)) {
  if (!algorithm_) algorithm_ = make_algorithm(config);
  algorithm_->setup(config);
}

void CoSimulation::set_checkpoints(int64_t run_id, std::string folder) {
  run_id_ = run_id;
  checkpoint_folder_ = std::move(folder);
}

void CoSimulation::set_resume(ResumePoint resume) { resume_ = std::move(resume); }

bool CoSimulation::checkpoint_due(int64_t step, TimePoint t0, TimePoint t1) {
  if (config_.checkpoints.every <= Duration::zero()) return false;
  // A rejected attempt of a due step wrote its checkpoint file: the redo rewrites it.
  if (step == due_step_) return true;
  // Not after the last step: the run is over then. With fixed steps of H and every = m H this
  // is (step + 1) % m == 0.
  const Duration every = config_.checkpoints.every;
  if (t1 >= config_.t_end || (t1 - config_.t_start) / every == (t0 - config_.t_start) / every) return false;
  due_step_ = step;
  return true;
}

TimePoint CoSimulation::time_after(int64_t steps) const {
  if (resume_ && !resume_->times.empty() && steps <= resume_->steps_done)
    return resume_->times.at(static_cast<std::size_t>(steps));
  return config_.t_start + steps * config_.macro_step;
}

void CoSimulation::emit(StepRecord& rec) {
  if (rec.checkpoint) rec.algorithm_state = algorithm_->save_state();
  for (auto* o : observers_) o->on_step(rec);
}

void CoSimulation::connect() {
  const int64_t resume_steps = resume_ ? resume_->steps_done : 0;
  if ((config_.checkpoints.every > Duration::zero() || resume_) &&
      (run_id_ == 0 || checkpoint_folder_.empty()))
    throw std::logic_error("checkpoints without a run id or folder (set_checkpoints)");
  std::vector<cosim::configure_t> configs;
  for (const auto& p : config_.participants) {
    cosim::configure_t c{};
    c.protocol_version = cosim::kProtocolVersion;
    c.session_id = transport_.session();
    c.participant = p.name;
    c.t_start_ns = cosim::to_ns(config_.t_start);
    c.t_end_ns = cosim::to_ns(config_.t_end);
    c.macro_step_ns = cosim::to_ns(config_.macro_step);
    c.parameters_yaml = p.parameters_yaml;
    c.checkpoint_folder = checkpoint_folder_;
    c.run_id = run_id_;
    c.resume_steps_done = resume_steps;
    c.resume_t_ns = cosim::to_ns(time_after(resume_steps));
    configs.push_back(c);
  }
  setup_.config = &config_;
  setup_.session = transport_.session();
  setup_.bus = &transport_.stats();
  setup_.participants = transport_.connect(configs, config_.connect_timeout);
  check_wiring(config_, setup_.participants);
  setup_.steps = (config_.t_end - config_.t_start) / config_.macro_step;
  setup_.run_id = run_id_;
  setup_.checkpoint_folder = checkpoint_folder_;
  setup_.first_step = resume_steps;
  setup_.first_time = time_after(resume_steps);
  if (config_.checkpoints.every > Duration::zero()) {
    // A resumed participant that cannot checkpoint has refused its configuration already.
    std::string cannot;
    for (const auto& [name, info] : setup_.participants)
      if (!info.can_checkpoint) cannot += (cannot.empty() ? "'" : ", '") + name + "'";
    if (!cannot.empty())
      throw cosim::config::ConfigError(
          "checkpoints.every: participant(s) " + cannot +
          " cannot save checkpoints, so the run could not be resumed from them; set "
          "checkpoints.every: 0 (no checkpoints, no --resume) or replace the participant");
  }
  start_predictors();
  algorithm_->initialize({&setup_.participants, max_order_});
  if (resume_ && !resume_->algorithm_state.empty()) {
    try {
      algorithm_->restore_state(resume_->algorithm_state);
    } catch (const std::exception& e) {
      throw cosim::config::ConfigError("--resume: the record's /checkpoint/algorithm_state cannot be restored (" +
                                       std::string(e.what()) + "); the record is damaged or of another build");
    }
  }
}

void CoSimulation::start_predictors() {
  const int64_t resume_steps = resume_ ? resume_->steps_done : 0;
  predictors_.clear();
  max_order_ = 0;
  for (std::size_t i = 0; i < config_.connections.size(); ++i) {
    const auto& k = config_.connections[i];
    const auto& src = setup_.participants.at(k.from.participant);
    const auto& initial = src.initial_outputs.at(k.from.signal);
    predictors_.emplace_back(initial.kind, k.predictor, k.use);
    max_order_ = std::max(max_order_, k.predictor.order);
    if (!resume_) {
      predictors_.back().record(config_.t_start, initial.value);
      continue;
    }
    // The history an uninterrupted run's predictor holds after steps_done steps: the same
    // values (the recorded ones are what it was given), at the same times. The predictor
    // keeps only the latest samples it needs.
    const auto& received = resume_->received.at(i);
    if (static_cast<int64_t>(received.size()) != resume_steps + 1)
      throw std::logic_error("resume: received history of the wrong length");
    for (int64_t j = 0; j <= resume_steps; ++j) {
      if (k.use == Use::Average && j > 0) continue;  // its samples: the initial output only
      predictors_.back().record(time_after(j), received[static_cast<std::size_t>(j)]);
    }
    if (k.use == Use::Average)
      for (int64_t j = 1; j <= resume_steps; ++j)
        predictors_.back().record_mean(time_after(j - 1), time_after(j),
                                       resume_->received_average.at(i).at(static_cast<std::size_t>(j)));
  }
}

std::vector<cosim::step_request_t> CoSimulation::requests(const std::vector<std::string>& group,
                                                          int64_t step, int iteration,
                                                          TimePoint t0, TimePoint t1,
                                                          bool checkpoint) {
  std::vector<cosim::step_request_t> out;
  for (const auto& name : group) {
    cosim::step_request_t q{};
    q.session_id = transport_.session();
    q.participant = name;
    q.step_index = step;
    q.iteration = iteration;
    q.attempt = 0;
    q.t_start_ns = cosim::to_ns(t0);
    q.t_end_ns = cosim::to_ns(t1);
    q.checkpoint = checkpoint;
    // The algorithm will not do this step again: the participant need not keep its start.
    q.no_redo = !algorithm_->may_repeat(step);
    // Asked of a source whose output feeds a `use: average` connection.
    q.want_average = false;
    for (const auto& k : config_.connections)
      q.want_average = q.want_average || (k.from.participant == name && k.use == Use::Average);
    cosim::Polynomials inputs;
    for (std::size_t i = 0; i < config_.connections.size(); ++i)
      if (config_.connections[i].to.participant == name)
        inputs[config_.connections[i].to.signal] = predictors_[i].predict(t0, t1);
    q.inputs = cosim::to_message(inputs);
    out.push_back(std::move(q));
  }
  return out;
}

std::vector<cosim::StepAnswer> CoSimulation::exchange_requests(const std::vector<cosim::step_request_t>& qs) {
  try {
    return transport_.exchange(qs);
  } catch (const cosim::MissingAverageError& e) {
    // The transport knows the participant, the config knows which connection asked.
    for (std::size_t i = 0; i < config_.connections.size(); ++i) {
      const auto& k = config_.connections[i];
      if (k.use == Use::Average && k.from.participant == e.participant())
        throw cosim::LinkError(e.participant(),
                               "connections." + std::to_string(i) + " (" + k.from.str() + " -> " +
                                   k.to.str() + ") has use: average, but " + e.what() +
                                   "; set use: end on this connection");
    }
    throw;
  }
}

void CoSimulation::open_step(int64_t step, TimePoint t0, TimePoint t1) {
  open_.emplace();
  open_->rec.step_index = step;
  open_->rec.t_start = t0;
  open_->rec.t_end = t1;
  open_->sent.resize(config_.connections.size());
  open_->end.resize(config_.connections.size());
  if (step == last_opened_) {  // a rejected step redone: on from the iterations already sent
    iteration_base_ = highest_iteration_ + 1;
  } else {
    iteration_base_ = 0;
    highest_iteration_ = -1;
  }
  last_opened_ = step;
  if (hold_) predictors_before_ = predictors_;
}

void CoSimulation::hold_step() {
  if (open_ || held_) throw std::logic_error("hold_step inside a macro step or with one held");
  hold_ = true;
}

void CoSimulation::commit_step(double step_error, int rejected) {
  hold_ = false;
  if (!held_) return;  // a participant ended inside the step: no record
  StepRecord& rec = *held_;
  rec.step_error = step_error;
  rec.rejected = rejected;
  // The rejected attempts' time belongs to this step.
  rec.wall_seconds += spent_.wall;
  rec.master_seconds += spent_.wall - spent_.waiting;
  for (const auto& [name, v] : spent_.compute) rec.compute_seconds[name] += v;
  for (const auto& [name, v] : spent_.round_trip) rec.round_trip_seconds[name] += v;
  spent_ = {};
  emit(rec);
  held_.reset();
}

void CoSimulation::reject_step() {
  if (!held_) throw std::logic_error("reject_step without a held step");
  spent_.wall += held_->wall_seconds;
  spent_.waiting += held_->wall_seconds - held_->master_seconds;
  for (const auto& [name, v] : held_->compute_seconds) spent_.compute[name] += v;
  for (const auto& [name, v] : held_->round_trip_seconds) spent_.round_trip[name] += v;
  held_.reset();
  predictors_ = predictors_before_;
  last_power_.clear();
}

cosim::Value CoSimulation::end_value(std::size_t i) const {
  if (!open_) throw std::logic_error("end_value outside a macro step");
  if (open_->end.at(i)) return *open_->end[i];
  const auto p = predictors_.at(i).predict(open_->rec.t_start, open_->rec.t_end);
  return config_.connections[i].use == Use::Average ? p.mean() : p.evaluate(1.0);
}

void CoSimulation::set_end_value(std::size_t i, const cosim::Value& value) {
  if (!open_) throw std::logic_error("set_end_value outside a macro step");
  const auto& k = config_.connections.at(i);
  cosim::Value v = value;
  const auto kind = setup_.participants.at(k.from.participant).initial_outputs.at(k.from.signal).kind;
  if (kind == SignalKind::Kinematics) {  // a mix of unit quaternions: back onto the unit sphere
    auto q = Kinematics::from_value(v);
    double n = 0;
    for (double e : q.orientation) n += e * e;
    n = std::sqrt(n);
    if (n > 0)
      for (double& e : q.orientation) e /= n;
    v = q.to_value();
  }
  if (k.use == Use::Average)
    predictors_[i].record_mean(open_->rec.t_start, open_->rec.t_end, v);
  else
    predictors_[i].record(open_->rec.t_end, v);
  open_->end[i] = std::move(v);
}

void CoSimulation::set_residuals(std::vector<double> residuals) {
  if (!open_) throw std::logic_error("set_residuals outside a macro step");
  open_->rec.coupling_residuals = std::move(residuals);
}

void CoSimulation::exchange(const std::vector<std::string>& group, int iteration, bool checkpoint) {
  if (!open_) throw std::logic_error("exchange outside a macro step");
  OpenStep& s = *open_;
  StepRecord& rec = s.rec;
  const TimePoint t0 = rec.t_start, t1 = rec.t_end;
  if (iteration > 0 && !s.first_pass) s.first_pass = OpenStep::Pass{s.sent, rec.outputs, s.averages};
  auto qs = requests(group, rec.step_index, iteration_base_ + iteration, t0, t1, checkpoint);
  highest_iteration_ = std::max(highest_iteration_, iteration_base_ + iteration);
  for (std::size_t i = 0; i < config_.connections.size(); ++i)
    for (const auto& name : group)
      if (config_.connections[i].to.participant == name) s.sent[i] = predictors_[i].predict(t0, t1);
  const cosim::Stopwatch wait;
  const auto answers = exchange_requests(qs);
  s.waiting += wait.seconds();
  for (std::size_t g = 0; g < group.size(); ++g) {
    const auto& name = group[g];
    rec.outputs[name] = answers[g].outputs;
    rec.diagnostics[name] = answers[g].diagnostics;
    // Every iteration's time counts (the map's value starts at 0).
    rec.compute_seconds[name] += answers[g].compute_seconds;
    rec.round_trip_seconds[name] += answers[g].round_trip_seconds;
    if (answers[g].average) s.averages[name] = *answers[g].average;
    if (answers[g].ended_at) note_end(name, answers[g], t0, t1);
    for (std::size_t i = 0; i < config_.connections.size(); ++i) {
      const auto& k = config_.connections[i];
      if (k.from.participant != name) continue;
      if (k.use == Use::Average) {  // the mean over this step: interpolation from now on
        predictors_[i].record_mean(t0, t1, answers[g].average->at(k.from.signal).value);
        s.end[i] = answers[g].average->at(k.from.signal).value;
      } else {
        predictors_[i].record(t1, answers[g].outputs.at(k.from.signal).value);
        s.end[i] = answers[g].outputs.at(k.from.signal).value;
      }
    }
  }
}

// A participant ended itself (step_reply_t::ENDED, an FMU's terminate) at `answer.ended_at`:
// the run ends with this step; when the end lies before t1 the step is not recorded (the
// others' outputs are at t1, this one's earlier).
void CoSimulation::note_end(const std::string& name, const cosim::StepAnswer& answer, TimePoint t0, TimePoint t1) {
  char text[96];
  std::snprintf(text, sizeof text, "participant '%s' ended the run at t = %.9g s: ", name.c_str(),
                cosim::to_seconds(*answer.ended_at));
  ended_ = text + answer.ended_reason;
  ended_inside_ = *answer.ended_at < t1;
  char tail[96];
  std::snprintf(tail, sizeof tail, "; recorded up to t = %.9g s", cosim::to_seconds(ended_inside_ ? t0 : t1));
  *ended_ += tail;
}

void CoSimulation::record_connections(OpenStep& s) const {
  StepRecord& rec = s.rec;
  for (std::size_t i = 0; i < config_.connections.size(); ++i) {
    const auto& k = config_.connections[i];
    ConnectionRecord c;
    c.sent = s.sent[i];
    c.received = rec.outputs.at(k.from.participant).at(k.from.signal).value;
    if (k.use == Use::Average) {
      c.predicted = s.sent[i].mean();
      c.received_average = s.averages.at(k.from.participant).at(k.from.signal).value;
      c.deviation = deviation(s.sent[i].kind, c.predicted, c.received_average);
    } else {
      c.predicted = s.sent[i].evaluate(1.0);
      c.deviation = deviation(s.sent[i].kind, c.predicted, c.received);
    }
    rec.connections.push_back(std::move(c));
  }
}

void CoSimulation::record_power(StepRecord& rec, bool any_connection) const {
  for (const auto& p : config_.power) {
    auto conn = [&](const Endpoint& from, const std::string& to) -> const ConnectionRecord& {
      for (std::size_t i = 0; i < config_.connections.size(); ++i)
        if (config_.connections[i].from.str() == from.str() && config_.connections[i].to.participant == to)
          return rec.connections[i];
      throw std::logic_error("power pair without connection");
    };
    const auto& f = conn(p.force, p.velocity.participant);
    const auto& v = conn(p.velocity, p.force.participant);
    const auto kind = !any_connection ? SignalKind::Scalar
                                      : (f.received.size() == 1 ? SignalKind::Scalar : SignalKind::Wrench);
    PowerRecord r;
    r.force_side = power(kind, f.received_for_power(), v.predicted);
    r.motion_side = power(kind, f.predicted, v.received_for_power());
    r.residual = r.force_side - r.motion_side;
    rec.power.push_back(r);
  }
}

void CoSimulation::close_step(int iterations, bool checkpoint) {
  if (!open_) throw std::logic_error("close_step outside a macro step");
  OpenStep& s = *open_;
  if (ended_inside_) {  // a participant ended before t1: not a row
    open_.reset();
    return;
  }
  s.rec.iterations = iterations;
  s.rec.checkpoint = checkpoint && !ended_;  // every reply confirmed it, or exchange() raised
  record_connections(s);
  record_power(s.rec, !s.sent.empty());
  s.rec.wall_seconds = s.wall.seconds();
  s.rec.master_seconds = s.rec.wall_seconds - s.waiting;
  last_power_.clear();
  if (s.first_pass) {
    OpenStep first;
    first.sent = s.first_pass->sent;
    first.rec.outputs = s.first_pass->outputs;
    first.averages = s.first_pass->averages;
    record_connections(first);
    record_power(first.rec, !first.sent.empty());
    for (const auto& p : first.rec.power) last_power_.emplace_back(p.force_side, p.motion_side);
  } else {
    for (const auto& p : s.rec.power) last_power_.emplace_back(p.force_side, p.motion_side);
  }
  if (hold_) {  // commit_step or reject_step decides
    held_ = std::move(s.rec);
  } else {
    emit(s.rec);
  }
  open_.reset();
}

void CoSimulation::run() {
  const int64_t step = setup_.first_step;
  try {
    // In the try: a record that cannot start (its file, its first rows) stops the participants
    // and closes the records as incomplete, as any failure of the run does.
    for (auto* o : observers_) o->on_start(setup_);
    algorithm_->run(*this, step, setup_.first_time, config_.t_end);
  } catch (const std::exception& e) {
    open_.reset();
    transport_.terminate(true, e.what());
    for (auto* o : observers_) o->on_finish(false, e.what());
    throw;
  }
  if (ended_) std::fprintf(stderr, "cosim_master: %s\n", ended_->c_str());
  transport_.terminate(false, ended_ ? *ended_ : "finished");
  for (auto* o : observers_) o->on_finish(true, ended_.value_or(""));
}

}  // namespace master
