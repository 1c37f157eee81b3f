// A true-triaxial compression test of the project's own engine (docs/soil.md): a cube of grains
// between six frictionless walls, no gravity. The grains are inserted at random and compressed
// isotropically to the confining stress by servo-controlled walls (with `prep_friction`), then
// the test friction is switched on and the z walls close at a constant strain rate while the
// x and y walls hold the confining stress. Records the stress-strain and volumetric curves.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace dem {

struct TriaxialOptions {
  long grains = 1000;
  double radius = 0.005;      // m, mean
  double spread = 0.05;       // radii uniform in radius (1 +- spread)
  double density = 2600;      // kg/m^3
  double stiffness = 5e3;     // k_N, N/m (particles and walls)
  double restitution = 0.3;
  double tangential_stiffness_ratio = 1.0;
  double friction = 0.5;      // particle-particle mu during the test (walls frictionless)
  double prep_friction = 0.0; // mu while the sample is compressed isotropically (0: densest)
  double confining = 2000;    // Pa, sigma_3
  double strain_rate = 0.05;  // 1/s, axial (z)
  double max_strain = 0.06;   // axial strain at which the test ends
  double sample_strain = 0.001;  // one curve sample per this axial strain
  std::uint64_t seed = 1;
  int threads = 1;
};

// One curve point: averages over the strain interval that ends at axial_strain.
struct TriaxialSample {
  double axial_strain = 0;       // (L_z0 - L_z) / L_z0
  double volumetric_strain = 0;  // (V_0 - V) / V_0: compression positive, dilation negative
  double sigma1 = 0;             // Pa, z walls
  double sigma3 = 0;             // Pa, mean of the x and y walls
  double sigma_x = 0, sigma_y = 0;
};

struct TriaxialResult {
  std::vector<TriaxialSample> curve;
  double initial_fraction = 0;  // solid fraction of the box after the isotropic compression
  double peak_ratio = 0;        // largest sigma1 / sigma3
  double peak_strain = 0;
  double peak_phi = 0;          // rad: sin phi = (s1 - s3) / (s1 + s3) at the peak
  double final_phi = 0;         // rad, from the mean ratio over the last fifth of the curve
  double servo_error = 0;       // largest |sigma_x or y - confining| / confining of the samples
  double dt = 0;
};

// Throws std::invalid_argument naming the option (as --name) for a bad value.
void validate(const TriaxialOptions& o);

// Runs the test. progress(stage, axial strain or time, sigma1, sigma3) now and then.
TriaxialResult run_triaxial(const TriaxialOptions& o,
                            const std::function<void(const char*, double, double, double)>& progress = {});

// Mohr-Coulomb fit over tests at several confining stresses: least squares of
// q = (s1 - s3) / 2 against p = (s1 + s3) / 2, q = p sin(phi) + c cos(phi).
struct MohrCoulomb {
  double phi = 0;       // rad
  double cohesion = 0;  // Pa
};
MohrCoulomb mohr_coulomb_fit(const std::vector<double>& sigma3, const std::vector<double>& sigma1);

}  // namespace dem
