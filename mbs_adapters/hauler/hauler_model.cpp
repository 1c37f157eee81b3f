#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "hauler_model.hpp"

#include <cosim/yaml_config.hpp>

#include <cmath>
#include <sstream>

namespace hauler {

using namespace cosim;
namespace cfg = cosim::config;

namespace {
const char* const kScalars[] = {"front_fx",       "front_fz",      "rear1_fx",     "rear1_fz",
                                "rear2_fx",       "rear2_fz",      "front_stroke", "rear1_stroke",
                                "rear2_stroke",   "front_pressure", "rear_pressure", "hoist_force",
                                "body_angle"};

double norm(const V3& x) { return std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]); }
}  // namespace

HaulerModel::HaulerModel(YAML::Node machine_config) : base_(std::move(machine_config)) {}

void HaulerModel::configure(const YAML::Node& parameters, const RunInfo& run) {
  YAML::Node root = YAML::Clone(base_);
  if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  cfg::apply_overrides(root, parameters, "participants." + run.participant + ".parameters");
  run_ = run;
  p_ = read_parameters(root);
  inner_step_ = seconds_to_duration(p_.inner_step, "inner_step");
  if (inner_step_ <= Duration::zero()) throw cfg::ConfigError("inner_step: must be at least 1 ns");
  // Whether it divides the macro step is the master's check (check_wiring), once for everyone.
  try {
    model_ = std::make_unique<Hauler>(p_, to_seconds(run.t_start));
  } catch (const std::invalid_argument& e) {
    throw cfg::ConfigError(e.what());
  } catch (const std::runtime_error& e) {
    throw cfg::ConfigError(e.what());
  }
  scalars_.assign(std::begin(kScalars), std::end(kScalars));
  if (p_.test_payload) scalars_.push_back("payload_rigid");
}

Ports HaulerModel::inputs() const { return {{"body_wrench", SignalKind::Wrench}}; }

Ports HaulerModel::outputs() const {
  Ports p{{"body", SignalKind::Kinematics}};
  for (const auto& n : scalars_) p.push_back({n, SignalKind::Scalar});
  return p;
}

HaulerModel::Sample HaulerModel::sample() const {
  Sample s;
  s.body = model_->body();
  const Reports r = model_->reports();
  s.scalars = {r.axle[kFront].fx,     r.axle[kFront].fz,     r.axle[kRear1].fx,
               r.axle[kRear1].fz,     r.axle[kRear2].fx,     r.axle[kRear2].fz,
               r.axle[kFront].stroke, r.axle[kRear1].stroke, r.axle[kRear2].stroke,
               r.front.pressure,      r.rear.pressure,       r.hoist_force,
               r.body_angle};
  if (p_.test_payload) s.scalars.push_back(p_.test_payload->mass);
  return s;
}

Signals HaulerModel::to_signals(const Sample& s) const {
  Signals out;
  out["body"] = {SignalKind::Kinematics, s.body.to_value()};
  for (std::size_t i = 0; i < scalars_.size(); ++i) out[scalars_[i]] = {SignalKind::Scalar, {s.scalars[i]}};
  return out;
}

Signals HaulerModel::initial_outputs() { return to_signals(sample()); }

// The wrench is checked at the start, middle and end of the step against the limits; the
// torque is taken about the body origin at the step's start.
void HaulerModel::check_input(const StepInputs& in) const {
  const V3 origin = model_->body().position;
  for (double s : {0.0, 0.5, 1.0}) {
    const TimePoint t =
        in.t_start() + nanoseconds(std::llround(s * static_cast<double>(to_ns(in.length()))));
    const Wrench w = Wrench::from_value(in.at("body_wrench", t)).shifted_to(origin);
    const double F = norm(w.force), T = norm(w.torque);
    std::ostringstream msg;
    if (!(F <= p_.max_force))
      msg << "body_wrench: force " << F << " N at t = " << to_seconds(t)
          << " s exceeds limits.max_force = " << p_.max_force
          << " N (a DEM blow-up or a unit error? raise limits.max_force if it is real)";
    else if (!(T <= p_.max_torque))
      msg << "body_wrench: torque about the body origin " << T << " N m at t = " << to_seconds(t)
          << " s exceeds limits.max_torque = " << p_.max_torque
          << " N m (is the reference point r the body origin the DEM was given?)";
    if (!msg.str().empty()) throw InputError(msg.str());
  }
}

StepResult HaulerModel::step(const StepInputs& in, bool want_average) {
  check_input(in);
  const InputPolynomial poly = in.polynomial("body_wrench");
  const double t0 = to_seconds(in.t_start()), H = to_seconds(in.length());
  model_->set_body_wrench(
      [poly, t0, H](double t) { return Wrench::from_value(poly.evaluate((t - t0) / H)); });
  StepResult result;
  if (!want_average) {
    model_->advance(to_seconds(in.t_end()));
  } else {
    // trapezoid average over the inner steps, component by component; the orientation as the
    // normalized mean quaternion (its sign kept on the start's hemisphere)
    const Sample first = sample();
    Sample last = first, sum = first;
    Value body_sum = first.body.to_value();
    for (auto& v : body_sum) v *= 0.5;
    for (auto& v : sum.scalars) v *= 0.5;
    auto add_half = [&](const Sample& x) {
      const Value b = x.body.to_value();
      for (std::size_t i = 0; i < b.size(); ++i) body_sum[i] += b[i] * 0.5;
      for (std::size_t i = 0; i < sum.scalars.size(); ++i) sum.scalars[i] += x.scalars[i] * 0.5;
    };
    int n = 0;
    model_->advance(to_seconds(in.t_end()), [&] {
      if (n > 0) add_half(last);
      last = sample();
      Quat& q = last.body.orientation;
      const Quat& q0 = first.body.orientation;
      if (q[0] * q0[0] + q[1] * q0[1] + q[2] * q0[2] + q[3] * q0[3] < 0)
        for (double& c : q) c = -c;
      add_half(last);
      ++n;
    });
    for (auto& v : body_sum) v /= n;
    for (auto& v : sum.scalars) v /= n;
    sum.body = Kinematics::from_value(body_sum);
    sum.body.orientation = quat_normalized(sum.body.orientation);
    result.average = to_signals(sum);
  }
  result.outputs = to_signals(sample());
  const Reports r = model_->reports();
  result.diagnostics = {{"kinetic_energy", r.kinetic_energy},
                        {"front_oil", r.front.oil},
                        {"rear_oil", r.rear.oil},
                        {"front_level_flow", r.front.flow},
                        {"rear_level_flow", r.rear.flow},
                        {"front_ride_filtered", r.front.ride_filtered},
                        {"rear_ride_filtered", r.rear.ride_filtered},
                        {"hoist_length", r.hoist_length},
                        {"pitch", r.pitch}};
  return result;
}

void HaulerModel::load_checkpoint(const std::string& path) {
  model_->load_state(path);
  const double t = cosim::to_seconds(run_.resume_time);
  if (std::abs(model_->time() - t) > 1e-9 * std::max(1.0, std::abs(t)))
    throw std::runtime_error("its state is at t = " + std::to_string(model_->time()) + " s, the resume at " +
                             std::to_string(t) + " s");
}

}  // namespace hauler
