// A DEM scene where explicit coupling fails and implicit coupling holds (docs/coupling.md,
// "A light blade"): configs/blade_light.yaml, a 5 kg blade on a spring to its driver pushed
// through 500 spheres of the paper's soil, in one process (dem_service's model, the prescribed
// participant, the master). At the paper's macro step (1 ms) the explicit run blows up (the DEM
// stops it: a grain past scene.stability.max_speed); implicit IQN-ILS at the same step finishes
// with the mean draft force of an explicit run at the DEM step (0.1 ms) within 5 %, in a few
// iterations per step.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "config.hpp"
#include "cosim/link.hpp"
#include "cosim/participant_core.hpp"
#include "cosim/yaml_config.hpp"
#include "cosimulation.hpp"
#include "dem/service.hpp"
#include "prescribed_adapter.hpp"

namespace {

std::string source(const std::string& rel) { return std::string(SOURCE_DIR) + "/" + rel; }

struct BladeRun {
  std::vector<double> t, fx;
  std::vector<int> iterations;
  double energy_residual = 0;  // J, sum of the power residual times the step
  std::string failure;         // the run's error, "" when it finished
  double mean(const std::vector<double>& v, double from, double to) const {
    double s = 0;
    int n = 0;
    for (std::size_t i = 0; i < t.size(); ++i)
      if (t[i] > from && t[i] <= to) s += v[i], ++n;
    return n ? s / n : NAN;
  }
  double mean_iterations(double from, double to) const {
    double s = 0;
    int n = 0;
    for (std::size_t i = 0; i < t.size(); ++i)
      if (t[i] > from && t[i] <= to) s += iterations[i], ++n;
    return n ? s / n : NAN;
  }
};

class Collector final : public master::Observer {
 public:
  BladeRun* run = nullptr;
  void on_step(const master::StepRecord& r) override {
    run->t.push_back(cosim::to_seconds(r.t_end));
    run->fx.push_back(r.outputs.at("soil").at("blade").value[0]);
    run->iterations.push_back(r.iterations);
    run->energy_residual += r.power.at(0).residual * cosim::to_seconds(r.t_end - r.t_start);
  }
};

BladeRun run(std::vector<std::string> overrides) {
  overrides.insert(overrides.end(), {"output.file=", "output.csv=", "output.progress=off"});
  const master::Config config = master::load_config(source("configs/blade_light.yaml"), overrides);
  dem::ServiceModel soil(cosim::config::load_file(source("configs/blade_bed.yaml")), source("configs"));
  prescribed::PrescribedAdapter tool(YAML::Node(), "");
  cosim::ParticipantCore cs("soil", soil), ct("tool", tool);
  auto transport = cosim::make_in_process_transport(4321, {{"soil", &cs}, {"tool", &ct}});
  BladeRun out;
  Collector col;
  col.run = &out;
  try {
    master::CoSimulation sim(config, *transport);
    sim.add_observer(&col);
    sim.connect();
    sim.run();
  } catch (const std::exception& e) {
    out.failure = e.what();
  }
  return out;
}

const std::vector<std::string> kImplicit = {
    "coupling.type=implicit", "coupling.max_iterations=50", "coupling.at_max_iterations=stop",
    "coupling.convergence=[{connection: tool.blade_wrench, measure: absolute_or_relative, absolute: 10.0, "
    "relative: 1.0e-3}]",
    "coupling.acceleration={type: iqn_ils, relaxation: 0.5, reuse: 8}"};

}  // namespace

TEST(LightBlade, ExplicitBlowsUpAtThePapersMacroStepWhereImplicitHolds) {
  // The reference: explicit at the DEM step, 0.1 ms (the blade is resolved there).
  const BladeRun ref = run({"time.macro_step=1.0e-4"});
  ASSERT_EQ(ref.failure, "");
  ASSERT_NEAR(ref.t.back(), 2.0, 1e-9);
  const double ref_fx = ref.mean(ref.fx, 1.3, 2.0);
  // The blade digs: a draft force of several kN against its direction of travel (+x).
  EXPECT_LT(ref_fx, -2000.0);

  // Explicit at 1 ms: the coupling mode of the light blade against the bed grows until the DEM
  // stops the run naming the blow-up (a grain past max_speed), or at least pumps energy.
  const BladeRun ex = run({});
  std::printf("explicit 1 ms: %s\n  ended at t = %.3f s, energy residual %.4g J\n",
              ex.failure.substr(0, 300).c_str(), ex.t.empty() ? 0.0 : ex.t.back(), ex.energy_residual);
  const bool blew_up = ex.failure.find("blow-up") != std::string::npos;
  EXPECT_TRUE(blew_up || std::abs(ex.energy_residual) > 1e4) << ex.failure;

  // Implicit at the same 1 ms: finishes, with the reference's draft force.
  const BladeRun im = run(kImplicit);
  ASSERT_EQ(im.failure, "");
  ASSERT_NEAR(im.t.back(), 2.0, 1e-9);
  const double im_fx = im.mean(im.fx, 1.3, 2.0);
  const double iterations = im.mean_iterations(1.2, 2.0);
  std::printf("reference 0.1 ms: mean Fx(1.3-2 s) %.1f N, energy residual %.3g J\n"
              "implicit 1 ms (IQN-ILS): mean Fx %.1f N (%+.2f %%), energy residual %.3g J, "
              "%.2f iterations/step in the bed (1.2-2 s), %.2f before\n",
              ref_fx, ref.energy_residual, im_fx, 100 * (im_fx / ref_fx - 1), im.energy_residual, iterations,
              im.mean_iterations(0, 1.2));
  EXPECT_NEAR(im_fx / ref_fx, 1.0, 0.05);
  EXPECT_LT(std::abs(im.energy_residual), 1.0);
  EXPECT_LE(iterations, 6.0);
  EXPECT_GT(iterations, 1.5);  // the bed is stiff for the blade: one pass is not enough
}
