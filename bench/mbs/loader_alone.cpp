// The wheel loader alone, as its bus adapter steps it, against a recorded soil wrench: no bus,
// no master, no DEM (docs/performance.md, "The loader alone"). The CPU seconds of the stepping
// per simulated second, per macro step and per inner step; every output of every step (the
// kinematics and scalars the adapter sends, its diagnostics) to a raw file whose bytes two
// builds can be compared by (cmp). Not a test.
//
//   loader_alone [--wrench FILE.f64] [--end 2.0] [--macro 1e-3] [--machine configs/wheel_loader/machine.yaml]
//                [--params '{inner_step: 2e-4}'] [--out FILE.f64] [--average 0|1]
//
// --wrench: float64 little-endian, 9 numbers per macro step (force, torque about r, r; ground):
//   the constant wrench of step k is row k (the main job's order-0 force predictor under
//   Jacobi). bench/mbs/export_wrench.py writes it from a master record. Rows past its end and
//   NaN rows are a zero wrench; without --wrench the wrench is zero throughout.
// --out: per step the bucket kinematics (13), the scalars (14) and the diagnostics (4), float64.
// --average 1 asks for interval averages at every step (the path a `use: average` connection
//   takes) and writes them after the outputs.
#include <cosim/participant.hpp>
#include <cosim/yaml_config.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "../common/cli.hpp"
#include "wheel_loader_adapter.hpp"

namespace {

// A positive number from option `key`, or a message naming it.
double positive(const std::map<std::string, std::string>& opt, const std::string& key) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(opt.at(key), &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != opt.at(key).size() || !(v > 0) || !std::isfinite(v))
    throw std::invalid_argument(key + " needs a positive number of seconds, got '" + opt.at(key) + "'");
  return v;
}

std::vector<double> read_f64(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::vector<double> v;
  double x;
  while (in.read(reinterpret_cast<char*>(&x), sizeof x)) v.push_back(x);
  if (v.size() % 9 != 0) throw std::runtime_error(path + ": not 9 float64 per row");
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> opt{{"--wrench", ""},     {"--end", "2.0"},
                                         {"--macro", "1e-3"},  {"--machine", "configs/wheel_loader/machine.yaml"},
                                         {"--params", "{}"},   {"--out", ""},
                                         {"--average", "0"}};
  if (!bench::parse_options(argc, argv, 1, "loader_alone", opt)) return 2;
  try {
    const double end = positive(opt, "--end"), macro = positive(opt, "--macro");
    if (opt["--average"] != "0" && opt["--average"] != "1")
      throw std::invalid_argument("--average must be 0 or 1, got '" + opt["--average"] + "'");
    const bool average = opt["--average"] == "1";
    const std::vector<double> wrench = opt["--wrench"].empty() ? std::vector<double>{} : read_f64(opt["--wrench"]);
    const long steps = std::lround(end / macro);
    if (steps < 1 || std::abs(steps * macro - end) > 1e-9 * end)
      throw std::invalid_argument("--end must be a whole number of --macro steps");
    const auto H = cosim::nanoseconds(std::llround(macro * 1e9));

    wheel_loader::WheelLoaderAdapter m(cosim::config::load_file(opt["--machine"]));
    const double c0 = bench::cpu_seconds();
    m.configure(YAML::Load(opt["--params"]), {"loader", cosim::TimePoint{}, cosim::TimePoint{} + H * steps, H});
    const double c_configure = bench::cpu_seconds() - c0;
    m.initial_outputs();

    std::FILE* out = opt["--out"].empty() ? nullptr : std::fopen(opt["--out"].c_str(), "wb");
    if (!opt["--out"].empty() && !out) throw std::runtime_error("cannot write " + opt["--out"]);
    auto write = [&](const cosim::Signals& s) {
      for (const auto& [name, sig] : s) std::fwrite(sig.value.data(), sizeof(double), sig.value.size(), out);
    };

    long nonzero = 0;
    cosim::TimePoint t{};
    const double c1 = bench::cpu_seconds();
    for (long k = 0; k < steps; ++k, t += H) {
      cosim::Value w(9, 0.0);
      if (9 * (k + 1) <= static_cast<long>(wrench.size()) && !std::isnan(wrench[9 * k]))
        for (int i = 0; i < 9; ++i) w[i] = wrench[9 * k + i];
      nonzero += w[0] != 0 || w[2] != 0;
      const cosim::Polynomials in{
          {"bucket_wrench", cosim::InputPolynomial::constant(cosim::SignalKind::Wrench, w)}};
      const cosim::StepResult r = m.step(cosim::StepInputs(t, t + H, in), average);
      if (out) {
        write(r.outputs);
        for (const auto& [name, v] : r.diagnostics) std::fwrite(&v, sizeof v, 1, out);
        if (r.average) write(*r.average);
      }
    }
    const double cpu = bench::cpu_seconds() - c1;
    if (out) std::fclose(out);
    const double inner = 1e-9 * static_cast<double>(cosim::to_ns(m.inner_step()));
    const double substeps = steps * std::round(macro / inner);
    std::printf("loader_alone: %ld macro steps of %g s (%ld with a soil wrench), inner step %g s, average %d\n",
                steps, macro, nonzero, inner, average ? 1 : 0);
    std::printf("configure (static equilibrium) %.3f CPU s\n", c_configure);
    std::printf("stepping %.3f CPU s: %.3f CPU s per simulated s, %.1f us per macro step, %.1f us per inner step\n",
                cpu, cpu / (steps * macro), 1e6 * cpu / steps, 1e6 * cpu / substeps);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "loader_alone: %s\n", e.what());
    return 1;
  }
}
