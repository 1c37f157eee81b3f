// libFuzzer target: the STL mesh loader, binary and ASCII. The input is the file's bytes. The
// strict reader (dem::read_stl) runs first; what it accepts goes on to assimp (from memory, as
// load_mesh reads an .stl) and to build_mesh (welding, edges, valences). Refusals are
// std::runtime_error naming the file; anything else escaping is a crash.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "dem/mesh.hpp"
#include "dem/stl.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    const auto triangles = dem::read_stl(bytes, "fuzz.stl");
    const dem::Mesh m = dem::load_mesh_data(bytes, "fuzz.stl", 1.0, {});
    // What the reader accepted, assimp must have read triangle for triangle (it drops none
    // of a well-formed file): the two readers agree on the count of non-degenerate ones.
    if (m.triangles.size() > triangles.size()) __builtin_trap();
  } catch (const std::runtime_error&) {
  }
  return 0;
}
