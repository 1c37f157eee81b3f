#include "dem/stl.hpp"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace dem {
namespace {

constexpr std::size_t kHeader = 84, kRecord = 50;

[[noreturn]] void fail(const std::string& source, const std::string& what) {
  throw std::runtime_error("mesh file '" + source + "': " + what);
}

std::string vertex_name(std::size_t k) {
  return "vertex " + std::to_string(k) + " (triangle " + std::to_string(k / 3) + ", corner " +
         std::to_string(k % 3) + ")";
}

std::string show(double v) {
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

std::vector<StlTriangle> read_binary(std::string_view b, const std::string& source) {
  std::uint32_t n = 0;
  std::memcpy(&n, b.data() + 80, 4);
  std::vector<StlTriangle> out(n);
  for (std::uint32_t t = 0; t < n; ++t) {
    const char* rec = b.data() + kHeader + kRecord * t;
    for (int c = 0; c < 3; ++c) {
      std::memcpy(out[t].corner[c].data(), rec + 12 + 12 * c, 12);  // after the normal
      const auto& p = out[t].corner[c];
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
        fail(source, vertex_name(3 * t + c) + " is (" + show(p[0]) + ", " + show(p[1]) + ", " +
                         show(p[2]) + "): not a finite number; fix or re-export the mesh");
    }
  }
  return out;
}

// Whitespace-separated words with their line numbers.
class Words {
 public:
  explicit Words(std::string_view text) : t_(text) {}
  bool next(std::string_view& word) {
    while (i_ < t_.size() && (std::isspace(static_cast<unsigned char>(t_[i_])) || t_[i_] == '\0')) {
      if (t_[i_] == '\n') ++line_;
      ++i_;
    }
    if (i_ >= t_.size()) return false;
    const std::size_t start = i_;
    while (i_ < t_.size() && !std::isspace(static_cast<unsigned char>(t_[i_])) && t_[i_] != '\0') ++i_;
    word = t_.substr(start, i_ - start);
    return true;
  }
  // Only whitespace (or nothing) left: the word just read was the file's last.
  bool at_end() const {
    for (std::size_t k = i_; k < t_.size(); ++k)
      if (!std::isspace(static_cast<unsigned char>(t_[k])) && t_[k] != '\0') return false;
    return true;
  }
  void skip_line() {
    while (i_ < t_.size() && t_[i_] != '\n') ++i_;
  }
  std::size_t line() const { return line_; }

 private:
  std::string_view t_;
  std::size_t i_ = 0, line_ = 1;
};

bool same_word(std::string_view a, std::string_view keyword) {
  if (a.size() != keyword.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != keyword[i]) return false;
  return true;
}

std::string clip(std::string_view w) {
  std::string s(w.substr(0, 40));
  for (char& c : s)
    if (!std::isprint(static_cast<unsigned char>(c))) c = '?';
  return w.size() > 40 ? s + "..." : s;
}

std::vector<StlTriangle> read_ascii(std::string_view text, const std::string& source) {
  Words words(text);
  std::vector<StlTriangle> out;
  std::string_view w;
  std::string solid;  // name of the open solid
  auto truncated = [&](const char* expected) {
    fail(source, "the ASCII STL ends at line " + std::to_string(words.line()) + " inside solid '" +
                     solid + "' after " + std::to_string(out.size()) +
                     " complete triangles, where '" + expected +
                     "' should follow: the file is truncated; re-export it");
  };
  auto expect = [&](const char* keyword) {
    if (!words.next(w)) truncated(keyword);
    if (!same_word(w, keyword) && words.at_end()) truncated(keyword);  // cut inside a word
    if (!same_word(w, keyword))
      fail(source, "line " + std::to_string(words.line()) + ": expected '" + keyword + "', got '" +
                       clip(w) + "': not a valid ASCII STL; re-export it");
  };
  auto number = [&](std::size_t vertex, int axis) -> float {
    if (!words.next(w)) truncated("a coordinate");
    const std::string s(w);
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(s.c_str(), &end);
    const char* name = axis == 0 ? "x" : axis == 1 ? "y" : "z";
    if (s.empty() || end != s.c_str() + s.size())
      fail(source, "line " + std::to_string(words.line()) + ": " + vertex_name(vertex) + " " + name +
                       " is '" + clip(w) + "', not a number; fix or re-export the mesh");
    if (!std::isfinite(v))
      fail(source, "line " + std::to_string(words.line()) + ": " + vertex_name(vertex) + " " + name +
                       " is '" + clip(w) + "': not a finite number; fix or re-export the mesh");
    if (std::abs(v) > std::numeric_limits<float>::max())
      fail(source, "line " + std::to_string(words.line()) + ": " + vertex_name(vertex) + " " + name +
                       " is " + clip(w) + ", beyond the 32-bit floats an STL stores (about 3.4e38): "
                       "check the export units");
    return static_cast<float>(v);
  };

  if (!words.next(w) || !same_word(w, "solid"))
    fail(source, "neither a binary STL (its size is not 84 + 50 x the triangle count in its "
                 "header) nor an ASCII STL (it does not start with 'solid'): truncated or not an "
                 "STL; re-export it");
  for (;;) {  // one solid per pass
    const std::size_t line = words.line();
    words.skip_line();  // the solid's name
    solid = "at line " + std::to_string(line);
    for (;;) {
      if (!words.next(w)) truncated("endsolid");
      if (same_word(w, "endsolid")) {
        words.skip_line();
        break;
      }
      if (!same_word(w, "facet") && words.at_end()) truncated("facet' or 'endsolid");
      if (!same_word(w, "facet"))
        fail(source, "line " + std::to_string(words.line()) + ": expected 'facet' or 'endsolid', got '" +
                         clip(w) + "': not a valid ASCII STL; re-export it");
      expect("normal");
      for (int k = 0; k < 3; ++k)  // the normal is not used: any three words
        if (!words.next(w)) truncated("a normal component");
      expect("outer");
      expect("loop");
      StlTriangle tri{};
      for (int c = 0; c < 3; ++c) {
        expect("vertex");
        for (int a = 0; a < 3; ++a) tri.corner[c][a] = number(3 * out.size() + c, a);
      }
      expect("endloop");
      expect("endfacet");
      out.push_back(tri);
    }
    if (!words.next(w)) return out;
    if (!same_word(w, "solid"))
      fail(source, "line " + std::to_string(words.line()) + ": '" + clip(w) +
                       "' after 'endsolid' (only another solid may follow): re-export the mesh");
  }
}

}  // namespace

bool is_stl_path(const std::string& path) {
  if (path.size() < 4) return false;
  return same_word(std::string_view(path).substr(path.size() - 4), ".stl");
}

std::vector<StlTriangle> read_stl(std::string_view bytes, const std::string& source) {
  if (bytes.size() >= kHeader) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    if (bytes.size() == kHeader + kRecord * static_cast<std::uint64_t>(n)) return read_binary(bytes, source);
  }
  std::size_t i = 0;
  while (i < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[i]))) ++i;
  if (bytes.substr(i, 5) != "solid" && bytes.size() >= kHeader) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    fail(source, "a binary STL of " + std::to_string(bytes.size()) + " bytes, but its header says " +
                     std::to_string(n) + " triangles, which take 84 + 50 x " + std::to_string(n) +
                     " = " + std::to_string(kHeader + kRecord * static_cast<std::uint64_t>(n)) +
                     " bytes: the file is truncated or damaged; re-export it");
  }
  return read_ascii(bytes, source);
}

}  // namespace dem
