// The bucket as a triangle mesh in the bucket frame (origin at the A-pin, x along the floor
// towards the cutting edge, y left, z up): an open shell of thin surfaces, consistently
// oriented with every normal on the soil side (into the bucket; under the cutting-edge bevel,
// downwards). One strip follows the profile across the width (bevel under the cutting edge,
// bottom plate, heel arc, back plate, spill guard); two side plates close its ends and share
// its end vertices. Rim (edges used once): the spill guard's top, the side plates' front
// edges, the bevel's back edge and its ends.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "parameters.hpp"

namespace wheel_loader {

using Point = std::array<double, 3>;
using Triangle = std::array<Point, 3>;

constexpr int kMaxRefine = 4;

struct BucketMesh {
  std::vector<Point> vertices;
  std::vector<std::array<int, 3>> triangles;
  double struck_volume = 0;  // m3: side-plate area (below the strike line) times the width
  double heaped_volume = 0;  // m3: struck plus a 2:1 heap over the strike plane (SAE J742)
};

// refine 1 (a few thousand triangles) .. kMaxRefine (about 40,000); element size 0.1/refine m.
BucketMesh make_bucket_mesh(const BucketShape& shape, int refine);
// Binary STL; raises std::runtime_error if the file cannot be written.
void write_stl(const BucketMesh& mesh, const std::string& path);

}  // namespace wheel_loader
