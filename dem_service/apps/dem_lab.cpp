// dem_lab triaxial|biaxial|repose CONFIG.yaml [--set dotted.key=value ...] [--out DIR] [--no-plot]
// Virtual lab tests of the DEM engine (docs/soil_lab.md): CSVs of the curves and a summary in
// DIR (default results/lab), charts by scripts/lab_plot.py (/usr/bin/python3, matplotlib).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "cosim/yaml_config.hpp"
#include "dem/lab/repose.hpp"
#include "dem/lab/triaxial.hpp"

#ifndef DEM_LAB_PLOT_SCRIPT
#define DEM_LAB_PLOT_SCRIPT "scripts/lab_plot.py"
#endif

namespace {

namespace fs = std::filesystem;
namespace lab = dem::lab;

void usage() {
  std::cerr << "usage: dem_lab triaxial|biaxial|repose CONFIG.yaml [--set dotted.key=value ...] "
               "[--out DIR] [--no-plot]\n"
               "  triaxial: servo-controlled true-triaxial compression at each confining pressure\n"
               "  biaxial:  plane-strain compression (the y walls fixed) at each confining pressure\n"
               "  repose:   lifted-cylinder angle of repose\n"
               "  Writes CSVs to DIR (default results/lab) and charts them with "
               "scripts/lab_plot.py; see docs/soil_lab.md.\n";
}

std::ofstream open_out(const fs::path& p) {
  std::ofstream f(p);
  if (!f) throw std::runtime_error("cannot write " + p.string() + "; check --out");
  f << std::setprecision(9);
  return f;
}

void progress(const std::string& line) { std::cerr << line << "\n"; }

// "translating" or "rotating, rolling resistance mu_r 0.1 (damping 0.3)".
std::string model_text(const lab::Grains& g) {
  const dem::RotationOptions& r = g.rotation;
  if (!r.rotating()) return "translating grains";
  std::ostringstream t;
  t << "rotating grains, ";
  if (r.rolling.kind == dem::RollingResistance::Kind::none)
    t << "no rolling resistance";
  else
    t << "rolling resistance mu_r " << r.rolling.friction << " (EPSD, damping "
      << r.rolling.damping << ")";
  return t.str();
}

// The triaxial and the biaxial test: the same rig, CSVs named after the test.
int run_compression(const YAML::Node& root, const fs::path& out, const std::string& name) {
  const lab::TriaxialOptions o =
      name == "biaxial" ? lab::parse_biaxial(root) : lab::parse_triaxial(root);
  std::cerr << name << ": " << o.count << " grains, r " << o.grains.radius_min << " .. "
            << o.grains.radius_max << " m, mu " << o.grains.law.friction << ", k_T/k_N "
            << o.grains.law.tangential_stiffness_ratio << ", " << model_text(o.grains) << ", "
            << o.confining.size() << " confining pressures\n";
  const lab::Sample sample = lab::prepare_sample(o, o.confining.front(), progress);
  const double prep_packing = lab::packing_fraction(sample.state, sample.lo, sample.hi);
  std::cerr << "prepared: packing fraction " << prep_packing << " at " << o.confining.front()
            << " Pa (preparation friction " << o.preparation_friction << "), dt " << sample.dt
            << " s\n";
  std::vector<lab::TriaxialTest> tests;
  for (double p : o.confining) tests.push_back(lab::run_triaxial(o, sample, p, progress));

  std::ofstream c = open_out(out / (name + "_curves.csv"));
  c << "confining_Pa,axial_strain,volumetric_strain,sigma1_Pa,sigma3_Pa,q_Pa,sin_phi,packing,"
       "time_s,sigma2_Pa,strain2,strain3\n";
  for (const auto& t : tests)
    for (const auto& r : t.curve)
      c << t.confining << "," << r.axial_strain << "," << r.volumetric_strain << "," << r.sigma1
        << "," << r.sigma3 << "," << r.q() << "," << r.sin_phi() << "," << r.packing << ","
        << r.time << "," << r.sigma2 << "," << r.strain2 << "," << r.strain3 << "\n";
  std::ofstream s = open_out(out / (name + "_summary.csv"));
  s << "confining_Pa,grains,packing,packing_inner,bulk_density_kg_m3,porosity,coordination,strain_rate_1_s,"
       "inertial_number,peak_axial_strain,sigma1_peak_Pa,sigma3_peak_Pa,phi_peak_deg,phi_end_deg,"
       "dilatancy_end,critical_state,servo_worst,sigma2_peak_Pa,b_peak,dilatancy_max,psi_max_deg,"
       "phi_max_deg,phi_first_peak_deg\n";
  std::vector<double> s1, s3, e1, e3;
  bool all_critical = true;
  for (const auto& t : tests) {
    const auto& pk = t.curve[t.peak];
    s1.push_back(pk.sigma1);
    s3.push_back(pk.sigma3);
    e1.push_back(t.sigma1_end);
    e3.push_back(t.sigma3_end);
    all_critical = all_critical && t.critical;
    s << t.confining << "," << t.grains << "," << t.packing << "," << t.packing_inner << ","
      << t.packing_inner * o.grains.density << "," << 1 - t.packing_inner << "," << t.coordination << ","
      << t.strain_rate << "," << t.inertial_number << "," << pk.axial_strain << "," << pk.sigma1
      << "," << pk.sigma3 << "," << t.phi_peak << "," << t.phi_end << "," << t.dilatancy_end
      << "," << (t.critical ? 1 : 0) << "," << t.servo_worst << "," << t.sigma2_peak << ","
      << t.b_peak << "," << t.dilatancy_max << "," << t.psi_max << "," << t.phi_max << ","
      << t.phi_first_peak << "\n";
    std::cout << std::fixed << std::setprecision(2) << "sigma3 " << t.confining / 1e3
              << " kPa: packing " << std::setprecision(3) << t.packing << " (inner " << t.packing_inner << "), " << std::setprecision(2)
              << t.coordination << " contacts/grain, peak phi " << t.phi_peak << " deg at "
              << 100 * pk.axial_strain << " % axial strain";
    if (o.plane_strain)
      std::cout << " (sigma2 " << t.sigma2_peak / 1e3 << " kPa, b " << t.b_peak << ", psi_max "
                << t.psi_max << " deg)";
    if (t.phi_max > t.phi_peak + 1e-9)
      std::cout << ", largest " << t.phi_max << " deg";
    std::cout << ", end phi " << t.phi_end
              << " deg (dilatancy " << std::setprecision(3) << t.dilatancy_end
              << (t.critical ? ", critical state" : ", not yet critical") << "), servo within "
              << std::setprecision(2) << 100 * t.servo_worst << " %, I = " << std::scientific
              << std::setprecision(1) << t.inertial_number << std::fixed << "\n";
  }
  const lab::MohrCoulombFit peak = lab::fit_mohr_coulomb(s1, s3);
  const lab::MohrCoulombFit end = lab::fit_mohr_coulomb(e1, e3);
  std::ofstream f = open_out(out / (name + "_fit.csv"));
  f << "state,phi_origin_deg,phi_deg,cohesion_Pa,phi_stderr_deg\n"
    << "peak," << peak.phi_origin << "," << peak.phi << "," << peak.cohesion << ","
    << peak.phi_stderr << "\n"
    << (all_critical ? "critical" : "end") << "," << end.phi_origin << "," << end.phi << ","
    << end.cohesion << "," << end.phi_stderr << "\n";
  std::cout << std::setprecision(2) << "Mohr-Coulomb, peak: phi " << peak.phi_origin
            << " deg through the origin; fit phi " << peak.phi << " +- " << peak.phi_stderr
            << " deg, c " << peak.cohesion / 1e3 << " kPa\n"
            << (all_critical ? "critical state" : "end of test (not every test critical)")
            << ": phi " << end.phi_origin << " deg through the origin\n";
  return 0;
}

int run_repose(const YAML::Node& root, const fs::path& out) {
  const lab::ReposeOptions o = lab::parse_repose(root);
  std::cerr << "repose: " << o.count << " grains, mu " << o.grains.law.friction << ", "
            << model_text(o.grains) << "\n";
  const lab::ReposeResult r = lab::run_repose(o, progress);
  std::ofstream c = open_out(out / "repose_surface.csv");
  c << "sector,radius_m,height_m,used\n";
  for (const auto& p : r.surface)
    c << p.sector << "," << p.radius << "," << p.height << "," << (p.used ? 1 : 0) << "\n";
  std::ofstream g = open_out(out / "repose_grains.csv");
  g << "x,y,z,r\n";
  for (std::size_t i = 0; i < r.grains.size(); ++i)
    g << r.grains[i].x << "," << r.grains[i].y << "," << r.grains[i].z - r.base << "," << r.radius[i] << "\n";
  std::ofstream s = open_out(out / "repose_summary.csv");
  s << "grains,angle_deg,angle_sector_sd_deg,sectors,height_m,pile_radius_m,intercept_m,lost,cylinder_radius_m\n"
    << r.count << "," << r.angle << "," << r.angle_sd << "," << r.sectors << "," << r.height
    << "," << r.pile_radius << "," << r.intercept << "," << r.lost << "," << r.cylinder_radius << "\n";
  std::cout << std::fixed << std::setprecision(2) << "angle of repose " << r.angle << " deg (+- "
            << r.angle_sd << " deg over " << r.sectors << " sectors), pile height " << r.height
            << " m, radius " << r.pile_radius << " m, " << r.count << " grains on the base (" << r.lost << " ran off it)\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    usage();
    return 2;
  }
  const std::string test = argv[1];
  if (test != "triaxial" && test != "biaxial" && test != "repose") {
    std::cerr << "dem_lab: unknown test '" << test << "' (allowed: triaxial, biaxial, repose)\n";
    usage();
    return 2;
  }
  fs::path out = "results/lab";
  bool plot = true;
  std::string plot_script = DEM_LAB_PLOT_SCRIPT;
  YAML::Node root;
  try {
    root = cosim::config::load_file(argv[2]);
    for (int i = 3; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--set" && i + 1 < argc) {
        cosim::config::apply_override(root, argv[++i]);
      } else if (a == "--out" && i + 1 < argc) {
        out = argv[++i];
      } else if (a == "--no-plot") {
        plot = false;
      } else if (a == "--plot-script" && i + 1 < argc) {
        plot_script = argv[++i];
      } else {
        std::cerr << "dem_lab: unknown or incomplete argument '" << a << "'\n";
        usage();
        return 2;
      }
    }
    fs::create_directories(out);
  } catch (const std::exception& e) {
    std::cerr << "dem_lab: " << e.what() << "\n";
    return 2;
  }
  int rc;
  try {
    rc = test == "repose" ? run_repose(root, out) : run_compression(root, out, test);
  } catch (const cosim::config::ConfigError& e) {
    std::cerr << "dem_lab: config refused: " << e.what() << "\n";
    return 2;
  } catch (const std::invalid_argument& e) {
    std::cerr << "dem_lab: config refused: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "dem_lab: " << e.what() << "\n";
    return 3;
  }
  if (rc == 0 && plot) {
    const std::string cmd = "/usr/bin/python3 '" + plot_script + "' " + test + " '" +
                            out.string() + "'";
    if (std::system(cmd.c_str()) != 0)
      std::cerr << "dem_lab: the chart failed (" << cmd << "); the CSVs are in " << out << "\n";
  }
  return rc;
}
