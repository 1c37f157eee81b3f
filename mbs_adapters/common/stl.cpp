#include "stl.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <stdexcept>

namespace mbs {

void write_binary_stl(const std::vector<std::array<double, 3>>& vertices,
                      const std::vector<std::array<int, 3>>& triangles, const std::string& header,
                      const std::string& path) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error("cannot write '" + path + "'");
  char head[80] = {};
  std::strncpy(head, header.c_str(), 79);
  out.write(head, 80);
  const auto n = static_cast<std::uint32_t>(triangles.size());
  out.write(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : triangles) {
    const auto& a = vertices[t[0]];
    const auto& b = vertices[t[1]];
    const auto& c = vertices[t[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double nrm[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double l = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    float f[12];
    for (int i = 0; i < 3; ++i) f[i] = static_cast<float>(l > 0 ? nrm[i] / l : 0);
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 3; ++i) f[3 + 3 * k + i] = static_cast<float>(vertices[t[k]][i]);
    out.write(reinterpret_cast<const char*>(f), sizeof f);
    const std::uint16_t attr = 0;
    out.write(reinterpret_cast<const char*>(&attr), 2);
  }
  if (!out) throw std::runtime_error("writing '" + path + "' failed");
}

}  // namespace mbs
