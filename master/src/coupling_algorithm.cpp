#include "coupling_algorithm.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "acceleration.hpp"

namespace master {

cosim::Value Coupling::end_value(std::size_t) const {
  throw std::logic_error("this coupling cannot tell a connection's end value (implicit coupling needs a CoSimulation)");
}
void Coupling::set_end_value(std::size_t, const cosim::Value&) {
  throw std::logic_error("this coupling cannot set a connection's end value (implicit coupling needs a CoSimulation)");
}
void Coupling::set_residuals(std::vector<double>) {}
std::vector<std::pair<double, double>> Coupling::last_power() const {
  throw std::logic_error("this coupling cannot tell the power bonds (an adaptive step needs a CoSimulation)");
}

void Coupling::hold_step() {
  throw std::logic_error("this coupling cannot hold a step back (an adaptive step needs a CoSimulation)");
}
void Coupling::commit_step(double, int) {
  throw std::logic_error("this coupling cannot hold a step back (an adaptive step needs a CoSimulation)");
}
void Coupling::reject_step() {
  throw std::logic_error("this coupling cannot reject a step (an adaptive step needs a CoSimulation)");
}

void CouplingAlgorithm::restore_state(const std::string& state) {
  if (!state.empty())
    throw std::runtime_error(name() + " keeps no state between macro steps, but the checkpoint holds some");
}

namespace {

// An algorithm's state as lines "<key> <n> <number> ..." with numbers in C's %a (exact).
void put_line(std::string& out, const std::string& key, const std::vector<double>& values) {
  out += key + " " + std::to_string(values.size());
  char buf[64];
  for (double v : values) {
    std::snprintf(buf, sizeof buf, " %a", v);
    out += buf;
  }
  out += "\n";
}

// The numbers of line `key`; raises naming the key when it is missing or damaged.
std::vector<double> get_line(const std::string& text, const std::string& key) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream l(line);
    std::string k;
    std::size_t n = 0;
    if (!(l >> k) || k != key) continue;
    if (!(l >> n)) break;
    std::vector<double> v;
    std::string word;
    while (l >> word) {
      char* end = nullptr;
      v.push_back(std::strtod(word.c_str(), &end));
      if (!end || *end) throw std::runtime_error("algorithm state: '" + key + "' holds '" + word + "', not a number");
    }
    if (v.size() != n) break;
    return v;
  }
  throw std::runtime_error("algorithm state: '" + key + "' is missing or damaged");
}

}  // namespace

void CouplingAlgorithm::set_step(Duration) {
  throw std::logic_error(name() + " has no settable macro step");
}

namespace {

std::vector<std::vector<std::string>> scheme_groups(const Config& config) {
  std::vector<std::vector<std::string>> groups;
  if (config.scheme == Scheme::Jacobi) {
    groups.push_back({});
    for (const auto& p : config.participants) groups.back().push_back(p.name);
  } else {
    for (const auto& name : config.order) groups.push_back({name});
  }
  return groups;
}

}  // namespace

void CouplingAlgorithm::run(Coupling& coupling, int64_t first_step, TimePoint t, TimePoint t_end) {
  for (int64_t step = first_step; t < t_end && !coupling.ended(); ++step) {
    const Duration taken = do_step(coupling, step, t);
    if (taken <= Duration::zero())
      throw std::logic_error(name() + ": a macro step of zero length at step " + std::to_string(step));
    t += taken;
  }
}

std::string FixedStepAlgorithm::name() const {
  return scheme_ == Scheme::Jacobi ? "fixed step (Jacobi)" : "fixed step (Gauss-Seidel)";
}

void FixedStepAlgorithm::setup(const Config& config) {
  scheme_ = config.scheme;
  macro_step_ = config.macro_step;
  startup_iterations_ = config.startup_iterations;
  groups_ = scheme_groups(config);
}

