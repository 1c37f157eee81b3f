// Checkpoint -> restore -> continue equals the uninterrupted run bit for bit.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;

// A small bed with a moving tool, so pair history, mesh slots and tool poses all matter.
std::pair<dem::Scene, dem::State> scene_with_tool(int threads) {
  dem::Scene scene = one_species_scene(0.004, 0.006);
  scene.gravity = {0, 0, -9.81};
  scene.threads = threads;
  scene.particle_particle = scene.particle_wall = law_n_per_m(5e4, 0.3, true, 0.5, 0.5, 0.5);
  scene.walls = {{"floor", {0, 0, 0}, {0, 0, 1}}, {"x0", {0, 0, 0}, {1, 0, 0}},
                 {"x1", {0.1, 0, 0}, {-1, 0, 0}}, {"y0", {0, 0, 0}, {0, 1, 0}},
                 {"y1", {0, 0.1, 0}, {0, -1, 0}}};
  std::vector<Vec3> c;
  quad(c, {-0.02, -0.04, 0}, {0.02, -0.04, 0.01}, {0.02, 0.04, 0.01}, {-0.02, 0.04, 0});
  dem::Tool tool = static_tool("plate", c);
  tool.motion.keyframes = {{0, {0.0, 0.05, 0.03}, {1, 0, 0, 0}},
                           {0.2, {0.1, 0.05, 0.02}, {0.98, 0, 0.2, 0}}};
  dem::validate_keyframes(tool.motion.keyframes, "test");
  scene.tools.push_back(tool);
  scene.dt = 2e-5;
  dem::State st;
  dem::FillRegion r;
  r.min = {0, 0, 0};
  r.max = {0.1, 0.1, 0.1};
  r.count = 250;
  r.seed = 5;
  dem::fill_region(scene, r, st);
  st.tool_pose = {tool.motion.evaluate(0)};
  return {scene, st};
}

void advance(const dem::Scene& scene, dem::Engine& e, dem::State& s, int steps) {
  for (int k = 0; k < steps; ++k) {
    s.tool_pose[0] = scene.tools[0].motion.evaluate(s.step * scene.dt);
    e.step(s);
  }
}

template <class T>
bool same(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

TEST(dem_Checkpoint, RestoreAndContinueIsBitIdentical) {
  for (int threads : {1, 2}) {
    auto [scene, a] = scene_with_tool(threads);
    dem::EngineOptions options;
    options.min_particles_per_thread = 1;  // 250 particles: force the requested thread count
    dem::Engine ea(scene, options);
    advance(scene, ea, a, 3003);  // mid-interval: steps_since_rebuild != 0
    const std::string file =
        (std::filesystem::temp_directory_path() / ("dem_ckpt_" + std::to_string(threads) + ".h5"))
            .string();
    dem::save_checkpoint(a, file);
    dem::State b = dem::load_checkpoint(file);
    std::filesystem::remove(file);
    dem::Engine eb(scene, options);  // a fresh engine: nothing may hide in its workspace
    advance(scene, ea, a, 2000);
    advance(scene, eb, b, 2000);
    EXPECT_TRUE(same(a.x, b.x)) << threads << " threads";
    EXPECT_TRUE(same(a.v, b.v));
    EXPECT_TRUE(same(a.pair_spring, b.pair_spring));
    EXPECT_TRUE(same(a.slot_spring, b.slot_spring));
    EXPECT_TRUE(same(a.id, b.id));
    EXPECT_EQ(a.rebuilds, b.rebuilds);
    const auto& wa = ea.tool_wrenches()[0];
    const auto& wb = eb.tool_wrenches()[0];
    EXPECT_EQ(0, std::memcmp(&wa, &wb, sizeof wa));
    EXPECT_GT(std::abs(wa.force.x) + std::abs(wa.force.z), 0) << "tool never touched the bed";
    // Something actually happened (else bit-identity would be trivial).
    std::size_t springs = 0;
    for (const Vec3& s : a.pair_spring) springs += norm2(s) > 0;
    EXPECT_GT(springs, 30u);
  }
}

TEST(dem_Checkpoint, MissingOrForeignFileIsRefused) {
  try {
    dem::load_checkpoint("/nonexistent/bed.h5");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/bed.h5"), std::string::npos);
  }
}

}  // namespace
