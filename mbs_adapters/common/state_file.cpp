#include "state_file.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace mbs {
namespace {

std::string hex(double v) {
  char text[40];
  std::snprintf(text, sizeof text, "%a", v);  // exact
  return text;
}

double number(const std::string& word) {
  char* end = nullptr;
  const double v = std::strtod(word.c_str(), &end);
  if (word.empty() || !end || *end != '\0' || !std::isfinite(v))
    throw std::runtime_error("'" + word + "' is not a finite number");
  return v;
}

}  // namespace

void write_state_file(const std::string& path, const std::string& model, const StateVectors& s) {
  std::ofstream out(path, std::ios::trunc);
  out << "mbs_state 1 " << model << "\nt " << hex(s.t) << "\n";
  for (const auto& [name, v] : {std::pair{"q", &s.q}, std::pair{"u", &s.u}, std::pair{"z", &s.z}}) {
    out << name << ' ' << v->size();
    for (double x : *v) out << ' ' << hex(x);
    out << "\n";
  }
  out.flush();
  if (!out) throw std::runtime_error("cannot write '" + path + "'");
}

StateVectors read_state_file(const std::string& path, const std::string& model,
                             const StateVectors& expected) {
  std::ifstream in(path);
  std::string magic, kind, key, word;
  int version = 0;
  if (!(in >> magic >> version >> kind) || magic != "mbs_state" || version != 1)
    throw std::runtime_error("not a machine-model state file (mbs_state 1)");
  if (kind != model) throw std::runtime_error("it is a " + kind + "'s state, this is a " + model);
  StateVectors s;
  if (!(in >> key >> word) || key != "t") throw std::runtime_error("no time");
  s.t = number(word);
  for (const auto& [name, v, want] : {std::tuple{"q", &s.q, &expected.q}, std::tuple{"u", &s.u, &expected.u},
                                      std::tuple{"z", &s.z, &expected.z}}) {
    std::size_t n = 0;
    if (!(in >> key >> n) || key != name) throw std::runtime_error(std::string("no ") + name + " vector");
    if (n != want->size())
      throw std::runtime_error(std::string("its ") + name + " has " + std::to_string(n) + " entries, the model " +
                               std::to_string(want->size()) + ": it is of another machine layout");
    v->resize(n);
    for (auto& x : *v) {
      if (!(in >> word)) throw std::runtime_error(std::string(name) + " is cut short");
      x = number(word);
    }
  }
  return s;
}

}  // namespace mbs