void FixedStepAlgorithm::initialize(const AlgorithmSetup& setup) {
  max_order_ = setup.max_order;
  can_iterate_ = true;
  for (const auto& [name, info] : *setup.participants) can_iterate_ = can_iterate_ && info.can_repeat;
  // Start-up iterations redo the first steps from their start: every participant must be able
  // to. One that cannot is refused here, before any step, not skipped silently (the order the
  // run would reach depends on it).
  if (startup_iterations_ > 0 && max_order_ > 0)
    for (const auto& [name, info] : *setup.participants)
      if (!info.can_repeat)
        throw cosim::config::ConfigError(
            "startup_iterations: " + std::to_string(startup_iterations_) + " (with predictor order " +
            std::to_string(max_order_) + ") redoes the first steps, but participant '" + name +
            "' cannot repeat a step" + (info.repeat_note.empty() ? std::string() : " (" + info.repeat_note + ")") +
            "; set startup_iterations: 0 (the first steps then run once, at a lower start-up order) "
            "or make the participant able to repeat steps");
}

Duration FixedStepAlgorithm::do_step(Coupling& coupling, int64_t step, TimePoint t) {
  // The first steps have too few samples for the configured orders; iterating them (redo from
  // the step's start with the new end sample) keeps the start-up from capping the order.
  const bool iterate = step < max_order_ && can_iterate_;
  const int iterations = iterate ? 1 + startup_iterations_ : 1;
  const bool checkpoint = coupling.checkpoint_due(step, t, t + macro_step_);
  coupling.open_step(step, t, t + macro_step_);
  int done = 0;
  for (int it = 0; it < iterations && !coupling.ended(); ++it, ++done)
    for (const auto& group : groups_) {
      if (coupling.ended()) break;
      // The checkpoint goes with the last iteration: the state after it is the step's result.
      coupling.exchange(group, it, it + 1 == iterations && checkpoint);
    }
  coupling.close_step(done, checkpoint);
  return macro_step_;
}

// --- Implicit coupling

ImplicitAlgorithm::ImplicitAlgorithm() = default;
ImplicitAlgorithm::~ImplicitAlgorithm() = default;

std::string ImplicitAlgorithm::name() const {
  return std::string(scheme_ == Scheme::Jacobi ? "implicit (Jacobi" : "implicit (Gauss-Seidel") + ", " +
         acceleration_name(spec_.acceleration.type) + ")";
}

void ImplicitAlgorithm::setup(const Config& config) {
  if (config.coupling.type != CouplingType::Implicit)
    throw std::logic_error("ImplicitAlgorithm set up with coupling.type: explicit");
  scheme_ = config.scheme;
  macro_step_ = config.macro_step;
  startup_iterations_ = config.startup_iterations;
  spec_ = config.coupling;
  if (spec_.convergence.empty())
    throw cosim::config::ConfigError("coupling.convergence: missing (coupling.type: implicit needs at least one measure)");
  groups_ = scheme_groups(config);
  connection_names_.clear();
  for (const auto& k : config.connections) connection_names_.push_back(k.to.str());
  // A connection is fed back when its consumer steps before (or with) its source: its value at
  // the step's end is then a guess the iteration improves. Jacobi: every connection.
  auto group_of = [&](const std::string& name) {
    for (std::size_t g = 0; g < groups_.size(); ++g)
      for (const auto& n : groups_[g])
        if (n == name) return g;
    throw std::logic_error("participant in no group: " + name);
  };
  fed_back_.clear();
  for (std::size_t i = 0; i < config.connections.size(); ++i)
    if (group_of(config.connections[i].to.participant) <= group_of(config.connections[i].from.participant))
      fed_back_.push_back(i);
  scale_.assign(fed_back_.size(), 0.0);
  acceleration_ = make_acceleration(spec_.acceleration);
  steps_ = total_iterations_ = unconverged_ = rejected_iterations_ = 0;
}

void ImplicitAlgorithm::initialize(const AlgorithmSetup& setup) {
  max_order_ = setup.max_order;
  // Every iteration after the first repeats the step from its start: refused before any step.
  for (const auto& [name, info] : *setup.participants)
    if (!info.can_repeat)
      throw cosim::config::ConfigError(
          "coupling.type: implicit repeats every macro step from its start, but participant '" + name +
          "' cannot repeat a step" + (info.repeat_note.empty() ? std::string() : " (" + info.repeat_note + ")") +
          "; use coupling.type: explicit, or make the participant able to repeat steps");
}

