// Granular packings: random sequential insertion (no lattice), a deposition that lets the
// inserted grains fall under gravity with a chosen friction and then freezes them into contact
// with the scene's own laws, and the measures of a bed (packing fraction, bulk density,
// coordination number) in an inner region away from walls and the free surface.
// docs/soil.md describes the method and today's numbers.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "dem/bed.hpp"
#include "dem/engine.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

// An axis-aligned box.
struct Box {
  Vec3 min, max;
  double volume() const {
    return std::max(0.0, max.x - min.x) * std::max(0.0, max.y - min.y) * std::max(0.0, max.z - min.z);
  }
};

// The measures of a bed in `region`.
struct PackingStats {
  Box region;                   // where it was measured
  double fraction = 0;          // solid volume / region volume (spheres cut by the box count in part)
  double bulk_density = 0;      // kg/m^3: solid mass in the region / region volume
  double coordination = 0;      // particle contacts per grain whose centre is in the region
  double rattlers = 0;          // share of those grains with fewer than 2 contacts
  long long grains = 0;         // grains whose centre is in the region
  double max_overlap_ratio = 0; // over the whole bed: largest pair or wall overlap / smaller radius
};

// Default margin of the inner region, in mean grain diameters (docs/soil.md).
inline constexpr double kPackingMarginDiameters = 2.5;
// Two grains touch when their centre distance is at most (r_i + r_j)(1 + kContactGap).
inline constexpr double kContactGap = 1e-6;

// The box of the particle centres shrunk by margin_diameters mean diameters on every face (the
// top face too: the free surface is loose). Throws std::invalid_argument naming the margin when
// nothing is left.
Box inner_region(const State& s, double margin_diameters = kPackingMarginDiameters);

// Solid fraction and bulk density by a jittered grid of sample points in the region (one seeded
// random point per cell of about 1/32 of the smallest diameter, at most ~8e6 cells: error below
// 1e-3 on lattices),
// coordination by a cell search. Throws std::invalid_argument for an empty region.
PackingStats measure_packing(const Scene& scene, const State& s, const Box& region);

// The largest overlap of the state, as a fraction of the smaller radius: particle pairs and
// particles against walls.
double max_overlap_ratio(const Scene& scene, const State& s);

// One line: "packing fraction 0.6412, bulk density 1603 kg/m^3, coordination 5.92 (rattlers
// 3.1 %), 812 grains in [x0, x1] x [y0, y1] x [z0, z1] m".
std::string describe(const PackingStats& p);

// --- Random sequential insertion.

// A box, a grain count and a seed: the same as a lattice fill's region (bed.hpp).
using InsertRegion = FillRegion;
// The largest solid fraction an insertion region may be asked to hold (random sequential
// insertion of spheres jams near 0.38; above about 0.3 it needs many attempts per grain).
inline constexpr double kMaxInsertionFraction = 0.3;

// Places `count` grains of the species at uniformly random non-overlapping positions inside
// the region (whole spheres inside), without a lattice; radii from the species distribution.
// Seeded, reproducible (own generator). A region that cannot hold count at
// kMaxInsertionFraction, or where the insertion fails, is refused with
// cosim::config::ConfigError naming `path` and the height that would hold the grains.
void insert_random(const Scene& scene, const InsertRegion& region, State& s,
                   const std::string& path = "particles.insert");

// --- Deposition: the inserted grains fall and come to rest with `deposition_friction` in
// every law, then the scene's own laws are switched on (velocities zeroed) and the bed settles
// again (frozen into contact). Frictionless deposition gives random close packing; friction
// during the fall makes it looser.
struct PrepareOptions {
  bool enabled = false;
  double deposition_friction = 0.0;  // Coulomb mu of every law while the grains fall
  double ke_per_particle = 1e-9;     // J: at rest (each stage)
  double max_time = 5.0;             // s simulated, each stage
  double margin = kPackingMarginDiameters;  // inner region, mean diameters
  std::string checkpoint;            // the prepared bed ("" = not saved)
};

struct PrepareResult {
  double deposition_time = 0, freeze_time = 0;  // s simulated
  bool deposition_converged = false, freeze_converged = false;
  PackingStats packing;
};

// Runs both stages on s (tools hold the pose they have in s). progress(stage, time, ke) is
// called every 100 steps. Throws std::invalid_argument if the inner region is empty.
PrepareResult prepare_bed(const Scene& scene, State& s, const PrepareOptions& o,
                          const std::function<void(const char*, double, double)>& progress = {});

// --- The bed's record in an HDF5 file (a checkpoint): attributes of the group "/bed".
// packing may be absent (a bed too small for an inner region): only the overlap is stored.
void write_bed_record(const std::string& path, double max_overlap_ratio,
                      const std::optional<PackingStats>& packing);
// The recorded largest overlap ratio of a bed file, if it has one.
std::optional<double> read_bed_overlap(const std::string& path);

}  // namespace dem
