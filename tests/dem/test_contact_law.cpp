// Binary impacts against closed forms: restitution and contact duration for sphere-sphere,
// sphere-plane and sphere-mesh (face, edge, vertex), with and without clipping.
#include <gtest/gtest.h>

#include <functional>

#include "dem/contact_law.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

struct Impact {
  double e = 0, tc = 0;
};

// Steps until contact started and ended. gap < 0 means overlap; vn is the normal relative
// velocity (positive when separating). Times of touching and parting are interpolated
// between steps (free flight before and after is exact).
Impact run_impact(const dem::Scene& scene, State st, const std::function<double(const State&)>& gap,
                  const std::function<double(const State&)>& vn) {
  dem::Engine engine(scene);
  st.tool_pose.resize(scene.tools.size());
  double t_start = -1, t_end = -1, v_in = 0, v_out = 0;
  double g_prev = gap(st), vn_prev = vn(st);
  for (int k = 0; k < 100000 && t_end < 0; ++k) {
    const double t = st.step * scene.dt;
    engine.step(st);
    const double g = gap(st);
    if (t_start < 0 && g_prev > 0 && g <= 0) {
      t_start = t + scene.dt * g_prev / (g_prev - g);
      v_in = vn_prev;
    } else if (t_start >= 0 && g_prev <= 0 && g > 0) {
      t_end = t + scene.dt * (-g_prev) / (g - g_prev);
      // The last force window can reach past the crossing: read the velocity in free flight.
      for (int extra = 0; extra < 3; ++extra) engine.step(st);
      v_out = vn(st);
    }
    g_prev = g;
    vn_prev = vn(st);
  }
  EXPECT_GE(t_end, 0) << "contact never ended";
  return {-v_out / v_in, t_end - t_start};
}

// Reference for the clipped law: the 1-DOF overlap ODE m d'' = -max(k d + eta d', 0),
// integrated with RK4 at a tiny step.
Impact clipped_reference(double k, double eta, double m, double v0) {
  auto acc = [&](double d, double u) { return -std::max(k * d + eta * u, 0.0) / m; };
  const double h = M_PI * std::sqrt(m / k) / 2e5;
  double d = 0, u = v0, t = 0;
  while (true) {
    const double k1d = u, k1u = acc(d, u);
    const double k2d = u + 0.5 * h * k1u, k2u = acc(d + 0.5 * h * k1d, u + 0.5 * h * k1u);
    const double k3d = u + 0.5 * h * k2u, k3u = acc(d + 0.5 * h * k2d, u + 0.5 * h * k2u);
    const double k4d = u + h * k3u, k4u = acc(d + h * k3d, u + h * k3u);
    const double dn = d + h / 6 * (k1d + 2 * k2d + 2 * k3d + k4d);
    const double un = u + h / 6 * (k1u + 2 * k2u + 2 * k3u + k4u);
    if (dn <= 0 && t > 0) return {-un / v0, t + h * d / (d - dn)};
    d = dn;
    u = un;
    t += h;
  }
}

struct Expected {
  double e, tc, k, eta;
};
Expected closed_form(const dem::ContactLaw& law, double length, double meff) {
  const auto c = dem::coefficients(law, length, meff);
  const double w0 = std::sqrt(c.k / meff);
  const double zeta = c.eta / (2 * std::sqrt(c.k * meff));
  return {law.restitution, M_PI / (w0 * std::sqrt(1 - zeta * zeta)), c.k, c.eta};
}

constexpr double kR = 0.01, kV = 0.5;

// Expected values for a law: unclipped from the closed forms, clipped from the ODE.
Expected expected(const dem::ContactLaw& law, double length, double meff) {
  Expected x = closed_form(law, length, meff);
  if (law.clip_attractive) {
    const Impact ref = clipped_reference(x.k, x.eta, meff, kV);
    x.e = ref.e;
    x.tc = ref.tc;
  }
  return x;
}

void check(const Impact& got, const Expected& want, const char* what) {
  EXPECT_NEAR(got.e, want.e, 0.005 * want.e) << what << ": restitution " << got.e << " vs " << want.e
                                             << " (" << 100 * (got.e / want.e - 1) << " %)";
  EXPECT_NEAR(got.tc, want.tc, 0.01 * want.tc)
      << what << ": duration " << got.tc << " vs " << want.tc << " ("
      << 100 * (got.tc / want.tc - 1) << " %)";
  std::printf("%-28s e %.5f (ref %.5f, %+.3f %%)  t_c %.4e (ref %.4e, %+.3f %%)\n", what, got.e,
              want.e, 100 * (got.e / want.e - 1), got.tc, want.tc, 100 * (got.tc / want.tc - 1));
}

