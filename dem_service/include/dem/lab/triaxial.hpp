// The virtual triaxial test (docs/soil_lab.md): a cubic sample of random grains between six
// frictionless walls, isotropically consolidated to a confining pressure by servo-controlled
// walls, then compressed along z at a constant axial strain rate while the four lateral walls
// keep the confining stress (a true-triaxial rig with sigma_2 = sigma_3). Gravity off.
// The biaxial (plane-strain) test is the same rig with the two y walls held fixed while the
// sample is sheared (zero strain along y): only the x walls keep sigma_3, and the fixed walls
// carry the intermediate stress sigma_2.
#pragma once

#include <yaml-cpp/yaml.h>

#include <functional>
#include <string>
#include <vector>

#include "dem/lab/grains.hpp"

namespace dem::lab {

struct TriaxialOptions {
  Grains grains;
  // sample
  long count = 1000;                 // grains
  std::uint64_t seed = 1;
  double initial_fraction = 0.30;    // packing fraction of the random insertion
  double preparation_friction = 0.0; // mu while the sample is compacted (0: densest)
  double aspect = 1.0;               // height (z) over width (x, y): 1 a cube; a taller biaxial
                                     // sample lets its shear band leave through the x walls
  double thickness = 1.0;            // extent along y over the width (x): below 1 a slab
                                     // (of the insertion box; compaction closes a thin side more)
  // test
  std::vector<double> confining;     // Pa, one test each (ascending after parsing)
  double inertial_number = 1e-3;     // sets the axial strain rate per test: I = rate d sqrt(rho/p)
  double strain_rate = 0;            // 1/s; > 0 replaces the rate from inertial_number
  double max_axial_strain = 0.15;
  double record_every = 0.002;       // axial strain between records
  double servo_gain = 0.1;           // BoxRig servo: fraction of the stress error per step
  double tolerance = 0.01;           // consolidation: every face within this of the target
  long max_consolidation_steps = 400000;  // steps before a consolidation that does not hold fails
  int threads = 1;
  // Plane strain (dem_lab biaxial): while shearing, the y walls stay where the consolidation
  // left them (strain 0 along y), the x walls alone are servoed to sigma_3.
  bool plane_strain = false;
  // Which record is the peak (`peak: first | max`): the first peak, the largest mobilised angle
  // before the angle first falls 3 deg below its running maximum (the biaxial's default), or
  // the largest over the whole test (the triaxial's default).
  bool first_peak = false;
  // The config section of the test ("triaxial" or "biaxial"): messages name its keys.
  std::string section = "triaxial";
};

// Reads `grains`, `sample`, `triaxial`, `run` (threads) at the top of a lab config; every key
// is checked, every bad value refused with cosim::config::ConfigError naming its dotted key.
TriaxialOptions parse_triaxial(const YAML::Node& root);
// The biaxial (plane-strain) test: `grains`, `sample`, `biaxial` (the keys of `triaxial`), `run`;
// plane_strain set, messages naming biaxial.*.
TriaxialOptions parse_biaxial(const YAML::Node& root);

struct TriaxialRecord {
  double axial_strain = 0;       // (H0 - H) / H0, compression positive
  double volumetric_strain = 0;  // (V0 - V) / V0, compression positive (dilation negative)
  double sigma1 = 0;             // axial stress (mean of the two z walls), Pa
  double sigma3 = 0;             // lateral stress (mean of the servoed lateral walls: four in
                                 // the triaxial, the two x walls in the biaxial), Pa
  double sigma2 = 0;             // stress on the y walls, Pa (biaxial: the fixed walls, the
                                 // intermediate stress; triaxial: servoed to sigma_3 as well)
  double sigma3_worst = 0;       // servoed lateral wall farthest from the target, Pa (signed)
  double strain2 = 0;            // (W0 - W) / W0 along y since the start of shearing (biaxial: 0)
  double strain3 = 0;            // the same along x
  double q() const { return sigma1 - sigma3; }
  double sin_phi() const { return (sigma1 - sigma3) / (sigma1 + sigma3); }
  double packing = 0;
  double time = 0;               // s since the start of shearing
};

struct TriaxialTest {
  double confining = 0;          // Pa
  double strain_rate = 0;        // 1/s
  double inertial_number = 0;    // of the shearing
  double dt = 0;
  long grains = 0;
  double packing = 0;            // after consolidation, whole sample (grain volume / box)
  double packing_inner = 0;      // after consolidation, centres more than 2 r_max from every wall
  double coordination = 0;       // after consolidation, contacts per grain
  double consolidation_time = 0; // s simulated
  std::vector<TriaxialRecord> curve;
  std::size_t peak = 0;          // record of the peak (first peak or largest, per options)
  double phi_peak = 0;           // deg, at that record
  double phi_max = 0;            // deg, the largest over the test
  double phi_first_peak = 0;     // deg, before the first softening of more than 3 deg
  // Mean sin(phi) over the last quarter of the strain, as an angle (deg), and the dilatancy
  // there (d eps_v / d eps_a); a critical state if |dilatancy| < 0.05 and the strain reached 0.1.
  double phi_end = 0, dilatancy_end = 0;
  double sigma1_end = 0, sigma3_end = 0;  // Pa, means over the last quarter
  bool critical = false;
  double servo_worst = 0;        // largest |sigma3 - target| / target over the records
  // At the peak: sigma_2 and b = (sigma_2 - sigma_3) / (sigma_1 - sigma_3) (0 triaxial).
  double sigma2_peak = 0, b_peak = 0;
  // The largest dilatancy rate -d eps_v / d eps_1 and dilatancy angle
  // psi = asin(-d eps_v / (d eps_1 - d eps_3)) (the plane-strain definition, Bolton 1986),
  // each from differences over 4 records (centred), deg.
  double dilatancy_max = 0, psi_max = 0;
};

// Mohr-Coulomb fit of the peak (or end) circles: through the origin (cohesionless,
// sin phi = sum(s t) / sum(s^2), s = (s1 + s3) / 2, t = (s1 - s3) / 2) and with an intercept
// (t = a + s sin phi, c = a / cos phi); its standard error when there are three or more tests.
struct MohrCoulombFit {
  double phi_origin = 0;  // deg
  double phi = 0;         // deg, with intercept
  double cohesion = 0;    // Pa
  double phi_stderr = 0;  // deg (0 with fewer than 3 points)
};
MohrCoulombFit fit_mohr_coulomb(const std::vector<double>& sigma1, const std::vector<double>& sigma3);

// Prepares a sample: random insertion at initial_fraction in a cube, then compaction with the
// preparation friction by all six walls servoed to `pressure` until it holds. Returns the state;
// the rig's box is returned in lo/hi.
struct Sample {
  State state;
  Vec3 lo, hi;
  double dt = 0;
};
using Progress = std::function<void(const std::string&)>;
Sample prepare_sample(const TriaxialOptions& o, double pressure, const Progress& progress = {});

// Consolidates a prepared sample with the test friction to `confining` and shears it.
TriaxialTest run_triaxial(const TriaxialOptions& o, const Sample& sample, double confining,
                          const Progress& progress = {});

}  // namespace dem::lab
