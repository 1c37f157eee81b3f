// The oscillator halves as FMUs (fmu_export/oscillator), loaded from the build tree and driven
// through their fmi2 functions: exported symbols, the packed archive, the same numbers as the
// native model (oscillator::Half and the native participants under the master's schemes:
// results, convergence orders, critical macro steps), FMU states that repeat a step bit for
// bit, and each refusal with its message.
#include <cosim/participant_core.hpp>
#include <cosim/yaml_config.hpp>

#include <cmath>
#include <cstdio>
#include <memory>
#include <set>

#include "../oscillator/harness.hpp"
#include "fmu_loader.hpp"
#include "stability.hpp"

namespace {

using fmu_test::Instance;
using fmu_test::Library;

std::string run_command(const std::string& cmd) {
  std::string out;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return out;
  char buf[512];
  while (std::fgets(buf, sizeof buf, p)) out += buf;
  pclose(p);
  return out;
}

// A test master's view of one FMU half as a cosim::Model, so the master's own schemes,
// predictors and start-up iterations drive it in process: the input polynomial's value at
// the step start and its derivatives u^(j) = a_j j! / H^j go in through fmi2SetReal and
// fmi2SetRealInputDerivatives; repeats use fmi2GetFMUstate / fmi2SetFMUstate. The native
// parameter keys are the FMU's parameter names, except mass2's coupled_position and
// coupled_velocity, which are the start values of its inputs x and v.
class FmuHalf final : public cosim::Model {
 public:
  explicit FmuHalf(oscillator::Side side)
      : side_(side), id_(side == oscillator::Side::Mass1 ? "oscillator_mass1" : "oscillator_mass2"), lib_(id_) {}
  ~FmuHalf() override {
    if (inst_ && snapshot_) inst_->lib.fmi2FreeFMUstate(inst_->c, &snapshot_);
  }

  void configure(const YAML::Node& parameters, const cosim::RunInfo& run) override {
    inst_ = std::make_unique<Instance>(lib_, id_, run.participant);
    if (!inst_->c) throw std::runtime_error("fmi2Instantiate failed: " + inst_->log.all());
    double inner = 5e-6;
    for (const auto& kv : parameters) {
      std::string name = kv.first.as<std::string>();
      const double value = kv.second.as<double>();
      if (name == "inner_step") inner = value;
      if (name == "coupled_position") name = "x";
      if (name == "coupled_velocity") name = "v";
      if (inst_->set(name, value) != fmi2OK) throw std::runtime_error("set " + name + ": " + inst_->log.all());
    }
    inner_ = cosim::seconds_to_duration(inner, "inner_step");
    if (inst_->initialize(cosim::to_seconds(run.t_start), cosim::to_seconds(run.t_end)) != fmi2OK)
      throw std::runtime_error("initialization: " + inst_->log.all());
  }
  cosim::Ports inputs() const override {
    if (side_ == oscillator::Side::Mass1) return {{"force", cosim::SignalKind::Scalar}};
    return {{"x", cosim::SignalKind::Scalar}, {"v", cosim::SignalKind::Scalar}};
  }
  cosim::Ports outputs() const override {
    if (side_ == oscillator::Side::Mass1) return {{"x", cosim::SignalKind::Scalar}, {"v", cosim::SignalKind::Scalar}};
    return {{"force", cosim::SignalKind::Scalar}};
  }
  cosim::Duration inner_step() const override { return inner_; }
  cosim::Signals initial_outputs() override { return read_outputs(); }
  cosim::StepResult step(const cosim::StepInputs& in, bool) override {
    const double H = cosim::to_seconds(in.length());
    for (const auto& port : inputs()) {
      const auto& p = in.polynomial(port.name);
      if (inst_->set(port.name, p.evaluate(0.0)[0]) != fmi2OK) throw std::runtime_error(inst_->log.all());
      double factorial = 1, Hj = 1;
      for (int j = 1; j < p.n_coefficients; ++j) {
        factorial *= j;
        Hj *= H;
        if (inst_->set_derivative(port.name, j, p.coefficients[j] * factorial / Hj) != fmi2OK)
          throw std::runtime_error(inst_->log.all());
      }
    }
    if (inst_->step(cosim::to_seconds(in.t_start()), H) != fmi2OK) throw std::runtime_error(inst_->log.all());
    cosim::StepResult r;
    r.outputs = read_outputs();
    return r;
  }
  bool can_repeat() const override { return true; }
  void save_snapshot() override {
    if (inst_->lib.fmi2GetFMUstate(inst_->c, &snapshot_) != fmi2OK) throw std::runtime_error(inst_->log.all());
  }
  void restore_snapshot() override {
    if (inst_->lib.fmi2SetFMUstate(inst_->c, snapshot_) != fmi2OK) throw std::runtime_error(inst_->log.all());
  }

