// A tiny blade scene (docs/soil_blade.md): a random bed prepared with `prepare:` in a
// plane-strain bin (smooth side walls), a vertical blade with its own contact law pushed through
// it at two depths. The draft force is positive, grows with depth and is of the size of the
// passive wedge for a dense sand (Reece's equation; the depth-squared trend needs deeper cuts
// than a test of seconds affords and is measured by the benchmark). The
// full comparison with theory is bench/soil/blade_validation.py; this checks that the scene the
// benchmark relies on runs and pulls the right way.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <iostream>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem/earthmoving.hpp"
#include "dem/engine.hpp"
#include "dem/packing.hpp"

namespace {

namespace fs = std::filesystem;

constexpr double kL = 0.12, kW = 0.03, kH = 0.06;  // bin length, width (3 diameters), bed height
constexpr double kSpeed = 0.05, kTravel = 0.04, kSteadyFrom = 0.02;

std::string head(double region_top) {
  std::ostringstream s;
  s << "scene: {dt: 2.0e-5, gravity: [0, 0, -9.81]";
  if (region_top > 0) s << ", region: {min: [-1, -1, -1], max: [2, 2, " << region_top << "]}";
  s << R"(}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: {distribution: uniform, min: 0.0045, max: 0.0055}}]
contact:
  particle_particle: {normal_stiffness: 2.0e4, stiffness_unit: N/m, restitution: 0.3,
                      tangential_stiffness_ratio: 0.5, friction: 0.2}
walls:
  - {name: floor, type: plane, point: [0, 0, 0], normal: [0, 0, 1]}
  - {name: back, type: plane, point: [0, 0, 0], normal: [1, 0, 0], contact: {friction: 0.0}}
  - {name: front, type: plane, point: [0.12, 0, 0], normal: [-1, 0, 0], contact: {friction: 0.0}}
  - {name: side0, type: plane, point: [0, 0, 0], normal: [0, 1, 0], contact: {friction: 0.0}}
  - {name: side1, type: plane, point: [0, 0.03, 0], normal: [0, -1, 0], contact: {friction: 0.0}}
)";
  return s.str();
}

// Mean draft (-F_x on the blade) over the second half of the travel, blade tip at `depth`
// below `surface`, grains rising one diameter above the surface removed.
double draft(const fs::path& dir, double surface, double depth) {
  std::ostringstream s;
  s << head(surface + 0.01) << R"(tools:
  - name: blade
    mesh: blade.obj
    contact: {friction: 0.2}
    motion:
      keyframes:
        - {time: 0.0, position: [0.0, 0.0, )" << surface - depth << R"(], orientation: [1, 0, 0, 0]}
        - {time: )" << kTravel / kSpeed << ", position: [" << kTravel << ", 0.0, " << surface - depth
    << R"(], orientation: [1, 0, 0, 0]}
particles: {checkpoint: bed.h5}
)";
  dem::RunConfig rc = dem::load_config(YAML::Load(s.str()), dir.string());
  dem::Engine engine(rc.scene);
  dem::State st = rc.state;
  const long steps = std::lround(kTravel / kSpeed / rc.scene.dt);
  double sum = 0;
  long n = 0;
  for (long k = 0; k < steps; ++k) {
    st.tool_pose.at(0) = rc.scene.tools.at(0).motion.evaluate(st.step * rc.scene.dt);  // as dem_run
    engine.step(st);
    if ((k + 1) * rc.scene.dt * kSpeed >= kSteadyFrom) {
      sum += -engine.tool_wrenches().at(0).force.x;
      ++n;
    }
  }
  return sum / n;
}

TEST(dem_Blade, DraftIsPositiveGrowsWithDepthAndIsTheWedgesSize) {
  const fs::path dir = fs::temp_directory_path() / "dem_blade_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  // A vertical blade: two triangles from the tip line (y across the bin) up 10 cm.
  std::ofstream(dir / "blade.obj") << "v 0 -0.005 0\nv 0 0.035 0\nv 0 0.035 0.1\nv 0 -0.005 0.1\n"
                                      "f 1 2 3\nf 1 3 4\n";
  // The bed: random insertion, frictionless deposition, frozen with mu 0.2.
  std::ostringstream bed;
  bed << head(0) << R"(particles:
  insert: [{species: grain, min: [0, 0, 0], max: [0.12, 0.03, 0.16], count: 250, seed: 3}]
)";
  dem::RunConfig rc = dem::load_config(YAML::Load(bed.str()), dir.string());
  dem::PrepareOptions po;
  po.enabled = true;
  po.ke_per_particle = 1e-8;
  po.max_time = 2.0;
  po.margin = 0.5;
  dem::State st = rc.state;
  const dem::PrepareResult pr = dem::prepare_bed(rc.scene, st, po);
  ASSERT_TRUE(pr.deposition_converged && pr.freeze_converged);
  EXPECT_GT(pr.packing.fraction, 0.55);  // a dense random bed, not a lattice
  dem::save_checkpoint(st, (dir / "bed.h5").string());
  // Surface: the mean of the highest grain top in each 1 cm column.
  double surface = 0;
  int columns = 0;
  for (double x0 = 0.01; x0 < kL - 0.015; x0 += 0.01) {
    double top = 0;
    for (std::size_t i = 0; i < st.size(); ++i)
      if (st.x[i].x >= x0 && st.x[i].x < x0 + 0.01) top = std::max(top, st.x[i].z + st.radius[i]);
    surface += top;
    ++columns;
  }
  surface /= columns;
  ASSERT_GT(surface, 0.045);
  ASSERT_LT(surface, 0.07);

  const double shallow = draft(dir, surface, 0.02), deep = draft(dir, surface, 0.04);
  // Reece: gamma d^2 N_gamma,h w for phi 35.7 deg (the triaxial peak of this law,
  // docs/soil_blade.md) and delta atan(0.2); gamma from packing 0.6 at 2600 kg/m^3.
  const double k = M_PI / 180, gamma = 0.6 * 2600 * 9.81;
  const double theory_deep = dem::reece_draft(gamma, 0.04, kW, 90 * k, 35.7 * k, std::atan(0.2));
  std::cout << "draft at 2 cm " << shallow << " N, at 4 cm " << deep << " N (Reece " << theory_deep
            << " N at 4 cm), packing " << pr.packing.fraction << "\n";
  EXPECT_GT(shallow, 0.0);
  // Twice the depth: 4 times the force in theory. This scene is 2 and 4 grain diameters deep,
  // too shallow for the square law (seeds 1-6 gave 2.0-3.5x; the square law is measured by the
  // benchmark at 4 and 6 diameters, docs/soil_blade.md): a force that does not grow fails.
  EXPECT_GT(deep, 1.5 * shallow);
  // The size of the wedge's force: a law far stronger than sand (the main job's mu 0.6 draws
  // 5-13x, issue 43) or a blade that barely touches the soil fails.
  EXPECT_GT(deep, 0.5 * theory_deep);
  EXPECT_LT(deep, 2.0 * theory_deep);
  fs::remove_all(dir);
}

}  // namespace
