// The wheel loader as an FMI 2.0 co-simulation FMU: a thin export wrapper around the Simbody
// model the native wheel_loader_adapter runs (mbs_adapters/wheel_loader: WheelLoader and its
// Parameters), with the same integrator (RK3, fixed inner step, restarted at every step), the
// same parameters and the same outputs. The soil's wrench is held over each doStep, as the
// native adapter's input is under the paper's constant force predictor. FMU states are copies
// of the Simbody State.
#include <cmath>
#include <cstdio>
#include <memory>

#include <cosim/yaml_config.hpp>

#include "../common/slave.hpp"
#include "table.hpp"
#include "wheel_loader.hpp"

namespace fmu_export {
namespace {

namespace cfg = cosim::config;

const char* const kWrench[] = {"force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z",
                               "reference_point_x", "reference_point_y", "reference_point_z"};

std::string number(double x) {
  char b[32];
  std::snprintf(b, sizeof b, "%.12g", x);
  return b;
}

double norm(const wheel_loader::V3& x) { return std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]); }

struct ModelState {
  std::shared_ptr<const void> simbody;  // WheelLoader::copy_state
  std::int64_t t_ns;
};

class WheelLoaderSlave final : public Slave {
 public:
  using Slave::Slave;

 private:
  // The machine config: machine_config (file) < machine_parameters (amendments) < the Real
  // parameters that differ from their native defaults. Every refusal names the parameter.
  wheel_loader::Parameters parameters() const {
    YAML::Node root;
    const std::string file = string("machine_config");
    try {
      if (!file.empty()) root = cfg::load_file(file);
    } catch (const cfg::ConfigError& e) {
      throw FmuError(std::string("parameter 'machine_config': ") + e.what());
    }
    if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
    const std::string amend = string("machine_parameters");
    if (!amend.empty()) {
      try {
        const YAML::Node a = cfg::load_string(amend, "parameter 'machine_parameters'");
        if (a && !a.IsNull()) cfg::apply_overrides(root, a, "parameter 'machine_parameters'");
      } catch (const cfg::ConfigError& e) {
        throw FmuError(std::string(e.what()) +
                       " (machine_parameters is a YAML map of dotted machine config keys, e.g. "
                       "{maneuver.tilt: [[0, 0], [2, 0.1]]})");
      }
    }
    for (const auto& p : wl::scalar_parameters()) {
      const double v = real(p.key);
      if (v == p.native_default) continue;  // left at its default: the file's value, if any
      YAML::Node one(YAML::NodeType::Map);
      one[p.key] = v;
      try {  // alone first, so that a bad value is blamed on the parameter
        YAML::Node alone(YAML::NodeType::Map);
        cfg::apply_overrides(alone, one, "parameter '" + p.key + "'");
        wheel_loader::read_parameters(alone);
      } catch (const cfg::ConfigError& e) {
        throw FmuError("parameter '" + p.key + "' = " + number(v) + ": " + e.what());
      }
      cfg::apply_overrides(root, one, "parameter '" + p.key + "'");
    }
    try {
      return wheel_loader::read_parameters(root);
    } catch (const cfg::ConfigError& e) {
      throw FmuError(std::string("the machine config (") +
                     (file.empty() ? std::string("built-in defaults") : "machine_config '" + file + "'") +
                     ", machine_parameters and the FMU's Real parameters): " + e.what());
    }
  }

  void initialize() override {
    p_ = parameters();
    inner_ns_ = whole_ns(p_.inner_step, "parameter 'inner_step'", " (time is counted in ns; choose e.g. 1e-4)");
    t_ns_ = whole_ns(start_time(), "the start time (fmi2SetupExperiment)");
    try {
      model_ = std::make_unique<wheel_loader::WheelLoader>(p_, static_cast<double>(t_ns_) * 1e-9);
    } catch (const std::exception& e) {
      throw FmuError(std::string("the machine cannot start with these parameters: ") + e.what());
    }
    outputs_valid_ = false;
    log(fmi2OK, "logEvents",
        "initialized at t = " + number(static_cast<double>(t_ns_) * 1e-9) + " s: inner step " +
            std::to_string(inner_ns_) + " ns, total mass " + number(model_->total_mass()) + " kg" +
            (string("machine_config").empty() ? std::string() : ", machine config " + string("machine_config")));
  }