 private:
  cosim::Signals read_outputs() {
    cosim::Signals s;
    for (const auto& port : outputs()) s[port.name] = {cosim::SignalKind::Scalar, {inst_->get(port.name)}};
    return s;
  }
  oscillator::Side side_;
  std::string id_;
  Library lib_;
  std::unique_ptr<Instance> inst_;
  cosim::Duration inner_{};
  fmi2FMUstate snapshot_ = nullptr;
};

harness::Series run_fmus_in_process(const master::Config& config) {
  FmuHalf m1(oscillator::Side::Mass1), m2(oscillator::Side::Mass2);
  cosim::ParticipantCore c1("mass1", m1), c2("mass2", m2);
  auto transport = cosim::make_in_process_transport(1234, {{"mass1", &c1}, {"mass2", &c2}});
  master::CoSimulation sim(config, *transport);
  harness::Collector col;
  sim.add_observer(&col);
  sim.connect();
  sim.run();
  return col.s;
}

double max_difference(const std::vector<double>& a, const std::vector<double>& b) {
  EXPECT_EQ(a.size(), b.size());
  double d = 0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

}  // namespace

TEST(OscillatorFmu, ExportsTheFmi2FunctionsAndNothingElse) {
  for (const std::string id : {"oscillator_mass1", "oscillator_mass2"}) {
    const std::string out = run_command("nm -D --defined-only " + fmu_test::so_path(id));
    ASSERT_FALSE(out.empty()) << "nm found no symbols in " << fmu_test::so_path(id);
    std::set<std::string> symbols;
    std::istringstream lines(out);
    for (std::string line; std::getline(lines, line);) {
      const std::string name = line.substr(line.rfind(' ') + 1);
      symbols.insert(name);
      EXPECT_EQ(name.rfind("fmi2", 0), 0u) << id << " exports " << name;
    }
    // The co-simulation functions of FMI 2.0, all of them.
    for (const char* f : {"fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging", "fmi2Instantiate",
                          "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
                          "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset", "fmi2GetReal",
                          "fmi2GetInteger", "fmi2GetBoolean", "fmi2GetString", "fmi2SetReal", "fmi2SetInteger",
                          "fmi2SetBoolean", "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate",
                          "fmi2FreeFMUstate", "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate",
                          "fmi2DeSerializeFMUstate", "fmi2GetDirectionalDerivative",
                          "fmi2SetRealInputDerivatives", "fmi2GetRealOutputDerivatives", "fmi2DoStep",
                          "fmi2CancelStep", "fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetIntegerStatus",
                          "fmi2GetBooleanStatus", "fmi2GetStringStatus"})
      EXPECT_TRUE(symbols.count(f)) << id << " lacks " << f;
    EXPECT_EQ(symbols.size(), 34u) << out;
  }
}

TEST(OscillatorFmu, ArchiveHoldsTheDescriptionAndTheLinux64Binary) {
  for (const std::string id : {"oscillator_mass1", "oscillator_mass2"}) {
    const std::string fmu = fmu_test::build_fmu_dir() + "/" + id + ".fmu";
    const std::string list = run_command(std::string(CMAKE_COMMAND) + " -E tar tf " + fmu);
    EXPECT_NE(list.find("modelDescription.xml"), std::string::npos) << list;
    EXPECT_NE(list.find("binaries/linux64/" + id + ".so"), std::string::npos) << list;
    EXPECT_EQ(run_command("head -c 2 " + fmu), "PK") << fmu << " is not a zip archive";
    const std::string xml = fmu_test::read_text(fmu_test::xml_path(id));
    EXPECT_NE(xml.find("modelIdentifier=\"" + id + "\""), std::string::npos);
    EXPECT_NE(xml.find("canGetAndSetFMUstate=\"true\""), std::string::npos);
    EXPECT_NE(xml.find("canInterpolateInputs=\"true\""), std::string::npos);
    EXPECT_NE(xml.find("fmiVersion=\"2.0\""), std::string::npos);
  }
  // mass2's force depends directly on its inputs x and v (indices 1 and 2), mass1's outputs on none.
  EXPECT_NE(fmu_test::read_text(fmu_test::xml_path("oscillator_mass2")).find("<Unknown index=\"3\" dependencies=\"1 2\"/>"),
            std::string::npos);
  EXPECT_NE(fmu_test::read_text(fmu_test::xml_path("oscillator_mass1")).find("<Unknown index=\"2\" dependencies=\"\"/>"),
            std::string::npos);
}

// One half alone with a cubic input polynomial: the FMU's states equal those of the model the
// native participant runs (oscillator::Half), to rounding of the derivative conversion, and bit
// for bit with a constant input (no conversion).
TEST(OscillatorFmu, StandaloneHalfMatchesTheNativeModel) {
  Library lib("oscillator_mass1");
  const double H = 1e-3, inner = 5e-6;
  const int n_inner = 200;
  const double a[4] = {0.3, -1.2, 0.7, 0.25};  // force(s) = sum a_j s^j over each step
  for (const int order : {0, 3}) {
    Instance fmu(lib, "oscillator_mass1");
    ASSERT_NE(fmu.c, nullptr) << fmu.log.all();
    ASSERT_EQ(fmu.initialize(0, 1), fmi2OK) << fmu.log.all();
    oscillator::Half native(oscillator::Side::Mass1, oscillator::Parameters{}, inner);
    double worst = 0;
    for (int k = 0; k < 500; ++k) {
      std::vector<Eigen::VectorXd> c;
      for (int j = 0; j <= order; ++j) c.push_back(Eigen::VectorXd::Constant(1, a[j] * (1 + 0.001 * k)));
      native.advance(c, n_inner);
      ASSERT_EQ(fmu.set("force", c[0](0)), fmi2OK);
      double fact = 1;
      for (int j = 1; j <= order; ++j) {
        fact *= j;
        ASSERT_EQ(fmu.set_derivative("force", j, c[j](0) * fact / std::pow(H, j)), fmi2OK) << fmu.log.all();
      }
      ASSERT_EQ(fmu.step(k * H, H), fmi2OK) << fmu.log.all();
      if (order == 0) {
        ASSERT_EQ(fmu.get("x"), native.state()(0)) << "step " << k;
        ASSERT_EQ(fmu.get("v"), native.state()(1)) << "step " << k;
      }
      worst = std::max({worst, std::abs(fmu.get("x") - native.state()(0)), std::abs(fmu.get("v") - native.state()(1))});
    }
    std::printf("order %d: largest difference from oscillator::Half over 500 steps: %.3g\n", order, worst);
    EXPECT_LT(worst, 1e-14);  // states of order 0.1: rounding only
    EXPECT_GT(std::abs(fmu.get("x")), 1e-3) << "the input must move the mass";
  }
}

// The dual-mass oscillator with both halves as FMUs under the master's schemes, in process,
// against the native participants with the same config: the same macro-step results.
TEST(OscillatorFmu, CoSimulationEqualsTheNativeParticipants) {
  struct Case {
    const char* scheme;
    int kq, kf;
  };
  for (const Case c : {Case{"jacobi", 0, 0}, Case{"jacobi", 1, 0}, Case{"jacobi", 1, 1}, Case{"jacobi", 2, 2},
                       Case{"gauss_seidel", 1, 1}, Case{"gauss_seidel", 3, 3}}) {
    const auto config = harness::oscillator_config(
        {std::string("scheme=") + c.scheme, "order=[mass2, mass1]", "time.macro_step=5e-4",
         "predictors.kinematics.order=" + std::to_string(c.kq), "predictors.force.order=" + std::to_string(c.kf),
         "output.file=", "output.csv="});
    const auto native = harness::run_in_process(config);
    const auto fmu = run_fmus_in_process(config);
    const double dx = max_difference(native.x1, fmu.x1), dv = max_difference(native.v1, fmu.v1),
                 df = max_difference(native.force, fmu.force);
    std::printf("%-12s (%d,%d): largest difference FMU - native: x1 %.3g m, v1 %.3g m/s, force %.3g N\n",
                c.scheme, c.kq, c.kf, dx, dv, df);
    if (c.kq == 0 && c.kf == 0) {
      // Constant inputs cross without any conversion: the same arithmetic, bit for bit.
      EXPECT_EQ(native.x1, fmu.x1);
      EXPECT_EQ(native.force, fmu.force);
    }
    // x1 ~ 0.1 m, force ~ 100 N; the co-simulation error itself is 1e-7..1e-4 m here.
    EXPECT_LT(dx, 1e-13);
    EXPECT_LT(dv, 1e-11);
    EXPECT_LT(df, 1e-10);
  }
}

namespace {
double observed_order(const std::vector<double>& e) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const int n = static_cast<int>(e.size());
  for (int i = 0; i < n; ++i) sx += i, sy += -std::log2(e[i]), sxx += i * i, sxy += i * -std::log2(e[i]);
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}
}  // namespace

