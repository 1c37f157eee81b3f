// cosim_stability: spectral radius of the one-macro-step map of a co-simulation scheme on the
// dual-mass oscillator, and the critical macro step of each scheme / predictor pair.
// See docs/stability.md.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "stability.hpp"

namespace {

using namespace cosim::stability;

constexpr const char* kUsage =
    "usage: cosim_stability [--scheme jacobi|gauss_seidel|all] [--kq K] [--kf K]\n"
    "                       [--samples-q M] [--samples-f M] [--use-force end|average]\n"
    "                       [--H seconds ...] [--param key=value ...] [--csv FILE]\n"
    "                       [--implicit] [--iterations K ...]\n"
    "  --scheme      which scheme(s) to analyse (default all)\n"
    "  --kq, --kf    predictor orders 0..3 of the kinematic inputs and of the force; giving "
    "either\n"
    "                selects that one pair (the other defaults to 0), otherwise the table covers\n"
    "                (0,0) (1,0) (0,1) (1,1) (2,1) (2,2) (3,3)\n"
    "  --samples-q, --samples-f\n"
    "                samples fitted (default order + 1; more gives a least-squares fit)\n"
    "  --use-force   what the force connection hands over: end (the force at each macro time,\n"
    "                default) or average (its mean over each macro step, fitted by\n"
    "                histopolation), as the master's connections[].use\n"
    "  --H           macro steps in seconds: print rho and rho - 1 at each instead of the table\n"
    "  --param       oscillator parameters, keys m1 c1 d1 m2 c2 d2 cc dc (SI units)\n"
    "  --csv FILE    also write the rows as CSV\n"
    "  --implicit    the table gets, beside each explicit H_crit, the implicit scheme's\n"
    "                (coupling.type: implicit without acceleration): converged, 2 and 3\n"
    "                iterations per step, scanned up to 10 s\n"
    "  --iterations  iterations per macro step for those columns, or with --H for the rows\n"
    "                (0 = converged, 1 = explicit, 2..1000); implies --implicit\n";

// A command-line mistake: reported with the usage line, exit code 2.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Options {
  std::vector<Scheme> schemes{Scheme::Jacobi, Scheme::GaussSeidel};
  std::optional<int> kq, kf, mq, mf;
  ForceUse force = ForceUse::End;
  std::vector<double> H;
  OscParams params;
  std::string csv;
  std::vector<int> iterations;  // implicit columns (--implicit, --iterations)
};

int parse_int(const std::string& flag, const std::string& text, int lo, int hi,
              const std::string& allowed) {
  int v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || v < lo || v > hi)
    throw UsageError(flag + ": '" + text + "' is not allowed; allowed: " + allowed);
  return v;
}

double parse_double(const std::string& flag, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v))
    throw UsageError(flag + ": '" + text + "' is not a number");
  return v;
}

