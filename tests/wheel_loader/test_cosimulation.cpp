// End to end over LCM on loopback: cosim_master + wheel_loader_adapter + dem_service, a small
// pile (4000 spheres) and 3 s of the maneuver with the machine started close to the pile.
// The DEM runs on one thread: ctest runs tests side by side, and OpenMP threads that wait for
// each other on an oversubscribed machine slow everything down many times over.
// The bucket picks up soil, the bearing forces are finite, of the expected sign and size,
// the machine slows on contact, and a second run gives the same numbers bit for bit.
#include <cosim/quantities.hpp>
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <cstdio>

#include "../oscillator/harness.hpp"

namespace {

constexpr double kEnd = 3.0;

std::string pile() {
  static const std::string path = [] {
    const std::string h5 = harness::temp_path("_pile.h5");
    harness::Process p = harness::spawn(
        {harness::bin("dem_run"), harness::source("configs/soil/pile_prepare.yaml"), "--output",
         harness::temp_path("_prepare.h5"), "--set", "particles.fill.0.max=[9.0, 1.9, 2.8]", "--set",
         "particles.fill.0.count=4000", "--set", "walls.1.point=[9.0, 0, 0]", "--set",
         "scene.threads=1", "--set",
         "settle.checkpoint=" + h5},
        h5 + ".log");
    EXPECT_EQ(harness::wait_for(p, 300), 0) << harness::read_text(h5 + ".log");
    return h5;
  }();
  return path;
}

struct Outputs {
  std::string master_h5, soil_h5;
};

Outputs cosimulate(const std::string& tag) {
  Outputs r{harness::temp_path("_" + tag + ".h5"), harness::temp_path("_" + tag + "_soil.h5")};
  const int code = harness::run_master(
      {"time.end=" + std::to_string(kEnd), "output.csv=",
       "participants.loader.parameters={initial_position: 1.8}",
       // The service checks its config file, checkpoint included, when it starts: the pile goes
       // on its command line; the rest may come with the master's parameters.
       // The bucket mesh of this build (the config names build/meshes, the README's build).
       "participants.soil.launch=[dem_service, " + harness::source("configs/soil/pile.yaml") +
           ", --set, 'particles.checkpoint=" + pile() + "', --set, 'tools.0.mesh=" +
           std::string(BIN_DIR) + "/../meshes/bucket_r1.stl']",
       "participants.soil.parameters={output.file: " + r.soil_h5 +
           ", walls.1.point: [9.0, 0, 0], output.particles_every: 1.0, scene.threads: 1}"},
      r.master_h5, 600, "configs/wheel_loader.yaml");
  EXPECT_EQ(code, 0) << harness::read_text(r.master_h5 + ".log");
  return r;
}

std::vector<double> column(const std::string& h5, const std::string& name) {
  return harness::read_dataset(h5, name);
}

// Names of the particle snapshots in the service's output, in order.
std::vector<std::string> snapshots(const std::string& h5) {
  std::vector<std::string> names;
  hid_t f = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return names;
  hid_t g = H5Gopen2(f, "particles", H5P_DEFAULT);
  H5G_info_t info;
  H5Gget_info(g, &info);
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    char buf[64];
    H5Lget_name_by_idx(g, ".", H5_INDEX_NAME, H5_ITER_INC, i, buf, sizeof buf, H5P_DEFAULT);
    names.push_back(std::string("particles/") + buf);
  }
  H5Gclose(g);
  H5Fclose(f);
  return names;
}

// Mass of the particles inside the bucket's cavity (bucket frame: 0 < x < cutting edge at
// 1.65 m, floor -0.45 m < z < top of the back plate 0.85 m, |y| < 1.5 m; machine.yaml).
double mass_in_bucket(const std::string& soil_h5, const std::string& snapshot,
                      const cosim::Kinematics& pose) {
  const auto x = column(soil_h5, snapshot + "/position");
  const auto r = column(soil_h5, snapshot + "/radius");
  const auto& q = pose.orientation;
  const auto& p = pose.position;
  const double w = q[0], qx = q[1], qy = q[2], qz = q[3];
  // Rows of R (bucket -> ground); R^T maps ground offsets into the bucket frame.
  const double R[3][3] = {{1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - w * qz), 2 * (qx * qz + w * qy)},
                          {2 * (qx * qy + w * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - w * qx)},
                          {2 * (qx * qz - w * qy), 2 * (qy * qz + w * qx), 1 - 2 * (qx * qx + qy * qy)}};
  double mass = 0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const double d[3] = {x[3 * i] - p[0], x[3 * i + 1] - p[1], x[3 * i + 2] - p[2]};
    double b[3];
    for (int c = 0; c < 3; ++c) b[c] = R[0][c] * d[0] + R[1][c] * d[1] + R[2][c] * d[2];
    if (b[0] > 0 && b[0] < 1.65 && b[2] > -0.45 && b[2] < 0.85 && std::abs(b[1]) < 1.5)
      mass += 2600 * 4.0 / 3.0 * M_PI * r[i] * r[i] * r[i];
  }
  return mass;
}

}  // namespace

