// soil_wedge --phi DEG [--delta DEG] [--alpha DEG] [--gamma N/m^3 --depth M --width M]
// Reece's fundamental earthmoving equation for dry cohesionless soil (docs/soil.md): N_gamma of
// the Coulomb passive wedge minimised over the failure-plane angle, and the draft force when the
// unit weight, depth and width are given. Independent of the DEM.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "dem/earthmoving.hpp"

namespace {

void usage() {
  std::fprintf(stderr,
               "usage: soil_wedge --phi DEG [--delta DEG] [--alpha DEG] [--gamma N/m^3 --depth M "
               "--width M]\n"
               "  phi: soil friction angle; delta: soil-blade friction angle (default 0); alpha: "
               "rake angle from the horizontal (default 90, vertical blade)\n");
}

double number(const std::string& flag, const char* text) {
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || !std::isfinite(v))
    throw std::invalid_argument(flag + ": expected a number, got '" + text + "'");
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    double phi = NAN, delta = 0, alpha = 90, gamma = NAN, depth = NAN, width = NAN;
    for (int a = 1; a < argc; ++a) {
      const std::string f = argv[a];
      if (f == "-h" || f == "--help") {
        usage();
        return 0;
      }
      if (a + 1 >= argc) throw std::invalid_argument("'" + f + "' needs a value (or is unknown)");
      const double v = number(f, argv[++a]);
      if (f == "--phi") phi = v;
      else if (f == "--delta") delta = v;
      else if (f == "--alpha") alpha = v;
      else if (f == "--gamma") gamma = v;
      else if (f == "--depth") depth = v;
      else if (f == "--width") width = v;
      else throw std::invalid_argument("unknown option '" + f + "'");
    }
    if (std::isnan(phi)) throw std::invalid_argument("--phi: missing (the soil's friction angle, deg)");
    const double k = M_PI / 180;
    const dem::WedgeResult r = dem::passive_wedge(alpha * k, phi * k, delta * k);
    std::printf("phi %g deg, delta %g deg, alpha %g deg: N_gamma %.6g, failure plane at %.4g deg, "
                "horizontal %.6g, vertical %.6g (per gamma d^2 w)\n",
                phi, delta, alpha, r.n_gamma, r.beta / k, r.horizontal, r.vertical);
    const int given = !std::isnan(gamma) + !std::isnan(depth) + !std::isnan(width);
    if (given == 3) {
      std::printf("draft force %.6g N (gamma %g N/m^3, depth %g m, width %g m)\n",
                  dem::reece_draft(gamma, depth, width, alpha * k, phi * k, delta * k), gamma, depth,
                  width);
    } else if (given != 0) {
      throw std::invalid_argument("--gamma, --depth and --width: give all three for a force");
    }
    return 0;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "soil_wedge: refused: %s\n", e.what());
    usage();
    return 2;
  }
}
