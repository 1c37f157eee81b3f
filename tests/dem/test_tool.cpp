// Tools: meshes from STL/OBJ/PLY, keyframe motion (linear, cubic, slerp), the wrench about the
// reference point; beds: filling and settling; blow-ups stop with a clear message.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "dem/bed.hpp"
#include "dem/config.hpp"
#include "dem/stability.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;
namespace fs = std::filesystem;

const std::string kMeshes = std::string(DEM_SOURCE_DIR) + "/configs/dem/meshes/";

TEST(dem_Tool, LoadsStlObjPlyAndWeldsSharedCorners) {
  // bucket.stl: 4 quads = 8 triangles, corners stored per triangle in the file.
  const dem::Mesh stl = dem::load_mesh(kMeshes + "bucket.stl", 1.0, {});
  EXPECT_EQ(stl.triangles.size(), 8u);
  EXPECT_EQ(stl.vertices.size(), 8u);  // welded: the box corners and the two top-front ones
  const dem::Mesh obj = dem::load_mesh(kMeshes + "blade.obj", 2.0, {0.1, 0, 0});
  EXPECT_EQ(obj.triangles.size(), 4u);
  EXPECT_EQ(obj.vertices.size(), 6u);
  // The bend edge and the two diagonals are shared by two triangles, the rest by one.
  int shared = 0;
  for (int v : obj.edge_valence) shared += v == 2;
  EXPECT_EQ(shared, 3);
  // Scale then shift by the reference point: file vertex (0.2, -0.1, 0) -> (0.3, -0.2, 0).
  bool found = false;
  for (const Vec3& p : obj.vertices)
    found |= std::abs(p.x - 0.3) < 1e-6 && std::abs(p.y + 0.2) < 1e-6 && std::abs(p.z) < 1e-9;
  EXPECT_TRUE(found);
  const dem::Mesh ply = dem::load_mesh(kMeshes + "floor.ply", 1.0, {});
  EXPECT_EQ(ply.triangles.size(), 2u);
  EXPECT_NEAR(ply.bounding_radius, std::sqrt(0.5), 1e-6);
}

TEST(dem_Tool, MotionInterpolatesPositionAndOrientation) {
  dem::ToolMotion m;
  const double s = std::sin(M_PI / 4), c = std::cos(M_PI / 4);  // 90 degrees about z
  m.keyframes = {{0, {0, 0, 0}, {1, 0, 0, 0}}, {1, {1, 2, 0}, {c, 0, 0, s}},
                 {2, {1, 2, 2}, {c, 0, 0, s}}};
  const dem::ToolPose p = m.evaluate(0.5);
  EXPECT_NEAR(p.position.x, 0.5, 1e-12);
  EXPECT_NEAR(p.position.y, 1.0, 1e-12);
  EXPECT_NEAR(p.velocity.y, 2.0, 1e-12);
  // Half way: 45 degrees about z.
  EXPECT_NEAR(p.orientation.w, std::cos(M_PI / 8), 1e-12);
  EXPECT_NEAR(p.orientation.z, std::sin(M_PI / 8), 1e-12);
  EXPECT_NEAR(p.angular_velocity.z, M_PI / 2, 1e-9);
  // Held outside the range.
  EXPECT_NEAR(m.evaluate(5).position.z, 2, 1e-12);
  EXPECT_EQ(m.evaluate(5).velocity.z, 0);
  // Cubic passes through the keyframes, with a continuous velocity at the inner one.
  m.interpolation = dem::ToolMotion::Interpolation::cubic;
  EXPECT_NEAR(m.evaluate(1.0).position.y, 2, 1e-12);
  const double v_before = m.evaluate(1 - 1e-7).velocity.z, v_after = m.evaluate(1 + 1e-7).velocity.z;
  EXPECT_NEAR(v_before, v_after, 1e-5);
  EXPECT_NEAR(v_before, 1.0, 1e-5);  // Catmull-Rom: (2 - 0) / (2 - 0)
}

TEST(dem_Tool, CsvKeyframesAndErrors) {
  const fs::path dir = fs::temp_directory_path();
  const fs::path good = dir / "dem_motion.csv", bad = dir / "dem_motion_bad.csv";
  std::ofstream(good) << "time,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n1,1,0,0,1,0,0,0\n";
  std::ofstream(bad) << "time,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n1,1,0,0\n";
  EXPECT_EQ(dem::load_keyframes_csv(good.string()).size(), 2u);
  try {
    dem::load_keyframes_csv(bad.string());
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(":3:"), std::string::npos) << e.what();
  }
}