namespace {

double norm(const cosim::Value& v) {
  double s = 0;
  for (double e : v) s += e * e;
  return std::sqrt(s);
}

std::string number(double v) {
  std::ostringstream o;
  o.precision(3);
  o << v;
  return o.str();
}

}  // namespace

Duration ImplicitAlgorithm::do_step(Coupling& coupling, int64_t step, TimePoint t) {
  const bool checkpoint = coupling.checkpoint_due(step, t, t + macro_step_);
  const std::size_t n = connection_names_.size();
  int min_iterations = spec_.min_iterations;
  if (step < max_order_) min_iterations = std::max(min_iterations, 1 + startup_iterations_);
  coupling.open_step(step, t, t + macro_step_);
  scale_before_ = scale_;
  last_unconverged_ = false;
  std::vector<cosim::Value> in(n), out(n);
  // Per entry of the flat vector the acceleration sees: 1 / the largest rms value its connection
  // has had (so that metres and newtons weigh alike in IQN-ILS's least squares).
  for (std::size_t f = 0; f < fed_back_.size(); ++f) {
    const auto v = coupling.end_value(fed_back_[f]);
    scale_[f] = std::max(scale_[f], norm(v) / std::sqrt(static_cast<double>(std::max<std::size_t>(v.size(), 1))));
  }
  std::vector<double> weights;
  for (std::size_t f = 0; f < fed_back_.size(); ++f) {
    const auto size = coupling.end_value(fed_back_[f]).size();
    weights.insert(weights.end(), size, scale_[f] > 0 ? 1.0 / scale_[f] : 1.0);
  }
  acceleration_->start_step(weights);
  std::vector<double> first(spec_.convergence.size(), 0.0), residuals(spec_.convergence.size(), 0.0);
  int k = 0;
  for (;; ++k) {
    for (std::size_t i = 0; i < n; ++i) in[i] = coupling.end_value(i);
    // Checkpoints are refused with implicit coupling (config.cpp): which iteration is the last
    // is known only after it.
    for (const auto& group : groups_)
      if (!coupling.ended()) coupling.exchange(group, k, checkpoint);
    if (coupling.ended()) break;  // a participant ended the run in this iteration: no more
    for (std::size_t i = 0; i < n; ++i) out[i] = coupling.end_value(i);
    bool all = true, any_sufficient = false;
    std::size_t worst = 0;
    double worst_ratio = -1;
    for (std::size_t c = 0; c < spec_.convergence.size(); ++c) {
      const auto& cs = spec_.convergence[c];
      cosim::Value r(out[cs.connection].size());
      for (std::size_t j = 0; j < r.size(); ++j) r[j] = out[cs.connection][j] - in[cs.connection][j];
      const double rn = norm(r), xn = norm(out[cs.connection]);
      if (k == 0) first[c] = rn;
      residuals[c] = rn;
      double ratio = 0;  // measure / limit: <= 1 is met
      switch (cs.measure) {
        case Measure::Absolute: ratio = rn / cs.limit; break;
        case Measure::Relative: ratio = rn == 0 ? 0 : rn / (cs.limit * xn); break;
        case Measure::ResidualRelative: ratio = rn == 0 ? 0 : rn / (cs.limit * first[c]); break;
        case Measure::AbsoluteOrRelative:
          ratio = std::min(rn / cs.limit, rn == 0 ? 0 : rn / (cs.relative_limit * xn));
          break;
      }
      const bool met = ratio <= 1;  // NaN: not met
      all = all && met;
      any_sufficient = any_sufficient || (met && cs.suffices);
      if (!met && !(ratio <= worst_ratio)) worst = c, worst_ratio = ratio;
    }
    const bool converged = all || any_sufficient;
    if (converged && k + 1 >= min_iterations) break;
    if (k + 1 >= spec_.max_iterations) {
      if (converged) break;
      const auto& cs = spec_.convergence[worst];
      const std::string what =
          "macro step " + std::to_string(step) + " (t = " + number(cosim::to_seconds(t)) + " s) did not converge in " +
          std::to_string(spec_.max_iterations) + " iterations: connection " + connection_names_[cs.connection] +
          " has residual |r| = " + number(residuals[worst]) + " (" + measure_name(cs.measure) + " measure at " +
          number(worst_ratio) + " x its limit)";
      if (spec_.stop_at_max)
        throw std::runtime_error(what + "; coupling.at_max_iterations: stop. Raise coupling.max_iterations, "
                                        "use an acceleration (coupling.acceleration.type: iqn_ils) or a smaller time.macro_step");
      if (unconverged_ < 10)
        std::fprintf(stderr, "cosim_master: warning: %s; accepted (coupling.at_max_iterations: accept)%s\n",
                     what.c_str(), unconverged_ == 9 ? "; further such warnings are not printed" : "");
      ++unconverged_;
      last_unconverged_ = true;
      break;
    }
    std::vector<double> x_in, x;
    for (std::size_t i : fed_back_) {
      x_in.insert(x_in.end(), in[i].begin(), in[i].end());
      x.insert(x.end(), out[i].begin(), out[i].end());
    }
    const auto next = acceleration_->next(x_in, x, k);
    std::size_t at = 0;
    for (std::size_t i : fed_back_) {
      const std::size_t size = in[i].size();
      coupling.set_end_value(i, cosim::Value(next.begin() + static_cast<std::ptrdiff_t>(at),
                                             next.begin() + static_cast<std::ptrdiff_t>(at + size)));
      at += size;
    }
  }
  acceleration_->end_step();
  coupling.set_residuals(residuals);
  coupling.close_step(k + 1, checkpoint);
  ++steps_;
  total_iterations_ += k + 1;
  last_iterations_ = k + 1;
  return macro_step_;
}

