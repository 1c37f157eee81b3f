// TYDEX C-axis system (TYre Data EXchange, "centre" axes) of a wheel: origin at the wheel
// centre; x in the wheel plane and parallel to the road; y along the spin axis, to the left;
// z = x cross y (in the wheel plane, "up" for a wheel standing on the road). The axes are built
// from the spin axis and the road normal, never from the axle body's axes: a pitched axle has
// the same TYDEX axes as a level one, a rolled (cambered) one has z tilted with the wheel plane.
// Plain C++ (the Simbody model and the tests both use it).
#pragma once

#include <array>
#include <cmath>
#include <stdexcept>

namespace hauler {

using Dir3 = std::array<double, 3>;

struct TydexAxes {
  Dir3 x{}, y{}, z{};
};

inline Dir3 tydex_cross(const Dir3& a, const Dir3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double tydex_dot(const Dir3& a, const Dir3& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// spin_axis: the wheel's spin axis pointing to the vehicle's left; road_normal: up, out of the
// road. Neither needs unit length. Raises std::invalid_argument if the spin axis is (nearly)
// along the road normal (a wheel lying flat has no TYDEX axes).
inline TydexAxes tydex_c_axes(const Dir3& spin_axis, const Dir3& road_normal) {
  const double ls = std::sqrt(tydex_dot(spin_axis, spin_axis));
  const double ln = std::sqrt(tydex_dot(road_normal, road_normal));
  if (!(ls > 0 && ln > 0)) throw std::invalid_argument("tydex_c_axes: zero spin axis or road normal");
  TydexAxes a;
  a.y = {spin_axis[0] / ls, spin_axis[1] / ls, spin_axis[2] / ls};
  const Dir3 n{road_normal[0] / ln, road_normal[1] / ln, road_normal[2] / ln};
  // x is perpendicular to the spin axis (in the wheel plane) and to the road normal (parallel
  // to the road): along y x n, which points forward for y left and n up
  const Dir3 x = tydex_cross(a.y, n);
  const double lx = std::sqrt(tydex_dot(x, x));
  if (!(lx > 1e-9))
    throw std::invalid_argument("tydex_c_axes: the spin axis is along the road normal");
  a.x = {x[0] / lx, x[1] / lx, x[2] / lx};
  a.z = tydex_cross(a.x, a.y);
  return a;
}

// A force vector (any frame the two axes are given in) in TYDEX C components (Fx, Fy, Fz).
inline Dir3 tydex_c(const Dir3& spin_axis, const Dir3& road_normal, const Dir3& force) {
  const TydexAxes a = tydex_c_axes(spin_axis, road_normal);
  return {tydex_dot(force, a.x), tydex_dot(force, a.y), tydex_dot(force, a.z)};
}

}  // namespace hauler