class dem_Impacts : public ::testing::TestWithParam<std::tuple<bool, double>> {};

TEST_P(dem_Impacts, SphereSphereMatchesClosedForm) {
  const auto [clip, e] = GetParam();
  dem::Scene scene = one_species_scene(kR, kR);
  // Pa mode: k = k_N * r r / (r + r) = k_N r / 2.
  scene.particle_particle = law_n_per_m(1, e, clip);
  scene.particle_particle.stiffness_per_length = true;
  scene.particle_particle.normal_stiffness = 2e6;
  scene.particle_wall = scene.particle_particle;
  const double m = sphere_mass(kR);
  const Expected want = expected(scene.particle_particle, kR / 2, m / 2);
  EXPECT_NEAR(want.k, 2e6 * kR / 2, 1e-9);
  scene.dt = want.tc / 50;
  State st;
  add(st, {-kR - 1e-4, 0, 0}, {kV / 2, 0, 0}, kR);
  add(st, {kR + 1e-4, 0, 0}, {-kV / 2, 0, 0}, kR);
  auto gap = [](const State& s) { return norm(s.x[0] - s.x[1]) - 2 * kR; };
  auto vn = [](const State& s) {
    const Vec3 n = (1.0 / norm(s.x[0] - s.x[1])) * (s.x[1] - s.x[0]);
    return dot(s.v[1] - s.v[0], n);
  };
  check(run_impact(scene, st, gap, vn), want, clip ? "sphere-sphere clipped" : "sphere-sphere");
}

TEST_P(dem_Impacts, SpherePlaneMatchesClosedForm) {
  const auto [clip, e] = GetParam();
  dem::Scene scene = one_species_scene(kR, kR);
  scene.particle_particle = scene.particle_wall = law_n_per_m(2e4, e, clip);
  scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
  const double m = sphere_mass(kR);
  const Expected want = expected(scene.particle_wall, kR, m);
  scene.dt = want.tc / 50;
  State st;
  add(st, {0, 0, kR + 1e-4}, {0, 0, -kV}, kR);
  auto gap = [](const State& s) { return s.x[0].z - kR; };
  auto vn = [](const State& s) { return s.v[0].z; };
  check(run_impact(scene, st, gap, vn), want, clip ? "sphere-plane clipped" : "sphere-plane");
}

// Mesh targets: a flat square (face), a roof ridge (edge), a pyramid apex (vertex). The
// sphere falls straight onto the feature.
enum class Target { face, face_on_diagonal, edge, vertex };

dem::Tool target_mesh(Target t) {
  std::vector<Vec3> c;
  const double L = 0.05;
  switch (t) {
    case Target::face:
    case Target::face_on_diagonal:
      quad(c, {-L, -L, 0}, {L, -L, 0}, {L, L, 0}, {-L, L, 0});
      break;
    case Target::edge: {  // ridge along y at z = 0, faces sloping down at 30 degrees
      const double dz = -L * std::tan(M_PI / 6);
      quad(c, {0, -L, 0}, {0, L, 0}, {-L, L, dz}, {-L, -L, dz});
      quad(c, {0, -L, 0}, {L, -L, dz}, {L, L, dz}, {0, L, 0});
      break;
    }
    case Target::vertex: {  // six-sided pyramid, apex at the origin
      const double dz = -L * std::tan(M_PI / 6);
      for (int k = 0; k < 6; ++k) {
        const double a0 = k * M_PI / 3, a1 = (k + 1) * M_PI / 3;
        c.insert(c.end(), {Vec3{0, 0, 0}, Vec3{L * std::cos(a0), L * std::sin(a0), dz},
                           Vec3{L * std::cos(a1), L * std::sin(a1), dz}});
      }
      break;
    }
  }
  return static_tool("target", c);
}