TEST(dem_Tool, WrenchIsForceAndTorqueAboutReferencePoint) {
  // A sphere resting on a static plate 0.3 m from the reference point (origin).
  dem::Scene scene = one_species_scene(0.01, 0.01);
  scene.gravity = {0, 0, -9.81};
  scene.particle_particle = scene.particle_wall = law_n_per_m(2e4, 0.3, true, 0.5);
  std::vector<Vec3> c;
  quad(c, {0.2, -0.1, 0}, {0.4, -0.1, 0}, {0.4, 0.1, 0}, {0.2, 0.1, 0});
  scene.tools.push_back(static_tool("plate", c));
  scene.dt = M_PI / std::sqrt(2e4 / sphere_mass(0.01)) / 30;
  dem::State st;
  add(st, {0.3, 0.05, 0.0099}, {}, 0.01);
  st.tool_pose.resize(1);
  dem::Engine engine(scene);
  for (int k = 0; k < 20000; ++k) engine.step(st);
  const dem::Wrench w = engine.tool_wrenches()[0];
  const double weight = sphere_mass(0.01) * 9.81;
  EXPECT_NEAR(w.force.z, -weight, 1e-9 * weight);
  // Torque of -W e_z applied at (0.3, 0.05, 0) about the origin: (-0.05 W, 0.3 W, 0).
  EXPECT_NEAR(w.torque.x, -0.05 * weight, 1e-6 * weight);
  EXPECT_NEAR(w.torque.y, 0.3 * weight, 1e-6 * weight);
  EXPECT_NEAR(w.torque.z, 0, 1e-9 * weight);
}

TEST(dem_Bed, FillIsSeededNonOverlappingAndSettles) {
  dem::Scene scene = one_species_scene(0.004, 0.006);
  scene.gravity = {0, 0, -9.81};
  scene.threads = 2;
  scene.particle_particle = scene.particle_wall = law_n_per_m(3e4, 0.3, true, 0.5);
  scene.walls = {{"floor", {0, 0, 0}, {0, 0, 1}}, {"x0", {0, 0, 0}, {1, 0, 0}},
                 {"x1", {0.08, 0, 0}, {-1, 0, 0}}, {"y0", {0, 0, 0}, {0, 1, 0}},
                 {"y1", {0, 0.08, 0}, {0, -1, 0}}};
  scene.dt = 2e-5;
  dem::FillRegion r{0, {0, 0, 0}, {0.08, 0.08, 0.2}, 300, 9};
  dem::State a, b;
  dem::fill_region(scene, r, a);
  dem::fill_region(scene, r, b);
  ASSERT_EQ(a.size(), 300u);
  EXPECT_EQ(0, std::memcmp(a.x.data(), b.x.data(), a.size() * sizeof(Vec3)));  // seeded
  scene.stability.overlap_tolerance = 0;
  EXPECT_NO_THROW(dem::validate_state(scene, a));  // no overlap at all
  double rmin = 1, rmax = 0;
  for (double rr : a.radius) rmin = std::min(rmin, rr), rmax = std::max(rmax, rr);
  EXPECT_GE(rmin, 0.004);
  EXPECT_LE(rmax, 0.006);
  EXPECT_GT(rmax - rmin, 0.0015);  // the distribution is used, not a constant
  r.count = 100000;
  EXPECT_THROW(dem::fill_region(scene, r, b), std::exception);  // region too small: refused
  a.tool_pose.clear();
  dem::Engine engine(scene);
  const dem::SettleResult res = dem::settle(engine, a, 1e-8, 1.5);
  EXPECT_TRUE(res.converged);
  EXPECT_LT(res.ke_per_particle, 1e-8);
  double zmax = 0, zsum = 0;
  for (const Vec3& x : a.x) zmax = std::max(zmax, x.z), zsum += x.z;
  std::printf("settled in %.3f s: KE/particle %.2e J, mean z %.4f, max z %.4f\n", res.time,
              res.ke_per_particle, zsum / a.size(), zmax);
  // It fell: filled up to z = 0.2 with mean ~0.1, a loose bed of 300 is ~0.08 high.
  EXPECT_LT(zmax, 0.15);
  EXPECT_LT(zsum / a.size(), 0.06);
}

TEST(dem_Stability, BlowUpStopsNamingStepParticleAndSafeDt) {
  dem::Scene scene = one_species_scene(0.01, 0.01);
  scene.gravity = {0, 0, -9.81};  // a lasting contact: the instability grows every step
  scene.particle_particle = scene.particle_wall = law_n_per_m(2e4, 0.9, false);
  scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
  const double tc = M_PI / std::sqrt(2e4 / sphere_mass(0.01));
  scene.dt = tc / 0.9;  // omega dt > 2: unstable
  scene.stability.max_speed = 5;
  std::ostringstream warn;
  EXPECT_THROW(dem::check_dt(scene, warn), std::invalid_argument);
  scene.stability.on_violation = dem::DtViolation::warn;
  dem::check_dt(scene, warn);
  EXPECT_NE(warn.str().find("Use scene.dt <="), std::string::npos) << warn.str();
  dem::State st;
  add(st, {0, 0, 0.00999}, {}, 0.01);
  dem::Engine engine(scene);
  try {
    for (int k = 0; k < 100000; ++k) engine.step(st);
    FAIL() << "no blow-up detected";
  } catch (const dem::SimulationError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("blow-up at step"), std::string::npos) << msg;
    EXPECT_NE(msg.find("particle id 0"), std::string::npos) << msg;
    EXPECT_NE(msg.find("largest safe"), std::string::npos) << msg;
  }
}

}  // namespace
