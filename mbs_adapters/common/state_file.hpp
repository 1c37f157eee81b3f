// Checkpoint files of the Simbody machine models (wheel loader, hauler): a multibody state's
// time and its q, u and z vectors as exact hexadecimal text, which is all a model whose
// integrator starts afresh at every macro step needs to continue bit for bit
// (docs/protocol.md#checkpoints-and-resume). Simbody-free: the models convert.
#pragma once

#include <string>
#include <vector>

namespace mbs {

struct StateVectors {
  double t = 0;
  std::vector<double> q, u, z;
};

// Throws std::runtime_error naming the file.
void write_state_file(const std::string& path, const std::string& model, const StateVectors& s);
// Throws std::runtime_error for a file of another model, another layout (vector sizes differ
// from `expected`'s) or a damaged one.
StateVectors read_state_file(const std::string& path, const std::string& model,
                             const StateVectors& expected);

}  // namespace mbs