std::string ImplicitAlgorithm::save_state() const {
  std::string out;
  put_line(out, "implicit.scale", scale_);
  put_line(out, "implicit.acceleration", acceleration_->save());
  return out;
}

void ImplicitAlgorithm::restore_state(const std::string& state) {
  auto scale = get_line(state, "implicit.scale");
  if (scale.size() != scale_.size())
    throw std::runtime_error("algorithm state: " + std::to_string(scale.size()) + " connection scales for " +
                             std::to_string(scale_.size()) + " fed-back connections");
  acceleration_->restore(get_line(state, "implicit.acceleration"));
  scale_ = std::move(scale);
}

void ImplicitAlgorithm::forget_step() {
  scale_ = scale_before_;
  acceleration_->forget_step();
  --steps_;
  total_iterations_ -= last_iterations_;
  rejected_iterations_ += last_iterations_;
  if (last_unconverged_) --unconverged_;
}

// --- Adaptive macro step

AdaptiveStepAlgorithm::AdaptiveStepAlgorithm(std::unique_ptr<CouplingAlgorithm> inner) : inner_(std::move(inner)) {}

std::string AdaptiveStepAlgorithm::name() const { return inner_->name() + ", adaptive step"; }

void AdaptiveStepAlgorithm::setup(const Config& config) {
  inner_->setup(config);
  spec_ = config.coupling.adaptive;
  if (!spec_.enabled) throw std::logic_error("AdaptiveStepAlgorithm without coupling.adaptive");
  t_end_ = config.t_end;
  next_ = config.macro_step;
  wanted_ = cosim::to_seconds(config.macro_step);
  previous_error_ = 1.0;
  history_.clear();
  rejected_ = 0;
}

