// Small builders shared by the DEM tests: programmatic scenes without YAML.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "dem/engine.hpp"
#include "dem/mesh.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace demtest {

// The pair kernels a bit-identity test runs the engine with: the scalar loop, the AVX-512 chunk
// kernel's source with its lanes emulated (any processor), the AVX-512 kernel itself where
// the processor has it, and the AVX2 one where it has that. None is skipped for want of AVX-512.
inline std::vector<dem::EngineOptions::PairKernel> pair_kernels() {
  using K = dem::EngineOptions::PairKernel;
  std::vector<K> k{K::scalar, K::emulated};
  if (dem::detail::pair_rows_vector_available()) k.push_back(K::vector);
  if (dem::detail::pair_rows_avx2_available()) k.push_back(K::avx2);
  return k;
}
inline const char* kernel_name(dem::EngineOptions::PairKernel k) {
  using K = dem::EngineOptions::PairKernel;
  return k == K::vector     ? "vector"
         : k == K::emulated ? "emulated"
         : k == K::avx2     ? "avx2"
                            : "scalar";
}

using dem::Vec3;

inline dem::ContactLaw law_n_per_m(double k, double e, bool clip, double mu = 0.0,
                                   double kt_ratio = 1.0, double etat_ratio = 0.5) {
  dem::ContactLaw l;
  l.stiffness_per_length = false;
  l.normal_stiffness = k;
  l.damping_from_restitution = true;
  l.restitution = e;
  l.clip_attractive = clip;
  l.friction = mu;
  l.tangential_stiffness_ratio = kt_ratio;
  l.tangential_damping_ratio = etat_ratio;
  dem::finalize(l, "test");
  return l;
}

inline dem::Scene one_species_scene(double rmin, double rmax, double density = 2500) {
  dem::Scene s;
  dem::Species sp;
  sp.name = "grain";
  sp.density = density;
  sp.radius.kind = rmin == rmax ? dem::RadiusDistribution::Kind::constant
                                : dem::RadiusDistribution::Kind::uniform;
  sp.radius.min = rmin;
  sp.radius.max = rmax;
  s.species.push_back(sp);
  s.gravity = {0, 0, 0};
  s.threads = 1;
  return s;
}

inline double sphere_mass(double r, double density = 2500) {
  return density * 4.0 / 3.0 * M_PI * r * r * r;
}

inline void add(dem::State& st, Vec3 x, Vec3 v, double r, double density = 2500) {
  dem::add_particle(st, x, v, r, sphere_mass(r, density), 0, static_cast<std::int64_t>(st.size()));
}

// Index of the particle with the given id (the broad phase reorders particles).
// 150 spheres of radius 0.8-1 r on a jittered 5 x 5 x 6 lattice (spacing 2.2 r, jitter 0.1 r)
// just above a floor at z = 0: the piles that the sleep tests drop and let settle.
inline void add_jittered_block(dem::State& st, double r, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  const double h = 2.2 * r;
  for (int iz = 0; iz < 6; ++iz)
    for (int iy = 0; iy < 5; ++iy)
      for (int ix = 0; ix < 5; ++ix)
        add(st, {(ix - 2) * h + 0.1 * r * U(rng), (iy - 2) * h + 0.1 * r * U(rng),
                 r + 0.001 + iz * h},
            {}, r * (0.8 + 0.2 * U(rng)));
}

// The scene thrown_lattice() runs in: one species (r 0.8-1.2 mm), broad phase when needed, one
// frictional law (500 N/m, e 0.3, mu 0.5) for pairs and walls, dt 2e-5 s, gravity, a floor at
// z = -1.5 mm. The tests add their own plate.
inline dem::Scene thrown_lattice_scene(int threads) {
  dem::Scene scene = one_species_scene(0.8e-3, 1.2e-3);
  scene.threads = threads;
  scene.broad_phase_interval = 1 << 30;  // when needed
  scene.particle_particle = scene.particle_wall = law_n_per_m(500, 0.3, true, 0.5);
  scene.dt = 2e-5;
  scene.gravity = {0, 0, -9.81};
  dem::Wall floor;
  floor.name = "floor";
  floor.point = {0, 0, -1.5e-3};
  floor.normal = {0, 0, 1};
  scene.walls.push_back(floor);
  return scene;
}

// Two grains (r 1 cm) near the origin inside 9 planes 5 mm from it, a cage of more walls than
// kBoundarySlots, so that a step stops with the boundary overflow error; dt 1e-4 s, gravity.
inline std::pair<dem::Scene, dem::State> caged_pair_scene(int threads) {
  dem::Scene scene = one_species_scene(0.01, 0.01);
  scene.threads = threads;
  scene.particle_particle = scene.particle_wall = law_n_per_m(1e3, 0.5, true);
  scene.dt = 1e-4;
  scene.gravity = {0, 0, -9.81};
  dem::State st;
  add(st, {0, 0, 0}, {0.1, 0, 0}, 0.01);
  add(st, {0.001, 0, 0}, {0, 0.1, 0}, 0.01);
  for (int w = 0; w < 9; ++w) {
    const double a = 2 * M_PI * w / 9;
    const Vec3 n{std::cos(a), std::sin(a), w % 2 ? 0.3 : -0.3};
    dem::Wall wall;
    wall.name = "w" + std::to_string(w);
    wall.normal = (1 / dem::norm(n)) * n;
    wall.point = -0.005 * wall.normal;
    scene.walls.push_back(wall);
  }
  static_assert(dem::kBoundarySlots < 9, "the cage must hold more walls than slots");
  return {scene, st};
}

// `count` grains of radius 0.8-1.2 mm on a 12 x 12 lattice of pitch 2.3 mm, each with a random
// creep below 4 mm/s and every 25th thrown at 0.5 m/s along x and down: the scene of the pair-block
// and one-region tests (seed 11).
inline dem::State thrown_lattice(int count, unsigned seed = 11) {
  dem::State st;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U01(0, 1);
  const double pitch = 2.3e-3;
  for (int k = 0; k < count; ++k) {
    const double r = 0.8e-3 + 0.4e-3 * U01(rng);
    Vec3 v{U01(rng) - 0.5, U01(rng) - 0.5, U01(rng) - 0.5};
    v = (4e-3 * U01(rng) / std::max(1e-9, dem::norm(v))) * v;
    if (k % 25 == 0) v = {0.5, 0.1 * (U01(rng) - 0.5), -0.2};
    add(st, {pitch * (k % 12), pitch * ((k / 12) % 12), pitch * (k / 144)}, v, r);
  }
  st.tool_pose.resize(1);
  return st;
}

inline std::size_t index_of(const dem::State& st, std::int64_t id) {
  for (std::size_t i = 0; i < st.size(); ++i)
    if (st.id[i] == id) return i;
  return st.size();
}

inline dem::Tool static_tool(const std::string& name, const std::vector<Vec3>& corners) {
  dem::Tool t;
  t.name = name;
  t.mesh = dem::build_mesh(corners, name);
  return t;
}

// Quad (a,b,c,d counter-clockwise) as two triangles split along a-c.
inline void quad(std::vector<Vec3>& corners, Vec3 a, Vec3 b, Vec3 c, Vec3 d) {
  corners.insert(corners.end(), {a, b, c, a, c, d});
}

}  // namespace demtest
