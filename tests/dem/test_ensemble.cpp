// What ensembles need from the DEM: a seeded, physically negligible perturbation of the
// particle positions (particles.perturb) and the payload of a tool.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "cosim/yaml_config.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem_test_util.hpp"

namespace {

const char* kBase = R"(
scene: {dt: 1.0e-5, threads: 1}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 4.0e7, restitution: 0.3, friction: 0.5}
particles:
  fill: [{species: grain, min: [0, 0, 0], max: [0.2, 0.2, 0.2], count: 200, seed: 3}]
)";

dem::RunConfig load(const std::vector<std::string>& sets) {
  YAML::Node root = YAML::Load(kBase);
  for (const auto& s : sets) cosim::config::apply_override(root, s);
  return dem::load_config(root, std::filesystem::temp_directory_path().string());
}

std::string error_of(const std::vector<std::string>& sets) {
  try {
    load(sets);
    return "";
  } catch (const std::exception& e) {
    return e.what();
  }
}

TEST(dem_Ensemble, PerturbationIsSeededBoundedAndPerParticle) {
  const dem::RunConfig base = load({});
  const double a = 1e-7;
  const dem::RunConfig p1 = load({"particles.perturb={amplitude: 1e-7, seed: 1}"});
  const dem::RunConfig p1b = load({"particles.perturb={amplitude: 1e-7, seed: 1}"});
  const dem::RunConfig p2 = load({"particles.perturb={amplitude: 1e-7, seed: 2}"});
  ASSERT_EQ(base.state.size(), 200u);
  double max_d = 0, sum = 0, sum2 = 0, max_between = 0;
  int n = 0;
  for (std::size_t i = 0; i < base.state.size(); ++i) {
    ASSERT_EQ(p1.state.id[i], base.state.id[i]);
    const dem::Vec3 d = p1.state.x[i] - base.state.x[i];
    for (double c : {d.x, d.y, d.z}) {
      max_d = std::max(max_d, std::abs(c));
      sum += c;
      sum2 += c * c;
      ++n;
    }
    // Same seed: the same displacement, bit for bit.
    EXPECT_EQ(p1.state.x[i].x, p1b.state.x[i].x);
    EXPECT_EQ(p1.state.x[i].z, p1b.state.x[i].z);
    max_between = std::max(max_between, dem::norm(p2.state.x[i] - p1.state.x[i]));
  }
  EXPECT_LE(max_d, a * (1 + 1e-6));  // rounding of x + d
  EXPECT_GT(max_d, 0.9 * a);         // 600 draws of a uniform on [-a, a] reach 0.9 a
  // Uniform on [-a, a]: mean 0, variance a^2 / 3 (600 draws: the mean within 4 sigma).
  EXPECT_LT(std::abs(sum / n), 4 * a / std::sqrt(3.0 * n));
  EXPECT_NEAR(sum2 / n, a * a / 3, 0.25 * a * a / 3);
  EXPECT_GT(max_between, 0.5 * a);   // another seed, another displacement
}

TEST(dem_Ensemble, PerturbationDependsOnIdNotOnOrder) {
  // Reversing the particle order of a listed pair does not change each particle's shift.
  const auto shift_of_id = [](const dem::State& st, std::int64_t id, const dem::Vec3& at) {
    for (std::size_t i = 0; i < st.size(); ++i)
      if (st.id[i] == id) return st.x[i] - at;
    return dem::Vec3{1, 1, 1};
  };
  const dem::RunConfig p = load({"particles.perturb={amplitude: 1e-7, seed: 5}"});
  const dem::RunConfig base = load({});
  dem::State reversed = base.state;
  std::reverse(reversed.x.begin(), reversed.x.end());
  std::reverse(reversed.id.begin(), reversed.id.end());
  dem::perturb_positions(reversed, dem::Perturbation{1e-7, 5});
  for (std::size_t i = 0; i < base.state.size(); i += 17) {
    const dem::Vec3 a = shift_of_id(p.state, base.state.id[i], base.state.x[i]);
    const dem::Vec3 b = shift_of_id(reversed, base.state.id[i], base.state.x[i]);
    EXPECT_EQ(a.x, b.x);
    EXPECT_EQ(a.y, b.y);
    EXPECT_EQ(a.z, b.z);
  }
}

TEST(dem_Ensemble, PerturbationRefusedWhenNotNegligible) {
  EXPECT_NE(error_of({"particles.perturb={amplitude: 1e-4}"}).find("smallest radius"), std::string::npos);
  EXPECT_NE(error_of({"particles.perturb={amplitude: -1e-9}"}).find("particles.perturb.amplitude"),
            std::string::npos);
  EXPECT_NE(error_of({"particles.perturb={amplitude: 1e-9, seed: -1}"}).find("particles.perturb.seed"),
            std::string::npos);
  EXPECT_NE(error_of({"particles.perturb={amplitude: 1e-9, sed: 1}"}).find("sed"), std::string::npos);
  EXPECT_EQ(error_of({"particles.perturb={amplitude: 4.9e-5}"}), "");  // 1 % of r = 5 mm
}

TEST(dem_Ensemble, PayloadCountsCentresInTheToolsBoxAtItsPose) {
  // A box mesh 2 x 1 x 0.5 m about the reference point, turned 90 degrees about z and moved.
  const std::vector<dem::Vec3> c{{-1, -0.5, 0}, {1, -0.5, 0}, {1, 0.5, 0.5},
                                 {-1, -0.5, 0}, {1, 0.5, 0.5}, {-1, 0.5, 0.5}};
  const dem::Mesh mesh = dem::build_mesh(c, "box");
  dem::ToolPose pose;
  pose.position = {10, 0, 0};
  pose.orientation = {std::cos(M_PI / 4), 0, 0, std::sin(M_PI / 4)};  // x_tool -> y_ground
  dem::State s;
  demtest::add(s, {10, 0.9, 0.25}, {}, 0.01);   // tool x = 0.9: inside
  demtest::add(s, {10.4, 0, 0.25}, {}, 0.01);   // tool y = -0.4: inside
  demtest::add(s, {10.6, 0, 0.25}, {}, 0.01);   // tool y = -0.6: outside
  demtest::add(s, {10, 1.1, 0.25}, {}, 0.01);   // tool x = 1.1: outside
  demtest::add(s, {10, 0, 0.6}, {}, 0.01);      // above
  demtest::add(s, {10, -0.5, 0.01}, {}, 0.02);  // inside, heavier
  const double expected = s.mass[0] + s.mass[1] + s.mass[5];
  EXPECT_DOUBLE_EQ(dem::payload_mass(s, mesh, pose), expected);
  pose.position = {0, 0, 0};
  EXPECT_EQ(dem::payload_mass(s, mesh, pose), 0.0);
}

}  // namespace
