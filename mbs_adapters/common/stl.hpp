// Binary STL output for the meshes the machine models generate (bucket, dump body).
#pragma once

#include <array>
#include <string>
#include <vector>

namespace mbs {

// Writes the triangles (vertex indices, counter-clockwise seen from the side the normal points
// to) as binary STL with facet normals from the corner order; header: at most 79 characters,
// e.g. the frame the coordinates are in. Throws std::runtime_error naming the path.
void write_binary_stl(const std::vector<std::array<double, 3>>& vertices,
                      const std::vector<std::array<int, 3>>& triangles, const std::string& header,
                      const std::string& path);

}  // namespace mbs
