#include "machine_adapter.hpp"

#include <cosim/yaml_config.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <new>
#include <sstream>
#include <stdexcept>

namespace mbs {

using namespace cosim;
namespace cfg = cosim::config;

void MachineAdapter::configure(const YAML::Node& parameters, const RunInfo& run) {
  YAML::Node root = YAML::Clone(base_);
  if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  cfg::apply_overrides(root, parameters, "participants." + run.participant + ".parameters");
  run_ = run;
  settings_ = read(root);
  wrench_ = settings_.body + "_wrench";
  inner_step_ = seconds_to_duration(settings_.inner_step, "inner_step");
  if (inner_step_ <= Duration::zero()) throw cfg::ConfigError("inner_step: must be at least 1 ns");
  // Whether it divides the macro step is the master's check (check_wiring), once for everyone.
  try {
    machine_ = build(to_seconds(run.t_start));
  } catch (const std::invalid_argument& e) {
    throw cfg::ConfigError(e.what());
  } catch (const std::runtime_error& e) {
    throw cfg::ConfigError(e.what());
  }
}

Ports MachineAdapter::inputs() const { return {{wrench_, SignalKind::Wrench}}; }

Ports MachineAdapter::outputs() const {
  Ports p{{settings_.body, SignalKind::Kinematics}};
  for (const auto& n : settings_.scalars) p.push_back({n, SignalKind::Scalar});
  return p;
}

MachineSample MachineAdapter::sample() const { return {machine_->coupled_body(), scalars()}; }

Signals MachineAdapter::to_signals(const MachineSample& s) const {
  Signals out;
  out[settings_.body] = {SignalKind::Kinematics, s.body.to_value()};
  for (std::size_t i = 0; i < settings_.scalars.size(); ++i)
    out[settings_.scalars[i]] = {SignalKind::Scalar, {s.scalars[i]}};
  return out;
}

Signals MachineAdapter::initial_outputs() { return to_signals(sample()); }

// The wrench is checked at the start, middle and end of the step against the limits; the
// torque is taken about the body origin at the step's start.
void MachineAdapter::check_input(const StepInputs& in) const {
  const V3 origin = machine_->coupled_body().position;
  for (double s : {0.0, 0.5, 1.0}) {
    const TimePoint t =
        in.t_start() + nanoseconds(std::llround(s * static_cast<double>(to_ns(in.length()))));
    const Wrench w = Wrench::from_value(in.at(wrench_, t)).shifted_to(origin);
    const double F = norm(w.force), T = norm(w.torque);
    std::ostringstream msg;
    if (!(F <= settings_.max_force))
      msg << wrench_ << ": force " << F << " N at t = " << to_seconds(t)
          << " s exceeds limits.max_force = " << settings_.max_force
          << " N (a DEM blow-up or a unit error? raise limits.max_force if it is real)";
    else if (!(T <= settings_.max_torque))
      msg << wrench_ << ": torque about the " << settings_.body << " origin " << T << " N m at t = "
          << to_seconds(t) << " s exceeds limits.max_torque = " << settings_.max_torque
          << " N m (is the reference point r the " << settings_.body << " origin the DEM was given?)";
    if (!msg.str().empty()) throw InputError(msg.str());
  }
}

StepResult MachineAdapter::step(const StepInputs& in, bool want_average) {
  check_input(in);
  const InputPolynomial poly = in.polynomial(wrench_);
  const double t0 = to_seconds(in.t_start()), H = to_seconds(in.length());
  machine_->set_wrench([poly, t0, H](double t) { return Wrench::from_value(poly.evaluate((t - t0) / H)); });
  StepResult result;
  if (!want_average) {
    machine_->advance(to_seconds(in.t_end()));
  } else {
    IntervalAverage average(sample());
    machine_->advance(to_seconds(in.t_end()), [&] { average.add(sample()); });
    result.average = to_signals(average.mean());
  }
  result.outputs = to_signals(sample());
  result.diagnostics = diagnostics();
  return result;
}

void MachineAdapter::load_checkpoint(const std::string& path) {
  machine_->load_state(path);
  const double t = to_seconds(run_.resume_time);
  if (std::abs(machine_->time() - t) > 1e-9 * std::max(1.0, std::abs(t)))
    throw std::runtime_error("its state is at t = " + std::to_string(machine_->time()) +
                             " s, the resume at " + std::to_string(t) + " s");
}

int serve_machine(int argc, char** argv, const std::string& program, const std::string& default_name,
                  const std::function<std::unique_ptr<MachineAdapter>(YAML::Node config)>& make) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  ParticipantArgs args;
  std::unique_ptr<MachineAdapter> adapter;
  try {
    args = parse_participant_args(argc, argv, false);
    adapter = make(args.config);
    adapter->check(args.config);  // refuse a bad file before joining any session
  } catch (const std::bad_alloc&) {
    std::cerr << out_of_memory_message(program) << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << program << ": " << (args.config_path.empty() ? "" : args.config_path + ": ")
              << e.what() << "\n"
              << "usage: " << program << " [CONFIG.yaml] [--set key=value ...] [--name NAME] "
                 "[--bus URL]\n";
    return 2;
  }
  return participant_main(program, [&] {
    return run_participant(*adapter, default_name, static_cast<int>(args.rest.size()), args.rest.data());
  });
}

}  // namespace mbs
