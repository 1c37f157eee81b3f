// Coarse graining (particles.coarse_grain, dem/coarse_grain.hpp, docs/soil_models.md): the
// scaled parameters follow the documented scaling, the physics it is meant to keep is kept
// (damping ratio, steps per contact, overlap of a bed of the same depth), bad input is refused.
#include <gtest/gtest.h>

#include <filesystem>

#include "cosim/yaml_config.hpp"
#include "dem/coarse_grain.hpp"
#include "dem/config.hpp"
#include "dem/stability.hpp"
#include "dem_test_util.hpp"

namespace {

const char* kBase = R"(
scene: {dt: 2.0e-6, threads: 1, gravity: [0, 0, -9.81]}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: {distribution: uniform, min: 0.004, max: 0.006}}]
contact:
  particle_particle: {normal_stiffness: 4.0e7, stiffness_unit: Pa, restitution: 0.3, friction: 0.5,
                      tangential_stiffness_ratio: 0.5}
  particle_wall: {normal_stiffness: 2.0e5, stiffness_unit: N/m, normal_damping: 3.0, friction: 0.4}
walls: [{name: bin, type: box, min: [0, 0, 0], max: [0.2, 0.2, 0.4], open_top: true}]
particles:
  fill: [{species: grain, min: [0, 0, 0], max: [0.2, 0.2, 0.3], count: 800, seed: 3}]
)";

dem::RunConfig load(const std::vector<std::string>& sets) {
  YAML::Node root = YAML::Load(kBase);
  for (const auto& s : sets) cosim::config::apply_override(root, s);
  return dem::load_config(root, std::filesystem::temp_directory_path().string());
}

TEST(dem_CoarseGrain, ParametersFollowTheDocumentedScaling) {
  const dem::RunConfig a = load({});
  for (const double s : {1.5, 2.0, 3.0}) {
    const dem::RunConfig b = load({"particles.coarse_grain=" + std::to_string(s)});
    const dem::Scene &A = a.scene, &B = b.scene;
    EXPECT_DOUBLE_EQ(B.species[0].radius.min, s * A.species[0].radius.min);
    EXPECT_DOUBLE_EQ(B.species[0].radius.max, s * A.species[0].radius.max);
    EXPECT_EQ(B.species[0].density, A.species[0].density);
    // k_N in Pa: unchanged (k in N/m grows with the effective length by itself)
    EXPECT_EQ(B.particle_particle.normal_stiffness, A.particle_particle.normal_stiffness);
    // k_N in N/m x s, a damping coefficient x s^2, dt x s
    EXPECT_DOUBLE_EQ(B.particle_wall.normal_stiffness, s * A.particle_wall.normal_stiffness);
    EXPECT_DOUBLE_EQ(B.particle_wall.normal_damping, s * s * A.particle_wall.normal_damping);
    EXPECT_DOUBLE_EQ(B.dt, s * A.dt);
    // dimensionless: unchanged
    EXPECT_EQ(B.particle_particle.restitution, A.particle_particle.restitution);
    EXPECT_EQ(B.particle_particle.friction, A.particle_particle.friction);
    EXPECT_EQ(B.particle_wall.friction, A.particle_wall.friction);
    EXPECT_EQ(B.particle_particle.tangential_stiffness_ratio, A.particle_particle.tangential_stiffness_ratio);
    EXPECT_EQ(B.skin, A.skin);
    // the same volume of soil: count / s^3
    ASSERT_EQ(b.fill.size(), 1u);
    EXPECT_EQ(b.fill[0].count, std::llround(800 / (s * s * s)));
    EXPECT_EQ(b.state.size(), static_cast<std::size_t>(b.fill[0].count));
    // What the scaling keeps: the steps per contact (the safe dt scales with the grain), and the
    // damping ratio of the wall law (eta / (2 sqrt(m k)) with m ~ s^3, k ~ s, eta ~ s^2).
    EXPECT_NEAR(dem::largest_safe_dt(B) / dem::largest_safe_dt(A), s, 1e-9 * s);
    const double m_a = A.species[0].mass(A.species[0].radius.max);
    const double m_b = B.species[0].mass(B.species[0].radius.max);
    const dem::ContactCoefficients ca = dem::coefficients(A.particle_wall, A.species[0].radius.max, m_a);
    const dem::ContactCoefficients cb = dem::coefficients(B.particle_wall, B.species[0].radius.max, m_b);
    EXPECT_NEAR(cb.eta / (2 * std::sqrt(m_b * cb.k)), ca.eta / (2 * std::sqrt(m_a * ca.k)), 1e-12);
    // One grain on another overlaps by delta / r = m g / (k r) ~ s (weight ~ s^3, k ~ s), but
    // the bottom contact of a column of depth h (h / 2r grains) keeps delta / r = rho g h / k_Pa
    // up to a constant: the point of the Pa law.
    const double ka = dem::coefficients(A.particle_particle, A.species[0].radius.max / 2, m_a / 2).k;
    const double kb = dem::coefficients(B.particle_particle, B.species[0].radius.max / 2, m_b / 2).k;
    const double h = 0.3;
    const double column_a = (h / (2 * A.species[0].radius.max)) * m_a * 9.81 / ka / A.species[0].radius.max;
    const double column_b = (h / (2 * B.species[0].radius.max)) * m_b * 9.81 / kb / B.species[0].radius.max;
    EXPECT_NEAR(column_b / column_a, 1.0, 1e-12);
  }
  EXPECT_EQ(dem::coarse_grain_count(1, 3.0), 1);
  EXPECT_EQ(dem::coarse_grain_count(0, 3.0), 0);
}

TEST(dem_CoarseGrain, BadInputIsRefusedByName) {
  for (const char* bad : {"0", "-2", "20", ".nan", "two"}) {
    try {
      load({std::string("particles.coarse_grain=") + bad});
      ADD_FAILURE() << "coarse_grain " << bad << " accepted";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("particles.coarse_grain"), std::string::npos) << e.what();
    }
  }
  try {
    YAML::Node root = YAML::Load(kBase);
    root["particles"]["list"] = YAML::Load("[{species: grain, position: [0.1, 0.1, 0.35]}]");
    cosim::config::apply_override(root, "particles.coarse_grain=2");
    dem::load_config(root, std::filesystem::temp_directory_path().string());
    ADD_FAILURE() << "coarse_grain with a list accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("particles.coarse_grain"), std::string::npos) << e.what();
  }
}

}  // namespace
