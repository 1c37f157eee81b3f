#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "wheel_loader_model.hpp"

#include <cosim/yaml_config.hpp>

#include <cmath>
#include <sstream>

namespace wheel_loader {

using namespace cosim;
namespace cfg = cosim::config;

namespace {
const char* const kScalars[] = {"a_long", "a_vert", "j_long", "j_vert", "lift_force",
                                "tilt_force", "speed", "x_machine", "drive_force",
                                "normal_load", "bucket_pitch", "boom_angle", "edge_x", "edge_z"};
constexpr int kNumScalars = sizeof(kScalars) / sizeof(kScalars[0]);

double norm(const V3& x) { return std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]); }
}  // namespace

struct WheelLoaderModel::Sample {
  Kinematics bucket;
  double scalars[kNumScalars];
};

WheelLoaderModel::WheelLoaderModel(YAML::Node machine_config) : base_(std::move(machine_config)) {}

void WheelLoaderModel::configure(const YAML::Node& parameters, const RunInfo& run) {
  YAML::Node root = YAML::Clone(base_);
  if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  cfg::apply_overrides(root, parameters, "participants." + run.participant + ".parameters");
  run_ = run;
  p_ = read_parameters(root);
  inner_step_ = seconds_to_duration(p_.inner_step, "inner_step");
  if (inner_step_ <= Duration::zero()) throw cfg::ConfigError("inner_step: must be at least 1 ns");
  // Whether it divides the macro step is the master's check (check_wiring), once for everyone.
  try {
    model_ = std::make_unique<WheelLoader>(p_, to_seconds(run.t_start));
  } catch (const std::invalid_argument& e) {
    throw cfg::ConfigError(e.what());
  } catch (const std::runtime_error& e) {
    throw cfg::ConfigError(e.what());
  }
}

Ports WheelLoaderModel::inputs() const { return {{"bucket_wrench", SignalKind::Wrench}}; }

Ports WheelLoaderModel::outputs() const {
  Ports p{{"bucket", SignalKind::Kinematics}};
  for (const char* n : kScalars) p.push_back({n, SignalKind::Scalar});
  return p;
}

WheelLoaderModel::Sample WheelLoaderModel::sample() const {
  Sample s;
  s.bucket = model_->bucket();
  const Reports r = model_->reports();
  const V3 edge = model_->cutting_edge();
  const double v[kNumScalars] = {r.a_long, r.a_vert, r.j_long, r.j_vert, r.lift_force,
                                 r.tilt_force, r.speed, r.x_machine, r.drive_force,
                                 r.normal_load, r.bucket_pitch, r.boom_angle, edge[0], edge[2]};
  std::copy(v, v + kNumScalars, s.scalars);
  return s;
}

namespace {
Signals to_signals(const Kinematics& bucket, const double* scalars) {
  Signals out;
  out["bucket"] = {SignalKind::Kinematics, bucket.to_value()};
  for (int i = 0; i < kNumScalars; ++i) out[kScalars[i]] = {SignalKind::Scalar, {scalars[i]}};
  return out;
}
}  // namespace

Signals WheelLoaderModel::initial_outputs() {
  const Sample s = sample();
  return to_signals(s.bucket, s.scalars);
}

// The wrench is checked at the start, middle and end of the step against the limits; the
// torque is taken about the bucket origin at the step's start.
void WheelLoaderModel::check_input(const StepInputs& in) const {
  const V3 origin = model_->bucket().position;
  for (double s : {0.0, 0.5, 1.0}) {
    const TimePoint t =
        in.t_start() + nanoseconds(std::llround(s * static_cast<double>(to_ns(in.length()))));
    const Wrench w = Wrench::from_value(in.at("bucket_wrench", t)).shifted_to(origin);
    const double F = norm(w.force), T = norm(w.torque);
    std::ostringstream msg;
    if (F > p_.max_force)
      msg << "bucket_wrench: force " << F << " N at t = " << to_seconds(t)
          << " s exceeds limits.max_force = " << p_.max_force
          << " N (a DEM blow-up or a unit error? raise limits.max_force if it is real)";
    else if (T > p_.max_torque)
      msg << "bucket_wrench: torque about the bucket origin " << T << " N m at t = "
          << to_seconds(t) << " s exceeds limits.max_torque = " << p_.max_torque
          << " N m (is the reference point r the bucket origin the DEM was given?)";
    if (!msg.str().empty()) throw InputError(msg.str());
  }
}

StepResult WheelLoaderModel::step(const StepInputs& in, bool want_average) {
  check_input(in);
  const InputPolynomial poly = in.polynomial("bucket_wrench");
  const double t0 = to_seconds(in.t_start()), H = to_seconds(in.length());
  model_->set_bucket_wrench(
      [poly, t0, H](double t) { return Wrench::from_value(poly.evaluate((t - t0) / H)); });
  StepResult result;
  if (!want_average) {
    model_->advance(to_seconds(in.t_end()));
  } else {
    // trapezoid average over the inner steps, component by component; the orientation as the
    // normalized mean quaternion (its sign kept on the start's hemisphere)
    const Sample first = sample();
    Sample last = first, sum = first;
    Value bucket_sum = first.bucket.to_value();
    for (auto& v : bucket_sum) v *= 0.5;
    for (auto& v : sum.scalars) v *= 0.5;
    auto add_half = [&](const Sample& x) {
      const Value b = x.bucket.to_value();
      for (std::size_t i = 0; i < b.size(); ++i) bucket_sum[i] += b[i] * 0.5;
      for (int i = 0; i < kNumScalars; ++i) sum.scalars[i] += x.scalars[i] * 0.5;
    };
    int n = 0;
    model_->advance(to_seconds(in.t_end()), [&] {
      if (n > 0) add_half(last);
      last = sample();
      Quat& q = last.bucket.orientation;
      const Quat& q0 = first.bucket.orientation;
      if (q[0] * q0[0] + q[1] * q0[1] + q[2] * q0[2] + q[3] * q0[3] < 0)
        for (double& c : q) c = -c;
      add_half(last);
      ++n;
    });
    for (auto& v : bucket_sum) v /= n;
    for (auto& v : sum.scalars) v /= n;
    sum.bucket = Kinematics::from_value(bucket_sum);
    sum.bucket.orientation = quat_normalized(sum.bucket.orientation);
    result.average = to_signals(sum.bucket, sum.scalars);
  }
  const Sample end = sample();
  result.outputs = to_signals(end.bucket, end.scalars);
  const Reports r = model_->reports();
  result.diagnostics = {{"normal_front", r.normal_front}, {"normal_rear", r.normal_rear},
                        {"lift_length", r.lift_length}, {"tilt_length", r.tilt_length}};
  return result;
}

void WheelLoaderModel::load_checkpoint(const std::string& path) {
  model_->load_state(path);
  const double t = cosim::to_seconds(run_.resume_time);
  if (std::abs(model_->time() - t) > 1e-9 * std::max(1.0, std::abs(t)))
    throw std::runtime_error("its state is at t = " + std::to_string(model_->time()) + " s, the resume at " +
                             std::to_string(t) + " s");
}

}  // namespace wheel_loader