TEST(WheelLoaderCosimulation, FillsTheBucketSlowsDownAndIsDeterministic) {
  const Outputs a = cosimulate("a");
  const auto t = column(a.master_h5, "time");
  ASSERT_GT(t.size(), 100u);
  ASSERT_NEAR(t.back(), kEnd, 1e-9);
  const std::string out = "participants/loader/outputs/";
  const auto speed = column(a.master_h5, out + "speed");
  const auto a_long = column(a.master_h5, out + "a_long"), a_vert = column(a.master_h5, out + "a_vert");
  const auto j_long = column(a.master_h5, out + "j_long"), j_vert = column(a.master_h5, out + "j_vert");
  const auto soil = column(a.master_h5, "participants/soil/outputs/bucket");  // wrench rows
  const auto bucket = column(a.master_h5, out + "bucket");                     // kinematics rows
  const std::size_t n = t.size(), last = n - 1;
  auto soil_at = [&](std::size_t i) {
    constexpr std::size_t m = cosim::Wrench::kSize;
    return cosim::Wrench::from_value({soil.begin() + m * i, soil.begin() + m * (i + 1)});
  };
  auto bucket_at = [&](std::size_t i) {
    constexpr std::size_t m = cosim::Kinematics::kSize;
    return cosim::Kinematics::from_value({bucket.begin() + m * i, bucket.begin() + m * (i + 1)});
  };

  for (const auto* s : {&a_long, &a_vert, &j_long, &j_vert})
    for (double v : *s) ASSERT_TRUE(std::isfinite(v) && std::abs(v) < 2e6);
  // Before contact the soil is silent; by the end it resists: pushes the bucket back (-x)
  // with tens to hundreds of kN, the traction limit of a 27 t machine is ~160 kN.
  EXPECT_EQ(soil_at(10).force[0], 0.0);
  double resist = 0;
  for (std::size_t i = n / 2; i < n; ++i) resist = std::max(resist, -soil_at(i).force[0]);
  EXPECT_GT(resist, 30e3);
  EXPECT_LT(resist, 1e6);
  // The boom pushes the bucket into the pile: the A-bearing's longitudinal force (towards the
  // cutting edge) rises from its no-load value by at least a large part of the resistance.
  double a_peak = 0;
  for (std::size_t i = n / 2; i < n; ++i) a_peak = std::max(a_peak, a_long[i]);
  std::printf("soil resistance peak %.0f N, A-bearing longitudinal %.0f -> peak %.0f N, speed %.3f -> %.3f m/s\n",
              resist, a_long[0], a_peak, speed[0], speed[last]);
  EXPECT_GT(a_peak - a_long[0], 0.3 * resist);
  EXPECT_LT(a_peak, 2e6);
  // The machine slows on contact: the speed target stays 1.2 m/s throughout.
  EXPECT_NEAR(speed[0], 1.2, 1e-6);
  EXPECT_LT(speed[last], 0.9 * speed[0]);

  // The bucket picks up soil.
  const auto snaps = snapshots(a.soil_h5);
  ASSERT_GE(snaps.size(), 2u);
  const double m0 = mass_in_bucket(a.soil_h5, snaps.front(), bucket_at(0));
  const double m1 = mass_in_bucket(a.soil_h5, snaps.back(), bucket_at(last));
  std::printf("soil in the bucket: %.0f kg at t = 0, %.0f kg at t = %.1f s\n", m0, m1, kEnd);
  EXPECT_EQ(m0, 0.0);
  EXPECT_GT(m1, 1000.0);

  // Deterministic: a second run, bit for bit.
  const Outputs b = cosimulate("b");
  for (const char* name : {"participants/loader/outputs/a_long", "participants/loader/outputs/j_vert",
                           "participants/loader/outputs/bucket", "participants/soil/outputs/bucket"})
    EXPECT_EQ(column(a.master_h5, name), column(b.master_h5, name)) << name;
}
