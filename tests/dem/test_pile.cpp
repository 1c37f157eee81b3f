// A settled pile carries exactly its weight on the floor (plane or mesh) and does not creep;
// runs with the same thread count are bit-identical.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

constexpr double kR = 0.005;

struct Pile {
  dem::Scene scene;
  State st;
};

Pile make_pile(bool mesh_floor, int threads) {
  Pile p;
  p.scene = one_species_scene(0.8 * kR, kR);
  p.scene.gravity = {0, 0, -9.81};
  p.scene.threads = threads;
  p.scene.particle_particle = p.scene.particle_wall = law_n_per_m(2e4, 0.3, true, 0.5, 1.0, 0.5);
  if (mesh_floor) {
    std::vector<Vec3> c;
    quad(c, {-0.2, -0.2, 0}, {0.2, -0.2, 0}, {0.2, 0.2, 0}, {-0.2, 0.2, 0});
    p.scene.tools.push_back(static_tool("floor", c));
  } else {
    p.scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
  }
  const double m_small = sphere_mass(0.8 * kR);
  p.scene.dt = M_PI / std::sqrt(2e4 / m_small) / 25;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> U(0, 1);
  const double h = 2.2 * kR;
  for (int iz = 0; iz < 6; ++iz)
    for (int iy = 0; iy < 5; ++iy)
      for (int ix = 0; ix < 5; ++ix) {
        const double r = kR * (0.8 + 0.2 * U(rng));
        add(p.st, {(ix - 2) * h + 0.1 * kR * U(rng), (iy - 2) * h + 0.1 * kR * U(rng),
                   kR + 0.001 + iz * h},
            {}, r);
      }
  p.st.tool_pose.resize(p.scene.tools.size());
  return p;
}

double weight(const State& st) {
  double m = 0;
  for (double mi : st.mass) m += mi;
  return m * 9.81;
}

void check_pile(bool mesh_floor) {
  Pile p = make_pile(mesh_floor, 2);
  dem::Engine engine(p.scene);
  auto floor_load = [&] {
    return mesh_floor ? -engine.tool_wrenches()[0].force.z : -engine.wall_forces()[0].z;
  };
  while (p.st.step * p.scene.dt < 1.5) engine.step(p.st);
  const std::vector<Vec3> x_settled = p.st.x;
  const std::vector<std::int64_t> id_settled = p.st.id;
  double worst = 0;
  while (p.st.step * p.scene.dt < 2.0) {
    engine.step(p.st);
    worst = std::max(worst, std::abs(floor_load() / weight(p.st) - 1));
  }
  // Creep: every particle (matched by id, the broad phase reorders) moved less than 1e-6 r.
  double moved = 0;
  for (std::size_t a = 0; a < p.st.size(); ++a) {
    const std::size_t b = index_of(p.st, id_settled[a]);
    moved = std::max(moved, norm(p.st.x[b] - x_settled[a]));
  }
  std::printf("%s floor: worst |load/weight - 1| over 0.5 s = %.2e, max creep %.2e m, KE %.2e J\n",
              mesh_floor ? "mesh" : "plane", worst, moved, dem::kinetic_energy(p.st));
  EXPECT_LT(worst, 1e-3);
  EXPECT_LT(moved, 1e-6 * kR);
}

TEST(dem_Pile, PlaneFloorCarriesTheWeightAndDoesNotCreep) { check_pile(false); }
TEST(dem_Pile, MeshFloorCarriesTheWeightAndDoesNotCreep) { check_pile(true); }

TEST(dem_Pile, SameThreadCountIsBitIdentical) {
  for (int threads : {1, 2}) {
    Pile a = make_pile(true, threads), b = make_pile(true, threads);
    dem::EngineOptions options;
    options.min_particles_per_thread = 1;  // really 2 threads
    dem::Engine ea(a.scene, options), eb(b.scene, options);
    for (int k = 0; k < 3000; ++k) {
      ea.step(a.st);
      eb.step(b.st);
    }
    ASSERT_EQ(a.st.x.size(), b.st.x.size());
    EXPECT_EQ(0, std::memcmp(a.st.x.data(), b.st.x.data(), a.st.x.size() * sizeof(Vec3)))
        << threads << " threads";
    EXPECT_EQ(0, std::memcmp(a.st.v.data(), b.st.v.data(), a.st.v.size() * sizeof(Vec3)));
  }
}

}  // namespace
