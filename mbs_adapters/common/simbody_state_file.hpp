// A Simbody State to and from a checkpoint file (state_file.hpp), for the machine models. Inline
// on purpose: include it only in sources compiled as Debian's Simbody was (without -DNDEBUG,
// soil_simbody_sources), like every other file that touches SimTK types.
#pragma once

#include <Simbody.h>

#include <string>
#include <vector>

#include "state_file.hpp"

namespace mbs {

inline std::vector<double> to_std(const SimTK::Vector& v) {
  std::vector<double> out(static_cast<std::size_t>(v.size()));
  for (int i = 0; i < v.size(); ++i) out[static_cast<std::size_t>(i)] = v[i];
  return out;
}

// Time, q, u and z of `s` to `path`, tagged with `model`.
inline void save_simbody_state(const std::string& path, const std::string& model,
                               const SimTK::State& s) {
  write_state_file(path, model, {s.getTime(), to_std(s.getQ()), to_std(s.getU()), to_std(s.getZ())});
}

// Reads `path` into `s`, whose layout (vector sizes) the file must match; throws
// std::runtime_error naming the file otherwise (read_state_file).
inline void load_simbody_state(const std::string& path, const std::string& model, SimTK::State& s) {
  const StateVectors layout{0, to_std(s.getQ()), to_std(s.getU()), to_std(s.getZ())};
  const StateVectors v = read_state_file(path, model, layout);
  s.setTime(v.t);
  auto assign = [](SimTK::Vector& to, const std::vector<double>& x) {
    for (int i = 0; i < to.size(); ++i) to[i] = x[static_cast<std::size_t>(i)];
  };
  assign(s.updQ(), v.q);
  assign(s.updU(), v.u);
  assign(s.updZ(), v.z);
}

}  // namespace mbs