// The convergence orders of docs/stability.md, min(kq, kf) + 1, with both halves as FMUs.
TEST(OscillatorFmu, ConvergenceOrdersAreTheNativeOnes) {
  struct Case {
    int kq, kf;
    double order;
  };
  for (const Case c : {Case{0, 0, 1}, Case{1, 0, 1}, Case{1, 1, 2}, Case{2, 2, 3}}) {
    std::vector<double> e_fmu, e_native;
    for (double H : {1e-3, 5e-4, 2.5e-4, 1.25e-4}) {
      const auto config = harness::oscillator_config(
          {"scheme=jacobi", "time.macro_step=" + std::to_string(H), "predictors.kinematics.order=" + std::to_string(c.kq),
           "predictors.force.order=" + std::to_string(c.kf), "output.file=", "output.csv="});
      e_fmu.push_back(harness::max_error(config, run_fmus_in_process(config)));
      e_native.push_back(harness::max_error(config, harness::run_in_process(config)));
    }
    const double order = observed_order(e_fmu);
    std::printf("jacobi (%d,%d) FMUs: errors %.4e %.4e %.4e %.4e -> order %.3f (native %.3f)\n", c.kq, c.kf, e_fmu[0],
                e_fmu[1], e_fmu[2], e_fmu[3], order, observed_order(e_native));
    EXPECT_NEAR(order, c.order, 0.1);
    EXPECT_NEAR(order, observed_order(e_native), 1e-6);
    for (std::size_t i = 0; i < e_fmu.size(); ++i) EXPECT_NEAR(e_fmu[i], e_native[i], 1e-9 * e_native[i] + 1e-14);
  }
}

