// A strict reader of STL files, binary and ASCII, that names what is wrong: a truncated file,
// a token where a keyword belongs, a coordinate that is not a finite 32-bit float (STL stores
// floats). load_mesh runs it on every .stl file before assimp reads the file.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

namespace dem {

struct StlTriangle {
  std::array<std::array<float, 3>, 3> corner;
};

// Parses the file's bytes. Binary when the size is 84 + 50 x the triangle count in the header
// (what assimp decides too), else ASCII, which must start with "solid". Raises
// std::runtime_error "mesh file '<source>': ..." naming the line, vertex or byte count and the
// fix. Vertices are numbered from 0 in file order (vertex k is corner k % 3 of triangle k / 3).
std::vector<StlTriangle> read_stl(std::string_view bytes, const std::string& source);

// True when the path ends in .stl (any case).
bool is_stl_path(const std::string& path);

}  // namespace dem