Options parse(int argc, char** argv) {
  Options o;
  std::vector<std::string> args(argv + 1, argv + argc);
  // Accept --flag=value as well as --flag value.
  std::vector<std::string> split;
  for (const auto& a : args) {
    const auto eq = a.find('=');
    if (a.rfind("--", 0) == 0 && eq != std::string::npos) {
      split.push_back(a.substr(0, eq));
      split.push_back(a.substr(eq + 1));
    } else {
      split.push_back(a);
    }
  }
  const auto is_flag = [](const std::string& s) { return s.rfind("--", 0) == 0; };
  for (std::size_t i = 0; i < split.size(); ++i) {
    const std::string& flag = split[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= split.size() || is_flag(split[i + 1])) throw UsageError(flag + " needs a value");
      return split[++i];
    };
    // Flags taking a list: every following word up to the next --flag.
    const auto values = [&]() {
      std::vector<std::string> out;
      while (i + 1 < split.size() && !is_flag(split[i + 1])) out.push_back(split[++i]);
      if (out.empty()) throw UsageError(flag + " needs at least one value");
      return out;
    };
    if (flag == "--help" || flag == "-h") {
      std::cout << kUsage;
      std::exit(0);
    } else if (flag == "--scheme") {
      const std::string v = value();
      if (v == "all") {
        o.schemes = {Scheme::Jacobi, Scheme::GaussSeidel};
      } else if (const auto s = parse_scheme(v)) {
        o.schemes = {*s};
      } else {
        throw UsageError("--scheme: '" + v +
                         "' is not allowed; allowed: jacobi, gauss_seidel, all");
      }
    } else if (flag == "--kq") {
      o.kq = parse_int(flag, value(), 0, 3, "0, 1, 2, 3");
    } else if (flag == "--kf") {
      o.kf = parse_int(flag, value(), 0, 3, "0, 1, 2, 3");
    } else if (flag == "--samples-q") {
      o.mq = parse_int(flag, value(), 1, 16, "1..16 (and at least kq + 1)");
    } else if (flag == "--samples-f") {
      o.mf = parse_int(flag, value(), 1, 16, "1..16 (and at least kf + 1)");
    } else if (flag == "--use-force") {
      const std::string v = value();
      const auto u = parse_force_use(v);
      if (!u) throw UsageError("--use-force: '" + v + "' is not allowed; allowed: end, average");
      o.force = *u;
    } else if (flag == "--H") {
      for (const auto& v : values()) {
        const double h = parse_double(flag, v);
        if (!(h > 0.0))
          throw UsageError("--H: '" + v + "' is not allowed; a macro step must be > 0");
        o.H.push_back(h);
      }
    } else if (flag == "--param") {
      for (const auto& kv : values()) {
        const auto eq = kv.find('=');
        if (eq == std::string::npos)
          throw UsageError("--param: '" + kv +
                           "' is not key=value; keys: m1, c1, d1, m2, c2, d2, cc, dc");
        try {
          set_param(o.params, kv.substr(0, eq),
                    parse_double("--param " + kv.substr(0, eq), kv.substr(eq + 1)));
        } catch (const std::invalid_argument& e) {
          throw UsageError(std::string("--param: ") + e.what());
        }
      }
    } else if (flag == "--csv") {
      o.csv = value();
    } else if (flag == "--implicit") {
      if (o.iterations.empty()) o.iterations = {0, 2, 3};
    } else if (flag == "--iterations") {
      o.iterations.clear();
      for (const auto& v : values())
        o.iterations.push_back(parse_int(flag, v, 0, 1000, "0 (converged), 1 (explicit), 2..1000"));
    } else {
      throw UsageError("unknown argument '" + flag +
                       "'; allowed: --scheme --kq --kf --samples-q --samples-f --use-force --H --param "
                       "--csv --implicit --iterations");
    }
  }
  try {
    validate(o.params);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--param: ") + e.what());
  }
  if (!o.iterations.empty() && o.force == ForceUse::Average)
    throw UsageError("--implicit/--iterations: the implicit scheme is modelled for --use-force end only");
  if ((o.mq && !o.kq && !o.kf) || (o.mf && !o.kq && !o.kf))
    throw UsageError("--samples-q/--samples-f apply to one pair: choose it with --kq and --kf");
  const int kq = o.kq.value_or(0), kf = o.kf.value_or(0);
  if (o.mq && *o.mq < kq + 1)
    throw UsageError("--samples-q " + std::to_string(*o.mq) + " is too few for --kq " +
                     std::to_string(kq) + ": allowed " + std::to_string(kq + 1) + "..16");
  if (o.mf && *o.mf < kf + 1)
    throw UsageError("--samples-f " + std::to_string(*o.mf) + " is too few for --kf " +
                     std::to_string(kf) + ": allowed " + std::to_string(kf + 1) + "..16");
  return o;
}

std::vector<Predictors> pairs(const Options& o) {
  if (o.kq || o.kf)
    return {Predictors{o.kq.value_or(0), o.kf.value_or(0), o.mq.value_or(0), o.mf.value_or(0),
                       o.force}};
  std::vector<Predictors> out;
  for (const auto& [kq, kf] :
       std::vector<std::pair<int, int>>{{0, 0}, {1, 0}, {0, 1}, {1, 1}, {2, 1}, {2, 2}, {3, 3}})
    out.push_back(Predictors{kq, kf, 0, 0, o.force});
  return out;
}

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string row_prefix(Scheme s, const Predictors& pr) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%-13s %2d %2d %2d %2d", std::string(scheme_name(s)).c_str(),
                pr.kq, pr.kf, pr.samples_q(), pr.samples_f());
  return buf;
}

std::string csv_prefix(Scheme s, const Predictors& pr) {
  return std::string(scheme_name(s)) + "," + std::to_string(pr.kq) + "," + std::to_string(pr.kf) +
         "," + std::to_string(pr.samples_q()) + "," + std::to_string(pr.samples_f());
}

// rho and rho - 1 at each requested macro step.
void print_at_steps(const Options& o, std::ostream* csv) {
  std::printf("%-13s %2s %2s %2s %2s  %-10s  %-14s  %-11s  %s\n", "scheme", "kq", "kf", "mq", "mf",
              "H [s]", "rho", "rho-1", "log(rho)/H [1/s]");
  if (csv) *csv << "scheme,kq,kf,mq,mf,H,rho,rho_minus_1,growth_per_s\n";
  std::vector<int> its = o.iterations.empty() ? std::vector<int>{1} : o.iterations;
  for (Scheme s : o.schemes)
    for (auto pr : pairs(o))
      for (int it : its)
      for (double H : o.H) {
        pr.iterations = it;
        if (!o.iterations.empty()) std::printf("it=%-4s ", it == 0 ? "conv" : std::to_string(it).c_str());
        const double r1 = spectral_radius_minus_one(o.params, s, pr, H);
        const double growth = std::log1p(r1) / H;
        std::printf("%s  %-10.4e  %-14.10f  %+.3e  %+.4e\n", row_prefix(s, pr).c_str(), H, 1.0 + r1,
                    r1, growth);
        if (csv)
          *csv << csv_prefix(s, pr) << "," << fmt("%.9e", H) << "," << fmt("%.15f", 1.0 + r1) << ","
               << fmt("%.9e", r1) << "," << fmt("%.9e", growth) << "\n";
      }
}

