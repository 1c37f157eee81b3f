// The virtual angle-of-repose test (docs/soil_lab.md): grains poured at random into a smooth
// cylinder standing on a rough base (a square array of the largest grains pinned in place), settled, the
// cylinder lifted slowly, the heap settled again; the angle is fitted to the free surface (the
// highest grain of each radial bin in each azimuthal sector).
#pragma once

#include <yaml-cpp/yaml.h>

#include <functional>
#include <string>
#include <vector>

#include "dem/lab/grains.hpp"

namespace dem::lab {

struct ReposeOptions {
  Grains grains;
  long count = 1000;            // grains in the cylinder
  std::uint64_t seed = 1;
  double cylinder_radius = 0;   // m; 0: the poured column stands two radii high
  double lift_speed = 0;        // m/s; 0: 0.5 sqrt(g d), slow against the grains' fall
  double base_radius = 0;       // m; 0: 4 cylinder radii (the rough base; grains that run off it are removed)
  double ke_per_grain = 0;      // J; settled below this; 0: 1e-6 m g d per grain
  double max_time = 10;         // s simulated per settling stage
  int sectors = 8;              // azimuthal sectors of the surface fit
  int threads = 1;
};

ReposeOptions parse_repose(const YAML::Node& root);

struct SurfacePoint {
  int sector = 0;
  double radius = 0;  // m from the axis, of the highest grain of the bin
  double height = 0;  // m above the base, top of the highest grain of the bin
  bool used = false;  // in the slope fit (sector -1: the whole ring, the angle; else a sector)
};

struct ReposeResult {
  double angle = 0;        // deg, from the fit over every sector's slope points
  double angle_sd = 0;     // deg, standard deviation of the per-sector angles
  int sectors = 0;         // sectors with a fit
  double height = 0;       // m, pile top above the base
  double pile_radius = 0;  // m, where the fitted cone meets the base
  double intercept = 0;    // m, the cone's height at the axis
  long count = 0;          // free grains left on the base
  long lost = 0;           // grains that ran off the base
  double base = 0;         // m, mean top of the base grains
  double cylinder_radius = 0;  // m
  std::vector<SurfacePoint> surface;
  std::vector<Vec3> grains;     // final positions of the free grains
  std::vector<double> radius;
};

// Fits the angle of a heap of grains (centres x, radii r) around the z axis standing on a base
// at z = base: the highest grain top in each radial bin (width bin) of each of `sectors`
// sectors; the bins whose height lies between 15 % and 85 % of the heap's height are the slope,
// fitted with one line height = a - tan(angle) radius (and one per sector for the scatter).
ReposeResult fit_heap(const std::vector<Vec3>& x, const std::vector<double>& r, double base,
                      double bin, int sectors);

using Progress = std::function<void(const std::string&)>;
ReposeResult run_repose(const ReposeOptions& o, const Progress& progress = {});

}  // namespace dem::lab