void AdaptiveStepAlgorithm::initialize(const AlgorithmSetup& setup) {
  inner_->initialize(setup);
  if (spec_.reject_above > 0)  // a rejected step is repeated from its start: refused before any step
    for (const auto& [name, info] : *setup.participants)
      if (!info.can_repeat)
        throw cosim::config::ConfigError(
            "coupling.adaptive.reject_above: " + number(spec_.reject_above) +
            " redoes a rejected macro step from its start, but participant '" + name + "' cannot repeat a step" +
            (info.repeat_note.empty() ? std::string() : " (" + info.repeat_note + ")") +
            "; set coupling.adaptive.reject_above: 0 (every step accepted), or make the participant able to repeat steps");
  // The quantum: the least common multiple of the inner steps (time.macro_step is a multiple of
  // each, check_wiring, so time.end - time.start is a multiple of the quantum too).
  int64_t q = 1;
  for (const auto& [name, info] : *setup.participants) {
    const int64_t inner = cosim::to_ns(info.inner_step);
    if (inner <= 0) continue;
    q = std::lcm(q, inner);
  }
  quantum_ = Duration(q);
  min_ = ((spec_.min_step + quantum_ - Duration(1)) / quantum_) * quantum_;  // rounded up
  max_ = (spec_.max_step / quantum_) * quantum_;                            // rounded down
  if (max_ < min_ || max_ <= Duration::zero())
    throw cosim::config::ConfigError(
        "coupling.adaptive: no whole multiple of every participant's inner step (their least common multiple: " +
        std::to_string(q) + " ns) lies in [min_step, max_step] = [" + number(cosim::to_seconds(spec_.min_step)) + ", " +
        number(cosim::to_seconds(spec_.max_step)) + "] s; widen the bounds");
}

namespace {

// ECCO's error estimate: per power bond the energy residual over the step against the
// tolerance abs + rel x the energy through the bond; the largest one counts.
double ecco_error(const std::vector<std::pair<double, double>>& bonds, Duration taken, const AdaptiveSpec& spec) {
  const double h = cosim::to_seconds(taken);
  double error = 0;
  for (const auto& [force_side, motion_side] : bonds) {
    const double residual = std::abs(force_side - motion_side) * h;
    const double through = std::max(std::abs(force_side), std::abs(motion_side)) * h;
    if (std::isfinite(residual)) error = std::max(error, residual / (spec.abs_tolerance + spec.rel_tolerance * through));
    else error = std::numeric_limits<double>::infinity();
  }
  return error;
}

}  // namespace

Duration AdaptiveStepAlgorithm::fit(Duration H, TimePoint t) const {
  // What would be left after H: nothing, or at least min_step (the last step is then no shorter
  // than min_step unless the whole run is). Else H leaves min_step, or takes the rest.
  const Duration rest = t_end_ - t;
  if (H >= rest) return rest;
  if (rest - H >= min_) return H;
  return rest - min_ >= min_ ? rest - min_ : rest;
}