  // The inputs as a wrench (ground axes, torque about the reference point); refused when not
  // finite or beyond the machine's limits, as the native adapter refuses such a step.
  wheel_loader::Wrench input_wrench(const char* when) const {
    wheel_loader::Wrench w;
    for (int i = 0; i < 3; ++i) {
      w.force[i] = real(kWrench[i]);
      w.torque[i] = real(kWrench[3 + i]);
      w.point[i] = real(kWrench[6 + i]);
    }
    for (int i = 0; i < 9; ++i)
      if (!std::isfinite(real(kWrench[i])))
        throw FmuError(std::string("input '") + kWrench[i] + "' is " + number(real(kWrench[i])) + " " + when);
    const wheel_loader::Wrench at_origin = w.shifted_to(model_->bucket().position);
    const double F = norm(at_origin.force), T = norm(at_origin.torque);
    if (F > p_.max_force)
      throw FmuError("input force " + number(F) + " N " + when + " exceeds parameter 'limits.max_force' = " +
                     number(p_.max_force) + " N (a DEM blow-up or a unit error? raise limits.max_force if it is real)");
    if (T > p_.max_torque)
      throw FmuError("input torque about the bucket origin " + number(T) + " N m " + when +
                     " exceeds parameter 'limits.max_torque' = " + number(p_.max_torque) +
                     " N m (is reference_point the point the torque is about, in ground coordinates?)");
    return w;
  }

  void step(double t, double h) override {
    const std::int64_t h_ns = step_ns(t, h, t_ns_, inner_ns_);
    const wheel_loader::Wrench w = input_wrench(("at t = " + number(t) + " s").c_str());
    model_->set_wrench([w](double) { return w; });
    outputs_valid_ = false;
    try {
      // The end time as the native adapter computes it (cosim::to_seconds of whole ns).
      model_->advance(static_cast<double>(t_ns_ + h_ns) * 1e-9);
    } catch (const std::exception& e) {
      throw FmuError(std::string("fmi2DoStep at t = ") + number(t) + " s: " + e.what());
    }
    t_ns_ += h_ns;
  }

  // Outputs from the state and the current inputs (the pin forces depend on the wrench
  // directly), computed once per state and input values.
  void update_outputs() override {
    if (!model_) return;  // before initialization: the start values
    std::array<double, 9> in{};
    for (int i = 0; i < 9; ++i) in[i] = real(kWrench[i]);
    if (outputs_valid_ && in == outputs_for_) return;
    wheel_loader::Wrench w;
    for (int i = 0; i < 3; ++i) {
      w.force[i] = in[i];
      w.torque[i] = in[3 + i];
      w.point[i] = in[6 + i];
    }
    model_->set_wrench([w](double) { return w; });
    const cosim::Kinematics k = model_->bucket();
    for (int i = 0; i < 3; ++i) {
      real_vr(wl::kPosition + i) = k.position[i];
      real_vr(wl::kVelocity + i) = k.velocity[i];
      real_vr(wl::kAngularVelocity + i) = k.angular_velocity[i];
    }
    for (int i = 0; i < 4; ++i) real_vr(wl::kQuaternion + i) = k.orientation[i];
    const wheel_loader::Reports r = model_->reports();
    const wheel_loader::V3 edge = model_->cutting_edge();
    // wheel_loader_adapter.cpp's order (wl::scalar_outputs())
    const double v[] = {r.a_long, r.a_vert, r.j_long, r.j_vert, r.lift_force,
                        r.tilt_force, r.speed, r.x_machine, r.drive_force,
                        r.normal_load, r.bucket_pitch, r.boom_angle, edge[0], edge[2]};
    for (std::size_t i = 0; i < wl::scalar_outputs().size(); ++i) real(wl::scalar_outputs()[i].name) = v[i];
    outputs_for_ = in;
    outputs_valid_ = true;
  }

  double& real_vr(fmi2ValueReference vr) {
    static const auto names = [] {
      std::map<fmi2ValueReference, std::string> m;
      for (const auto& v : fmu_export::description().variables)
        if (v.type == Type::Real) m[v.vr] = v.name;
      return m;
    }();
    return real(names.at(vr));
  }

  void on_terminate() override {
    if (model_) log(fmi2OK, "logEvents", "terminated at t = " + number(model_->time()) + " s");
  }

  std::shared_ptr<const void> save_model() const override {
    return std::make_shared<ModelState>(ModelState{model_->copy_state(), t_ns_});
  }
  void restore_model(const std::shared_ptr<const void>& saved) override {
    const auto& s = *static_cast<const ModelState*>(saved.get());
    model_->set_state(s.simbody);
    t_ns_ = s.t_ns;
    outputs_valid_ = false;
  }

  wheel_loader::Parameters p_;
  std::unique_ptr<wheel_loader::WheelLoader> model_;
  std::int64_t inner_ns_ = 0, t_ns_ = 0;
  bool outputs_valid_ = false;
  std::array<double, 9> outputs_for_{};
};

}  // namespace

std::unique_ptr<Slave> make_slave(const std::string& instance_name, const fmi2CallbackFunctions& callbacks,
                                  bool logging_on) {
  return std::make_unique<WheelLoaderSlave>(description(), instance_name, callbacks, logging_on);
}

}  // namespace fmu_export
