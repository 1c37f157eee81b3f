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

double norm3(double x, double y, double z) { return std::sqrt(x * x + y * y + z * z); }
}  // namespace

struct WheelLoaderModel::Sample {
  Value bucket;  // 13
  double scalars[kNumScalars];
};

WheelLoaderModel::WheelLoaderModel(YAML::Node machine_config) : base_(std::move(machine_config)) {}

void WheelLoaderModel::configure(const YAML::Node& parameters, const RunInfo& run) {
  YAML::Node root = YAML::Clone(base_);
  if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  cfg::apply_overrides(root, parameters, "participants." + run.participant + ".parameters");
  p_ = read_parameters(root);
  inner_step_ = seconds_to_ticks(p_.inner_step, "inner_step");
  if (inner_step_ <= 0) throw cfg::ConfigError("inner_step: must be at least 1 ns");
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
  const BucketKinematics k = model_->bucket();
  s.bucket = {k.position[0], k.position[1], k.position[2], k.rotation[0], k.rotation[1],
              k.rotation[2], k.rotation[3], k.velocity[0], k.velocity[1], k.velocity[2],
              k.angular_velocity[0], k.angular_velocity[1], k.angular_velocity[2]};
  const Reports r = model_->reports();
  const V3 edge = model_->cutting_edge();
  const double v[kNumScalars] = {r.a_long, r.a_vert, r.j_long, r.j_vert, r.lift_force,
                                 r.tilt_force, r.speed, r.x_machine, r.drive_force,
                                 r.normal_load, r.bucket_pitch, r.boom_angle, edge[0], edge[2]};
  std::copy(v, v + kNumScalars, s.scalars);
  return s;
}

namespace {
Signals to_signals(const Value& bucket, const double* scalars) {
  Signals out;
  out["bucket"] = {SignalKind::Kinematics, bucket};
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
    const Ticks t = in.t_start() + static_cast<Ticks>(std::llround(s * (in.t_end() - in.t_start())));
    const Value w = in.at("bucket_wrench", t);
    const double F = norm3(w[0], w[1], w[2]);
    const double r[3] = {w[6] - origin[0], w[7] - origin[1], w[8] - origin[2]};
    const double T = norm3(w[3] + r[1] * w[2] - r[2] * w[1], w[4] + r[2] * w[0] - r[0] * w[2],
                           w[5] + r[0] * w[1] - r[1] * w[0]);
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
  const double t0 = to_seconds(in.t_start()), H = to_seconds(in.t_end() - in.t_start());
  model_->set_bucket_wrench([poly, t0, H](double t) {
    const Value w = poly.evaluate((t - t0) / H);
    Wrench out;
    out.force = {w[0], w[1], w[2]};
    out.torque = {w[3], w[4], w[5]};
    out.point = {w[6], w[7], w[8]};
    return out;
  });
  StepResult result;
  if (!want_average) {
    model_->advance(to_seconds(in.t_end()));
  } else {
    // trapezoid average over the inner steps; the orientation as the normalized mean
    // quaternion (its sign kept on the start's hemisphere)
    Sample first = sample(), sum = first;
    for (auto& v : sum.bucket) v *= 0.5;
    for (auto& v : sum.scalars) v *= 0.5;
    Sample last = first;
    int n = 0;
    model_->advance(to_seconds(in.t_end()), [&] {
      if (n > 0) {
        for (std::size_t i = 0; i < 13; ++i) sum.bucket[i] += last.bucket[i] * 0.5;
        for (int i = 0; i < kNumScalars; ++i) sum.scalars[i] += last.scalars[i] * 0.5;
      }
      last = sample();
      double dot = 0;
      for (int i = 3; i < 7; ++i) dot += last.bucket[i] * first.bucket[i];
      if (dot < 0)
        for (int i = 3; i < 7; ++i) last.bucket[i] = -last.bucket[i];
      for (std::size_t i = 0; i < 13; ++i) sum.bucket[i] += last.bucket[i] * 0.5;
      for (int i = 0; i < kNumScalars; ++i) sum.scalars[i] += last.scalars[i] * 0.5;
      ++n;
    });
    for (auto& v : sum.bucket) v /= n;
    for (auto& v : sum.scalars) v /= n;
    const double qn = std::sqrt(sum.bucket[3] * sum.bucket[3] + sum.bucket[4] * sum.bucket[4] +
                                sum.bucket[5] * sum.bucket[5] + sum.bucket[6] * sum.bucket[6]);
    for (int i = 3; i < 7; ++i) sum.bucket[i] /= qn;
    result.average = to_signals(sum.bucket, sum.scalars);
  }
  const Sample end = sample();
  result.outputs = to_signals(end.bucket, end.scalars);
  const Reports r = model_->reports();
  result.diagnostics = {{"normal_front", r.normal_front}, {"normal_rear", r.normal_rear},
                        {"lift_length", r.lift_length}, {"tilt_length", r.tilt_length}};
  return result;
}

}  // namespace wheel_loader
