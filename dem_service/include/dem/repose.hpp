// An angle-of-repose test of the engine's own soil (docs/soil.md): a column of grains deposited
// in a box between smooth side walls is released by removing the front wall; the grains run out
// over a rough floor and come to rest. The angle is the slope of the free surface, a line fitted
// to the surface heights between 20 % and 80 % of the heap's height (the 2 diameters next to the
// back wall left out: a column one grain wide stands there).
#pragma once

#include <cstdint>
#include <vector>

namespace dem {

struct ReposeOptions {
  long grains = 2000;
  double radius = 0.005, spread = 0.05, density = 2600;
  double stiffness = 2e4;  // N/m
  double restitution = 0.3;
  double tangential_stiffness_ratio = 1.0;
  double friction = 0.5;             // particle-particle and floor
  double deposition_friction = 0.1;  // while the column is deposited
  double length = 0.1;               // m, the column's length along x (the run-out direction)
  double width = 0.08;               // m, between the smooth side walls
  double max_time = 3.0;             // s simulated after the release
  std::uint64_t seed = 1;
  int threads = 1;
};

struct ReposeResult {
  double angle = 0;        // rad
  double column_height = 0;  // m, top of the column before the release
  double final_height = 0;   // m, top of the heap after (beyond the 2 diameters at the back wall)
  double column_fraction = 0;  // packing fraction of the deposited column (inner region)
  int surface_points = 0;  // surface heights the line was fitted to
  double fit_rms = 0;      // m
  bool at_rest = false;
  std::vector<double> profile_x, profile_z;  // the surface, one point per diameter of x
};

// Throws std::invalid_argument naming the option (as --name) for a bad value.
void validate(const ReposeOptions& o);
ReposeResult run_repose(const ReposeOptions& o);

}  // namespace dem
