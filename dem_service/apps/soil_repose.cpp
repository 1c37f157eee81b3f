// soil_repose [--mu 0.5] [--deposition-mu 0.1] [--grains 2000] [--length 0.1] [--width 0.08]
//             [--radius 0.005] [--spread 0.05] [--density 2600] [--stiffness 2e4]
//             [--restitution 0.3] [--kt-ratio 1] [--max-time 3] [--seed 1] [--threads 1]
// The angle of repose of the engine's own soil by a column collapse (docs/soil.md).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "dem/repose.hpp"

namespace {

void usage() {
  std::fprintf(stderr,
               "usage: soil_repose [--mu MU] [--deposition-mu MU] [--grains N] [--length M] [--width M] "
               "[--radius M] [--spread S] [--density KG/M3] [--stiffness N/M] [--restitution E] "
               "[--kt-ratio R] [--max-time S] [--seed N] [--threads N] [--profile 1]\n");
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
    dem::ReposeOptions o;
    bool profile = false;
    for (int a = 1; a < argc; ++a) {
      const std::string f = argv[a];
      if (f == "-h" || f == "--help") {
        usage();
        return 0;
      }
      if (a + 1 >= argc) throw std::invalid_argument("'" + f + "' needs a value (or is unknown)");
      const double v = number(f, argv[++a]);
      if (f == "--mu") o.friction = v;
      else if (f == "--deposition-mu") o.deposition_friction = v;
      else if (f == "--grains") o.grains = std::lround(v);
      else if (f == "--length") o.length = v;
      else if (f == "--width") o.width = v;
      else if (f == "--radius") o.radius = v;
      else if (f == "--spread") o.spread = v;
      else if (f == "--density") o.density = v;
      else if (f == "--stiffness") o.stiffness = v;
      else if (f == "--restitution") o.restitution = v;
      else if (f == "--kt-ratio") o.tangential_stiffness_ratio = v;
      else if (f == "--max-time") o.max_time = v;
      else if (f == "--seed") o.seed = static_cast<std::uint64_t>(std::llround(v));
      else if (f == "--threads") o.threads = static_cast<int>(std::lround(v));
      else if (f == "--profile") profile = v != 0;
      else throw std::invalid_argument("unknown option '" + f + "'");
    }
    const dem::ReposeResult r = dem::run_repose(o);
    std::printf("%ld grains, mu %g, deposited with mu %g: column %.3f m high (packing %.3f) -> %s, heap %.3f m high; "
                "angle of repose %.2f deg (%d surface points, rms %.2g m)\n",
                o.grains, o.friction, o.deposition_friction, r.column_height, r.column_fraction,
                r.at_rest ? "at rest" : "NOT at rest (--max-time)", r.final_height, r.angle * 180 / M_PI,
                r.surface_points, r.fit_rms);
    if (profile)
      for (std::size_t k = 0; k < r.profile_x.size(); ++k)
        std::printf("surface x %.4f m, top %.4f m\n", r.profile_x[k], r.profile_z[k]);
    return std::isfinite(r.angle) ? 0 : 3;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "soil_repose: refused: %s\n", e.what());
    usage();
    return 2;
  }
}
