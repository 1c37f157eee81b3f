#include "coupling_algorithm.hpp"

namespace master {

void CouplingAlgorithm::run(Coupling& coupling, int64_t first_step, TimePoint t, TimePoint t_end) {
  for (int64_t step = first_step; t < t_end; ++step) {
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
  groups_.clear();
  if (config.scheme == Scheme::Jacobi) {
    groups_.push_back({});
    for (const auto& p : config.participants) groups_.back().push_back(p.name);
  } else {
    for (const auto& name : config.order) groups_.push_back({name});
  }
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
  const bool checkpoint = coupling.checkpoint_due(step);
  coupling.open_step(step, t, t + macro_step_);
  for (int it = 0; it < iterations; ++it)
    for (const auto& group : groups_)
      // The checkpoint goes with the last iteration: the state after it is the step's result.
      coupling.exchange(group, it, it + 1 == iterations && checkpoint);
  coupling.close_step(iterations, checkpoint);
  return macro_step_;
}

std::unique_ptr<CouplingAlgorithm> make_algorithm(const Config& config) {
  (void)config;  // scheme and step size are the fixed step's; an implicit or adaptive one goes here
  return std::make_unique<FixedStepAlgorithm>();
}

}  // namespace master