// At 0.98 and 1.02 of cosim_stability's critical macro step the FMU co-simulation decays and
// grows at the rate the spectral radius predicts, as the native one does (test_instability).
TEST(OscillatorFmu, CriticalMacroStepsAreTheNativeOnes) {
  using cosim::stability::Scheme;
  struct Case {
    const char* scheme;
    int kq, kf;
  };
  auto growth = [](const std::vector<double>& force) {
    const std::size_t n = force.size(), tenth = n / 10;
    double middle = 0, last = 0;
    for (std::size_t i = 4 * tenth; i < 5 * tenth; ++i) middle = std::max(middle, std::abs(force[i]));
    for (std::size_t i = n - tenth; i < n; ++i) last = std::max(last, std::abs(force[i]));
    return last / middle;
  };
  for (const Case c : {Case{"jacobi", 1, 0}, Case{"jacobi", 2, 2}, Case{"gauss_seidel", 1, 1}}) {
    const Scheme scheme = std::string(c.scheme) == "jacobi" ? Scheme::Jacobi : Scheme::GaussSeidel;
    const auto critical = cosim::stability::critical_macro_step({}, scheme, c.kq, c.kf);
    ASSERT_TRUE(critical.has_value());
    for (const double factor : {0.98, 1.02}) {
      const long long ns = std::llround(factor * *critical * 1e9);
      const long long steps = (100'000'000'000LL + ns - 1) / ns;
      char h[64], end[64];
      std::snprintf(h, sizeof h, "%.9f", ns * 1e-9);
      std::snprintf(end, sizeof end, "%.9f", steps * ns * 1e-9);
      const auto config = harness::oscillator_config(
          {std::string("scheme=") + c.scheme, "order=[mass1, mass2]", "predictors.kinematics.order=" + std::to_string(c.kq),
           "predictors.force.order=" + std::to_string(c.kf), std::string("time.end=") + end,
           std::string("time.macro_step=") + h, std::string("participants.mass1.parameters.inner_step=") + h,
           std::string("participants.mass2.parameters.inner_step=") + h, "output.file=", "output.csv="});
      const auto fmu = run_fmus_in_process(config);
      const auto native = harness::run_in_process(config);
      const double rate = std::log(growth(fmu.force)) / (0.5 * fmu.t.back());
      const double rate_native = std::log(growth(native.force)) / (0.5 * native.t.back());
      const double predicted = std::log(cosim::stability::spectral_radius({}, scheme, c.kq, c.kf, 0, 0, ns * 1e-9)) / (ns * 1e-9);
      std::printf("%-12s (%d,%d) H_crit %.6e, H = %.2f H_crit: rate FMUs %+.5f /s, native %+.5f /s, predicted %+.5f /s\n",
                  c.scheme, c.kq, c.kf, *critical, factor, rate, rate_native, predicted);
      EXPECT_NEAR(rate, rate_native, 1e-6 * std::abs(rate_native) + 1e-9);
      if (factor < 1) {
        EXPECT_LT(rate, 0);
      } else {
        EXPECT_GT(rate, 0);
        EXPECT_NEAR(rate, predicted, 0.05 * predicted);
      }
    }
  }
}

// A step repeated from a saved FMU state with the same inputs gives the same outputs bit for
// bit; with other inputs, what a fresh instance that took those inputs gives.
TEST(OscillatorFmu, RepeatedStepFromFmuStateIsBitIdentical) {
  Library lib("oscillator_mass2");
  const double H = 1e-3;
  auto drive = [&](Instance& f, int k, double scale) {
    EXPECT_EQ(f.set("x", 0.1 * std::cos(3.0 * k * H) * scale), fmi2OK);
    EXPECT_EQ(f.set("v", -0.3 * std::sin(3.0 * k * H)), fmi2OK);
    EXPECT_EQ(f.set_derivative("x", 1, -0.3 * std::sin(3.0 * k * H)), fmi2OK);
    EXPECT_EQ(f.set_derivative("v", 1, -0.9 * std::cos(3.0 * k * H)), fmi2OK);
    EXPECT_EQ(f.step(k * H, H), fmi2OK) << f.log.all();
  };
  Instance a(lib, "oscillator_mass2"), b(lib, "oscillator_mass2");
  ASSERT_EQ(a.initialize(), fmi2OK);
  ASSERT_EQ(b.initialize(), fmi2OK);
  const int k = 37;
  for (int i = 0; i < k; ++i) drive(a, i, 1);
  fmi2FMUstate s = nullptr;
  ASSERT_EQ(a.lib.fmi2GetFMUstate(a.c, &s), fmi2OK) << a.log.all();
  drive(a, k, 1);
  const double first = a.get("force");
  ASSERT_EQ(a.lib.fmi2SetFMUstate(a.c, s), fmi2OK) << a.log.all();
  drive(a, k, 1);
  EXPECT_EQ(a.get("force"), first);
  ASSERT_EQ(a.lib.fmi2SetFMUstate(a.c, s), fmi2OK);
  drive(a, k, 1.01);
  const double other = a.get("force");
  EXPECT_NE(other, first);
  for (int i = 0; i < k; ++i) drive(b, i, 1);
  drive(b, k, 1.01);
  EXPECT_EQ(b.get("force"), other);
  // and both go on alike
  drive(a, k + 1, 1);
  drive(b, k + 1, 1);
  EXPECT_EQ(a.get("force"), b.get("force"));
  // a state saved again into the same handle is overwritten, then freed
  ASSERT_EQ(a.lib.fmi2GetFMUstate(a.c, &s), fmi2OK);
  ASSERT_EQ(a.lib.fmi2FreeFMUstate(a.c, &s), fmi2OK);
  EXPECT_EQ(s, nullptr);
}

TEST(OscillatorFmu, RefusalsSayWhatIsWrong) {
  Library lib("oscillator_mass1");
  {  // a modelDescription.xml of another build
    Instance f(lib, "oscillator_mass1", "wrong_guid", "{00000000-0000-0000-0000-000000000000}");
    EXPECT_EQ(f.c, nullptr);
    EXPECT_NE(f.log.all().find("does not match"), std::string::npos) << f.log.all();
  }
  {  // a bad parameter is named at initialization
    Instance f(lib, "oscillator_mass1");
    ASSERT_EQ(f.set("mass", -1), fmi2OK);
    EXPECT_EQ(f.initialize(), fmi2Error);
    EXPECT_NE(f.log.all().find("parameter 'mass' = -1"), std::string::npos) << f.log.all();
  }
  {
    Instance f(lib, "oscillator_mass1");
    ASSERT_EQ(f.set("inner_step", 1.5e-10), fmi2OK);
    EXPECT_EQ(f.initialize(), fmi2Error);
    EXPECT_NE(f.log.all().find("not a whole number of nanoseconds"), std::string::npos) << f.log.all();
  }
  Instance f(lib, "oscillator_mass1");
  EXPECT_EQ(f.set("x", 1.0), fmi2Error);  // an output
  EXPECT_NE(f.log.all().find("'x' is an output"), std::string::npos) << f.log.all();
  EXPECT_EQ(f.step(0, 1e-3), fmi2Error);  // before initialization
  EXPECT_NE(f.log.all().find("fmi2DoStep: the FMU is instantiated"), std::string::npos) << f.log.all();
  ASSERT_EQ(f.initialize(0, 1), fmi2OK) << f.log.all();
  EXPECT_EQ(f.set("mass", 2.0), fmi2Error);  // fixed, after initialization
  EXPECT_NE(f.log.all().find("parameter 'mass' is fixed"), std::string::npos) << f.log.all();
  EXPECT_EQ(f.set_derivative("force", 4, 1.0), fmi2Error);
  EXPECT_NE(f.log.all().find("orders 1 to 3"), std::string::npos) << f.log.all();
  const fmi2ValueReference unknown = 77;
  double v = 0;
  EXPECT_EQ(lib.fmi2GetReal(f.c, &unknown, 1, &v), fmi2Error);
  EXPECT_NE(f.log.all().find("no Real variable with value reference 77"), std::string::npos) << f.log.all();
  // Still usable after those: argument errors do not break the instance.
  ASSERT_EQ(f.step(0, 1e-3), fmi2OK) << f.log.all();
  EXPECT_EQ(f.step(0, 1e-3), fmi2Error);  // the FMU is at 1e-3 now
  EXPECT_NE(f.log.all().find("but the FMU is at"), std::string::npos) << f.log.all();
  Instance g(lib, "oscillator_mass1");
  ASSERT_EQ(g.initialize(0, 1), fmi2OK);
  EXPECT_EQ(g.step(0, 1.2345e-5), fmi2Error);  // not a multiple of the 5 us inner step
  EXPECT_NE(g.log.all().find("not a multiple of the inner step 5000 ns"), std::string::npos) << g.log.all();
  EXPECT_EQ(g.step(0, 1e-3), fmi2Error);  // a failed step leaves the instance in error
  EXPECT_NE(g.log.all().find("in error"), std::string::npos) << g.log.all();
  EXPECT_EQ(lib.fmi2Reset(g.c), fmi2OK);  // until reset
  ASSERT_EQ(g.initialize(0, 1), fmi2OK) << g.log.all();
  EXPECT_EQ(g.step(0, 1e-3), fmi2OK) << g.log.all();
  EXPECT_EQ(g.step(1e-3, 2), fmi2Error);  // past the stop time
  EXPECT_NE(g.log.all().find("past the stop time"), std::string::npos) << g.log.all();
}