// The critical macro step of each pair, with rho - 1 at four reference steps.
void print_table(const Options& o, std::ostream* csv) {
  const ScanOptions scan_opt;
  const double refs[] = {1e-2, 2e-3, 1e-3, 5e-4};
  std::printf(
      "critical macro step = first H where rho(H) rises through 1 (log scan %.0e..%.0e s, "
      "%d points, bisected to %.0e relative)\n",
      scan_opt.h_min, scan_opt.h_max, scan_opt.points, scan_opt.rel_tol);
  std::printf("%-13s %2s %2s %2s %2s  %-12s  %-10s  %-10s  %-10s  %-10s   %s\n", "scheme", "kq",
              "kf", "mq", "mf", "H_crit [s]", "rho-1@1e-2", "rho-1@2e-3", "rho-1@1e-3",
              "rho-1@5e-4", "notes");
  if (csv)
    *csv << "scheme,kq,kf,mq,mf,H_crit,rho_minus_1_at_1e-2,rho_minus_1_at_2e-3,"
            "rho_minus_1_at_1e-3,rho_minus_1_at_5e-4,further_crossings";
  if (csv) {
    for (int it : o.iterations) *csv << ",H_crit_implicit_" << (it == 0 ? std::string("converged") : std::to_string(it));
    *csv << "\n";
  }
  for (Scheme s : o.schemes)
    for (const auto& pr : pairs(o)) {
      const StabilityScan scan = scan_stability(o.params, s, pr, scan_opt);
      const auto crit = scan.critical();
      std::string crit_text, crit_csv, notes, further;
      if (scan.unstable_at_h_min) {
        crit_text = "< " + fmt("%.1e", scan_opt.h_min);
        notes = "unstable already at the smallest H scanned";
      } else if (crit) {
        crit_text = fmt("%.6e", *crit);
        crit_csv = fmt("%.9e", *crit);
      } else {
        crit_text = "none";
        notes = "stable on the whole range";
      }
      // Crossings after the first one: the scheme can regain stability at larger H.
      bool first_up_seen = false;
      for (const auto& c : scan.crossings) {
        if (!first_up_seen && c.becomes_unstable && !scan.unstable_at_h_min) {
          first_up_seen = true;
          continue;
        }
        const std::string item =
            std::string(c.becomes_unstable ? "unstable again at " : "stable again at ") +
            fmt("%.4e", c.H);
        notes += (notes.empty() ? "" : "; ") + item;
        further += (further.empty() ? "" : "; ") + item;
      }
      std::printf("%s  %-12s", row_prefix(s, pr).c_str(), crit_text.c_str());
      if (csv) *csv << csv_prefix(s, pr) << "," << crit_csv;
      for (double H : refs) {
        const double r1 = spectral_radius_minus_one(o.params, s, pr, H);
        std::printf("  %+.3e", r1);
        if (csv) *csv << "," << fmt("%.9e", r1);
      }
      // The implicit scheme's critical step beside the explicit one.
      std::string implicit_csv;
      for (int it : o.iterations) {
        Predictors ip = pr;
        ip.iterations = it;
        ScanOptions wide = scan_opt;
        wide.h_max = 10.0;
        wide.points = 500;
        const auto ic = scan_stability(o.params, s, ip, wide).critical();
        const std::string name = it == 0 ? "converged" : std::to_string(it) + " iterations";
        std::printf("  implicit %s: %s", name.c_str(), ic ? fmt("%.4e", *ic).c_str() : "none <= 10 s");
        implicit_csv += "," + (ic ? fmt("%.9e", *ic) : std::string());
      }
      std::printf("%s%s\n", notes.empty() ? "" : "   ", notes.c_str());
      if (csv) *csv << ",\"" << further << "\"" << implicit_csv << "\n";
    }
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    o = parse(argc, argv);
  } catch (const UsageError& e) {
    std::cerr << "cosim_stability: " << e.what() << "\n" << kUsage;
    return 2;
  }
  try {
    std::ofstream csv_file;
    if (!o.csv.empty()) {
      csv_file.open(o.csv);
      if (!csv_file)
        throw std::runtime_error("--csv: cannot write '" + o.csv +
                                 "'; check that its folder exists and is writable");
    }
    std::ostream* csv = o.csv.empty() ? nullptr : &csv_file;
    if (o.force == ForceUse::Average)
      std::printf("force connection: use average (mf interval means, histopolation fit)\n");
    if (o.H.empty())
      print_table(o, csv);
    else
      print_at_steps(o, csv);
    if (csv && !csv_file.flush())
      throw std::runtime_error("--csv: writing '" + o.csv + "' failed (disk full?)");
  } catch (const std::exception& e) {
    std::cerr << "cosim_stability: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
