// The dump body's inner shell as a triangle mesh in the body frame (origin on the hinge axis
// at the centre plane, x forward along the floor, y left, z up from the floor when lowered):
// floor, front wall and two side walls as thin plates, open at the tail (x = tail_x) and at
// the top. The plates share their seam vertices (floor-front, floor-sides, front-sides), the
// mesh is consistently oriented and every normal points into the load. Rim (edges used once):
// the top edges of the walls and the tail edges of the floor and the side walls.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "parameters.hpp"

namespace hauler {

using Point = std::array<double, 3>;

struct BodyMesh {
  std::vector<Point> vertices;
  std::vector<std::array<int, 3>> triangles;
  int nx = 0, ny = 0, nz = 0;  // pieces along the length, the width and the height
  double volume = 0;           // m3: the cavity, length x width x side height
};

// element: the target edge length [m] (each side is cut into pieces no longer than it),
// between 0.02 and 1 m.
BodyMesh make_body_mesh(const BodyShape& shape, double element = 0.2);
// Binary STL; raises std::runtime_error if the file cannot be written.
void write_stl(const BodyMesh& mesh, const std::string& path);

}  // namespace hauler