TEST_P(dem_Impacts, SphereMeshFaceEdgeVertexMatchClosedForm) {
  const auto [clip, e] = GetParam();
  for (Target target : {Target::face, Target::face_on_diagonal, Target::edge, Target::vertex}) {
    dem::Scene scene = one_species_scene(kR, kR);
    scene.particle_particle = scene.particle_wall = law_n_per_m(2e4, e, clip);
    scene.tools.push_back(target_mesh(target));
    const double m = sphere_mass(kR);
    const Expected want = expected(scene.particle_wall, kR, m);
    scene.dt = want.tc / 50;
    State st;
    const double x0 = target == Target::face ? 0.013 : 0.0;
    const double y0 = target == Target::face ? -0.021 : 0.0;
    add(st, {x0, y0, kR + 1e-4}, {0, 0, -kV}, kR);
    auto gap = [](const State& s) { return s.x[0].z - kR; };
    auto vn = [](const State& s) { return s.v[0].z; };
    const char* names[] = {"sphere-mesh face", "sphere-mesh face diagonal", "sphere-mesh edge",
                           "sphere-mesh vertex"};
    std::string what = std::string(names[static_cast<int>(target)]) + (clip ? " clipped" : "");
    check(run_impact(scene, st, gap, vn), want, what.c_str());
  }
}

INSTANTIATE_TEST_SUITE_P(dem_ClipAndRestitution, dem_Impacts,
                         ::testing::Values(std::make_tuple(false, 0.5), std::make_tuple(false, 0.2),
                                           std::make_tuple(true, 0.5), std::make_tuple(true, 0.2)));

TEST(dem_ContactLaw, ClippedRestitutionExceedsTheFormula) {
  // facts.md: nominal 0.5 gives about 0.55, 0.2 about 0.33 once the pull is clipped.
  const double m = 1, k = 1e4;
  for (auto [e, lo, hi] : {std::tuple{0.5, 0.53, 0.57}, std::tuple{0.2, 0.31, 0.35}}) {
    const double zeta = dem::damping_ratio_from_restitution(e);
    const Impact ref = clipped_reference(k, 2 * zeta * std::sqrt(m * k), m, 1.0);
    EXPECT_GT(ref.e, lo);
    EXPECT_LT(ref.e, hi);
  }
}

TEST(dem_ContactLaw, CoulombCapResetsTheSpring) {
  dem::ContactLaw law = law_n_per_m(1000, 0.5, true, 0.5, 1.0, 0.0);
  const auto c = dem::coefficients(law, 0.01, 0.01);
  Vec3 spring{0.5, 0, 0};  // far beyond the cap
  Vec3 f;
  ASSERT_TRUE(dem::contact_force(law, c, 1e-3, {0, 0, 1}, {0, 0, 0}, spring, 1e-4, f));
  const double fn = 1000 * 1e-3;
  EXPECT_NEAR(f.z, fn, 1e-12);
  EXPECT_NEAR(f.x, -0.5 * fn, 1e-12);
  EXPECT_NEAR(c.kt * spring.x, 0.5 * fn, 1e-12);  // spring now holds exactly the cap
}

}  // namespace

// The step's contact statistics (reported by the service per macro step) count the contacts
// that carried a force and find the deepest overlap at the force time.
TEST(dem_ContactLaw, StatisticsCountContactsAndTheDeepestOverlap) {
  dem::Scene scene = one_species_scene(0.5 * kR, kR);
  scene.particle_particle = scene.particle_wall = law_n_per_m(2e4, 0.5, true);
  scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
  scene.dt = 1e-6;
  State st;
  add(st, {0, 0, kR - 2e-4}, {}, kR);                    // 2e-4 into the floor
  add(st, {2 * kR - 1e-4, 0, kR}, {}, kR);               // 1e-4 into the first sphere
  add(st, {10 * kR, 0, 0.5 * kR - 3e-4}, {}, 0.5 * kR);  // small sphere, 3e-4 into the floor
  add(st, {20 * kR, 0, 5 * kR}, {}, kR);                 // free
  dem::Engine engine(scene);
  engine.step(st);
  const dem::ContactStats& c = engine.contact_stats();
  EXPECT_EQ(c.particle_contacts, 1);
  EXPECT_EQ(c.boundary_contacts, 2);
  EXPECT_NEAR(c.max_overlap, 3e-4, 1e-12);
  EXPECT_NEAR(c.max_overlap_ratio, 3e-4 / (0.5 * kR), 1e-9);
}
