// soil_triaxial [--pressures 1000,2000,4000] [--mu 0.5] [--prep-mu 0] [--grains 1000] [--rate 0.05]
//               [--max-strain 0.06] [--radius 0.005] [--spread 0.05] [--density 2600]
//               [--stiffness 5e3] [--restitution 0.3] [--kt-ratio 1] [--seed 1] [--threads 1]
//               [--csv FILE]
// A true-triaxial test per confining pressure of the engine's own soil (docs/soil.md): peak and
// final friction angles, then the Mohr-Coulomb fit over the pressures.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "dem/triaxial.hpp"

namespace {

void usage() {
  std::fprintf(stderr,
               "usage: soil_triaxial [--pressures P1,P2,...] [--mu MU] [--prep-mu MU] [--grains N] "
               "[--rate 1/s] [--max-strain E] [--radius M] [--spread S] [--density KG/M3] "
               "[--stiffness N/M] [--restitution E] [--kt-ratio R] [--seed N] [--threads N] "
               "[--csv FILE]\n");
}

double number(const std::string& flag, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v))
    throw std::invalid_argument(flag + ": expected a number, got '" + text + "'");
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    dem::TriaxialOptions o;
    std::vector<double> pressures{1000, 2000, 4000};
    std::string csv;
    for (int a = 1; a < argc; ++a) {
      const std::string f = argv[a];
      if (f == "-h" || f == "--help") {
        usage();
        return 0;
      }
      if (a + 1 >= argc) throw std::invalid_argument("'" + f + "' needs a value (or is unknown)");
      const std::string v = argv[++a];
      if (f == "--pressures") {
        pressures.clear();
        std::stringstream ss(v);
        std::string item;
        while (std::getline(ss, item, ',')) pressures.push_back(number(f, item));
        if (pressures.empty()) throw std::invalid_argument("--pressures: give one or more stresses in Pa");
      } else if (f == "--mu") o.friction = number(f, v);
      else if (f == "--prep-mu") o.prep_friction = number(f, v);
      else if (f == "--grains") o.grains = std::lround(number(f, v));
      else if (f == "--rate") o.strain_rate = number(f, v);
      else if (f == "--max-strain") o.max_strain = number(f, v);
      else if (f == "--radius") o.radius = number(f, v);
      else if (f == "--spread") o.spread = number(f, v);
      else if (f == "--density") o.density = number(f, v);
      else if (f == "--stiffness") o.stiffness = number(f, v);
      else if (f == "--restitution") o.restitution = number(f, v);
      else if (f == "--kt-ratio") o.tangential_stiffness_ratio = number(f, v);
      else if (f == "--seed") o.seed = static_cast<std::uint64_t>(std::llround(number(f, v)));
      else if (f == "--threads") o.threads = static_cast<int>(std::lround(number(f, v)));
      else if (f == "--csv") csv = v;
      else throw std::invalid_argument("unknown option '" + f + "'");
    }
    for (double p : pressures) {
      o.confining = p;
      dem::validate(o);
    }
    std::ofstream out;
    if (!csv.empty()) {
      out.open(csv);
      if (!out) throw std::invalid_argument("--csv: cannot write '" + csv + "'");
      out << "confining_Pa,axial_strain,volumetric_strain,sigma1_Pa,sigma3_Pa,sigma_x_Pa,sigma_y_Pa\n";
    }
    std::vector<double> s1, s3;
    const double deg = 180 / M_PI;
    std::printf("%ld grains, mu %g (walls smooth), prepared with mu %g, strain rate %g 1/s\n", o.grains,
                o.friction, o.prep_friction, o.strain_rate);
    for (double p : pressures) {
      o.confining = p;
      const dem::TriaxialResult r = dem::run_triaxial(o, [&](const char* stage, double x, double a, double b) {
        if (std::string(stage) == "shear" && std::fmod(x + 1e-9, 0.01) < o.sample_strain)
          std::fprintf(stderr, "  sigma3 %g Pa: axial strain %.3f, sigma1 %.4g Pa, sigma3 %.4g Pa\n", p, x, a, b);
      });
      std::printf("sigma3 %8.1f Pa: packing %.4f, peak sigma1/sigma3 %.3f at strain %.3f -> phi_peak %.2f deg, "
                  "final phi %.2f deg, servo error %.2f %%, dt %.3g s\n",
                  p, r.initial_fraction, r.peak_ratio, r.peak_strain, r.peak_phi * deg, r.final_phi * deg,
                  100 * r.servo_error, r.dt);
      s3.push_back(p);
      s1.push_back(p * r.peak_ratio);
      for (const dem::TriaxialSample& c : r.curve)
        if (out) out << p << "," << c.axial_strain << "," << c.volumetric_strain << "," << c.sigma1 << ","
                     << c.sigma3 << "," << c.sigma_x << "," << c.sigma_y << "\n";
    }
    if (pressures.size() >= 2) {
      const dem::MohrCoulomb m = dem::mohr_coulomb_fit(s3, s1);
      std::printf("Mohr-Coulomb fit over %zu pressures (peak): phi %.2f deg, cohesion %.3g Pa\n",
                  pressures.size(), m.phi * deg, m.cohesion);
    }
    return 0;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "soil_triaxial: refused: %s\n", e.what());
    usage();
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "soil_triaxial: stopped: %s\n", e.what());
    return 3;
  }
}