Duration AdaptiveStepAlgorithm::do_step(Coupling& coupling, int64_t step, TimePoint t) {
  Duration H = fit(next_, t);
  int rejected = 0;
  Duration taken{};
  double error = 0;
  for (;;) {
    inner_->set_step(H);
    coupling.hold_step();
    taken = inner_->do_step(coupling, step, t);
    error = ecco_error(coupling.last_power(), taken, spec_);
    // Rejected: above the threshold (or not finite), longer than min_step, and no participant
    // has ended the run in it. Redone with the I part of the controller only (the step's own
    // error says how much shorter), at most min_change and at least one quantum shorter.
    if (!(spec_.reject_above > 0 && !(error <= spec_.reject_above) && taken > min_ && !coupling.ended())) break;
    // The energy residual of a step falls about as H^2 (first-order extrapolation): the redo's
    // length from the square root, at least 10 % shorter, at most min_change shorter.
    double factor = std::isfinite(error) ? spec_.safety * std::sqrt(1.0 / error) : spec_.min_change;
    factor = std::clamp(factor, spec_.min_change, 0.9);
    const Duration shorter = static_cast<int64_t>(std::floor(cosim::to_seconds(taken) * factor * 1e9 /
                                                             static_cast<double>(quantum_.count()))) * quantum_;
    const Duration redo = fit(std::clamp(std::min(shorter, taken - quantum_), min_, max_), t);
    // Near time.end the rest may allow no shorter step that leaves min_step: accepted then.
    if (redo >= taken) break;
    history_.push_back({t, taken, error, true});
    ++rejected_;
    ++rejected;
    coupling.reject_step();
    inner_->forget_step();
    H = redo;
  }
  history_.push_back({t, taken, error, false});
  // PI controller: factor = safety (1/e_n)^i_gain (e_(n-1)/e_n)^p_gain, within [min_change,
  // max_change]; not above 1 right after a rejection.
  double factor = spec_.max_change;
  if (error > 0 && std::isfinite(error))
    factor = spec_.safety * std::pow(1.0 / error, spec_.i_gain) * std::pow(previous_error_ / error, spec_.p_gain);
  else if (!std::isfinite(error))
    factor = spec_.min_change;
  factor = std::clamp(std::isfinite(factor) ? factor : spec_.max_change, spec_.min_change, spec_.max_change);
  if (rejected > 0) factor = std::min(factor, 1.0);
  if (error > 0 && std::isfinite(error)) previous_error_ = error;
  // The controller's step is continuous; the step taken is the largest whole multiple of the
  // quantum not above it. A step taken as planned continues from the controller's own length,
  // so that growth by less than one quantum per step adds up (rounding the taken step down and
  // multiplying that would hold a step of one quantum there forever at any factor below 2). A
  // step cut short (time.end, a redo) continues from what was taken.
  const double basis = (taken == next_ && rejected == 0) ? wanted_ : cosim::to_seconds(taken);
  wanted_ = std::clamp(basis * factor, cosim::to_seconds(min_), cosim::to_seconds(max_));
  const Duration next = static_cast<int64_t>(std::floor(wanted_ * 1e9 / static_cast<double>(quantum_.count()))) * quantum_;
  next_ = std::clamp(next, min_, max_);
  // After the update: a checkpoint after this step saves the state the next step starts from.
  coupling.commit_step(error, rejected);
  return taken;
}

std::string AdaptiveStepAlgorithm::save_state() const {
  std::string out;
  put_line(out, "adaptive", {static_cast<double>(next_.count()), previous_error_, static_cast<double>(rejected_), wanted_});
  return out + inner_->save_state();
}

void AdaptiveStepAlgorithm::restore_state(const std::string& state) {
  const auto a = get_line(state, "adaptive");
  // 4 numbers: next step, last error, rejections, the controller's continuous step (s); a record
  // of an earlier version holds the first 3 (the continuous step is then the next step).
  if ((a.size() != 3 && a.size() != 4) || !(a[0] > 0) || a[0] != std::floor(a[0]) || !(a[1] > 0) || !(a[2] >= 0) ||
      (a.size() == 4 && !(a[3] > 0 && std::isfinite(a[3]))))
    throw std::runtime_error("algorithm state: 'adaptive' holds no step, error, count and controller step");
  const Duration next(static_cast<int64_t>(a[0]));
  if (next < min_ || next > max_ || next % quantum_ != Duration::zero())
    throw std::runtime_error("algorithm state: the next step " + std::to_string(next.count()) +
                             " ns is not a multiple of the inner steps within the bounds");
  std::string inner;  // the inner algorithm's lines
  std::istringstream in(state);
  for (std::string line; std::getline(in, line);)
    if (line.rfind("adaptive ", 0) != 0) inner += line + "\n";
  inner_->restore_state(inner);
  next_ = next;
  wanted_ = a.size() == 4 ? a[3] : cosim::to_seconds(next);
  previous_error_ = a[1];
  rejected_ = static_cast<int64_t>(a[2]);
}

std::unique_ptr<CouplingAlgorithm> make_algorithm(const Config& config) {
  std::unique_ptr<CouplingAlgorithm> a;
  if (config.coupling.type == CouplingType::Implicit) a = std::make_unique<ImplicitAlgorithm>();
  else a = std::make_unique<FixedStepAlgorithm>();
  if (config.coupling.adaptive.enabled) return std::make_unique<AdaptiveStepAlgorithm>(std::move(a));
  return a;
}

}  // namespace master
