// The oscillator halves as FMI 2.0 co-simulation FMUs: a thin export wrapper around
// oscillator::Half, the model the native participants run (mbs_adapters/oscillator). The
// same exact integrator with the same inner step; the input over a communication step is the
// polynomial the master's predictor gives, received as the value at the step's start plus its
// time derivatives (fmi2SetRealInputDerivatives) and turned back into the native polynomial
// coefficients a_j = u^(j) h^j / j!.
#include <cmath>
#include <cstdint>
#include <memory>

#include "../common/slave.hpp"
#include "oscillator.hpp"

namespace fmu_export {
namespace {

constexpr oscillator::Side kSide =
    OSCILLATOR_FMU_SIDE == 1 ? oscillator::Side::Mass1 : oscillator::Side::Mass2;

std::int64_t whole_ns(double seconds, const std::string& what) {
  return fmu_export::whole_ns(seconds, what, " (time is counted in ns; choose e.g. 5e-6)");
}

struct ModelState {
  Eigen::Vector2d x;
  std::int64_t t_ns;
};

class OscillatorSlave final : public Slave {
 public:
  using Slave::Slave;

 private:
  const std::vector<std::string>& input_names() const {
    static const std::vector<std::string> m1{"force"}, m2{"x", "v"};
    return kSide == oscillator::Side::Mass1 ? m1 : m2;
  }

  oscillator::Parameters parameters() const {
    oscillator::Parameters p;
    auto positive = [&](const char* name) {
      const double v = real(name);
      if (!(v > 0)) throw FmuError(std::string("parameter '") + name + "' = " + std::to_string(v) + " must be > 0");
      return v;
    };
    auto non_negative = [&](const char* name) {
      const double v = real(name);
      if (v < 0)
        throw FmuError(std::string("parameter '") + name + "' = " + std::to_string(v) +
                       ": stiffness and damping values must be >= 0");
      return v;
    };
    if (kSide == oscillator::Side::Mass1) {
      p.m1 = positive("mass");
      p.c1 = non_negative("stiffness");
      p.d1 = non_negative("damping");
      p.x1 = real("position");
      p.v1 = real("velocity");
    } else {
      p.m2 = positive("mass");
      p.c2 = non_negative("stiffness");
      p.d2 = non_negative("damping");
      p.cc = non_negative("coupling_stiffness");
      p.dc = non_negative("coupling_damping");
      p.x2 = real("position");
      p.v2 = real("velocity");
    }
    return p;
  }

  void initialize() override {
    const oscillator::Parameters p = parameters();
    if (!(real("inner_step") > 0))
      throw FmuError("parameter 'inner_step' = " + std::to_string(real("inner_step")) + " s must be > 0");
    inner_ns_ = whole_ns(real("inner_step"), "parameter 'inner_step'");
    t_ns_ = whole_ns(start_time(), "the start time (fmi2SetupExperiment)");
    half_ = std::make_unique<oscillator::Half>(kSide, p, inner_ns_ * 1e-9);
    log(fmi2OK, "logEvents",
        "initialized: inner step " + std::to_string(inner_ns_) + " ns, start time " + std::to_string(t_ns_) + " ns");
  }

  void step(double t, double h) override {
    const std::int64_t h_ns = step_ns(t, h, t_ns_, inner_ns_);
    const auto& names = input_names();
    const int m = static_cast<int>(names.size());
    // The native polynomial in s = (t' - t) / h: a_0 = u(t), a_j = u^(j)(t) h^j / j!.
    const int order = input_derivative_order();
    std::vector<Eigen::VectorXd> a(order + 1, Eigen::VectorXd::Zero(m));
    double factor = 1;  // h^j / j!
    for (int j = 0; j <= order; ++j) {
      if (j > 0) factor *= h / j;
      for (int i = 0; i < m; ++i) a[j](i) = j == 0 ? real(names[i]) : input_derivative(names[i], j) * factor;
    }
    half_->advance(a, static_cast<int>(h_ns / inner_ns_));
    // The inputs at the step's end, as the native participant evaluates its polynomial (Horner
    // at s = 1): the outputs after the step (mass2's force) use them, like the native reply.
    for (int i = 0; i < m; ++i) {
      double u = 0;
      for (int j = order; j >= 0; --j) u = u * 1.0 + a[j](i);
      real(names[i]) = u;
    }
    t_ns_ += h_ns;
  }

  void update_outputs() override {
    if (kSide == oscillator::Side::Mass1) {
      const Eigen::Vector2d x = half_ ? half_->state() : Eigen::Vector2d(real("position"), real("velocity"));
      real("x") = x(0);
      real("v") = x(1);
    } else {
      Eigen::VectorXd u(2);
      u << real("x"), real("v");
      if (half_) {
        real("force") = half_->output(u)(0);
      } else {  // before initialization: from the parameters, as the half will start
        real("force") = -(real("coupling_stiffness") * (u(0) - real("position")) +
                          real("coupling_damping") * (u(1) - real("velocity")));
      }
    }
  }

  void on_terminate() override { log(fmi2OK, "logEvents", "terminated at " + std::to_string(t_ns_) + " ns"); }

  std::shared_ptr<const void> save_model() const override {
    return std::make_shared<ModelState>(ModelState{half_->state(), t_ns_});
  }
  void restore_model(const std::shared_ptr<const void>& saved) override {
    const auto& s = *static_cast<const ModelState*>(saved.get());
    half_->set_state(s.x);
    t_ns_ = s.t_ns;
  }

  std::unique_ptr<oscillator::Half> half_;
  std::int64_t inner_ns_ = 0, t_ns_ = 0;
};

}  // namespace

std::unique_ptr<Slave> make_slave(const std::string& instance_name, const fmi2CallbackFunctions& callbacks,
                                  bool logging_on) {
  return std::make_unique<OscillatorSlave>(description(), instance_name, callbacks, logging_on);
}

}  // namespace fmu_export
