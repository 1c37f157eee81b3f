// The side-by-side benchmarks' shared scene (docs/performance.md, "Identical scenes"): the
// grain and contact parameters both codes get, and the LAMMPS-format data file (read_data,
// atom_style sphere) that LAMMPS and LIGGGHTS load the same particles from. Not a test.
#pragma once

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "dem/state.hpp"

namespace bench {

constexpr double kR = 0.005;          // m
constexpr double kDensity = 2500;     // kg/m^3
constexpr double kStiffness = 2e5;    // N/m
constexpr double kRestitution = 0.3;  // between two spheres
constexpr double kFriction = 0.5;
constexpr double kDt = 1e-5;   // s
constexpr double kSkin = 0.5;  // of r

inline double sphere_mass() { return kDensity * 4.0 / 3.0 * M_PI * kR * kR * kR; }

// gamma_n [1/s] of LAMMPS gran/hooke/history for restitution e between two equal spheres:
// eta_N = m* gamma_n with m* = m/2 and eta_N = 2 zeta sqrt(m* k).
inline double gamma_n() {
  const double le = std::log(kRestitution);
  const double zeta = -le / std::sqrt(M_PI * M_PI + le * le);
  return 2 * zeta * std::sqrt(kStiffness / (sphere_mass() / 2));
}

// How the data file numbers and declares things for the code that reads it.
struct DataFormat {
  int atom_types = 1;           // LIGGGHTS wants a second type for walls and meshes
  bool ids_from_state = true;   // atom ID = State::id + 1; false: index + 1
  const char* atoms_header = "Atoms # sphere";
};

// Writes the particles of `st` (diameter, density from the mass, position; then velocities)
// in the box [0,sx] x [0,sy] x [0,ztop].
inline void write_data_file(const dem::State& st, double sx, double sy, double ztop,
                            const std::string& title, const DataFormat& fmt,
                            const std::string& file) {
  std::FILE* f = std::fopen(file.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + file);
  std::fprintf(f, "%s\n\n", title.c_str());
  std::fprintf(f, "%zu atoms\n%d atom types\n\n", st.size(), fmt.atom_types);
  std::fprintf(f, "0 %.17g xlo xhi\n0 %.17g ylo yhi\n0 %.17g zlo zhi\n\n", sx, sy, ztop);
  std::fprintf(f, "%s\n\n", fmt.atoms_header);
  auto id = [&](std::size_t i) {
    return fmt.ids_from_state ? static_cast<long long>(st.id[i]) + 1
                              : static_cast<long long>(i) + 1;
  };
  for (std::size_t i = 0; i < st.size(); ++i) {
    const double r = st.radius[i];
    const double rho = st.mass[i] / (4.0 / 3.0 * M_PI * r * r * r);
    std::fprintf(f, "%lld 1 %.17g %.17g %.17g %.17g %.17g\n", id(i), 2 * r, rho, st.x[i].x,
                 st.x[i].y, st.x[i].z);
  }
  std::fprintf(f, "\nVelocities\n\n");
  for (std::size_t i = 0; i < st.size(); ++i)
    std::fprintf(f, "%lld %.17g %.17g %.17g 0 0 0\n", id(i), st.v[i].x, st.v[i].y, st.v[i].z);
  std::fclose(f);
}

}  // namespace bench
