// Large benchmark beds as tiles of one settled 10k bed of spheres of radius r, shared by
// dem_bench and dem_side_by_side: settling 150k+ spheres from scratch takes most of an hour on
// 2 cores. Copies side by side do not overlap (the tile's side walls coincide); the caller
// relaxes the seams briefly.
#pragma once

#include <algorithm>
#include <cmath>
#include <utility>

#include "dem/state.hpp"

namespace bench {

constexpr long kTile = 10000;  // particles in one tile

// Footprint of one tile (about 40 layers high once settled).
inline double tile_side(double r) {
  return std::sqrt(static_cast<double>(kTile) / 40.0) * 2 * r * 1.15 + 2 * r;
}

// Tiles along x and y for n particles (n / kTile tiles, as square as the count allows).
inline std::pair<long, long> tiling(long n) {
  const long k = std::max(1L, n / kTile);
  long nx = static_cast<long>(std::sqrt(static_cast<double>(k)));
  while (k % nx) --nx;
  return {nx, k / nx};
}

// n particles (a multiple of kTile) as copies of `tile`, at rest, ids 0..n-1, species 0.
inline dem::State tiled_bed(const dem::State& tile, long n, double r) {
  const auto [tx, ty] = tiling(n);
  const double side = tile_side(r);
  dem::State st;
  std::int64_t id = 0;
  for (long a = 0; a < tx; ++a)
    for (long b = 0; b < ty; ++b)
      for (std::size_t i = 0; i < tile.size(); ++i)
        dem::add_particle(st, tile.x[i] + dem::Vec3{a * side, b * side, 0}, {}, tile.radius[i],
                          tile.mass[i], 0, id++);
  return st;
}

}  // namespace bench
