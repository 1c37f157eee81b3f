#include "cosim/timer.hpp"

#include <cstdio>

namespace cosim {

Timer::Timer(std::vector<std::string> sections)
    : names_(std::move(sections)), seconds_(names_.size(), 0.0) {}

double Timer::sum() const {
  double s = 0;
  for (double v : seconds_) s += v;
  return s;
}

void Timer::reset() { seconds_.assign(names_.size(), 0.0); }

std::vector<TimingRow> Timer::rows() const {
  std::vector<TimingRow> r;
  for (std::size_t i = 0; i < names_.size(); ++i) r.push_back({names_[i], seconds_[i]});
  return r;
}

std::vector<TimingRow> Timer::rows_since(const Timer& earlier) const {
  std::vector<TimingRow> r = rows();
  for (std::size_t i = 0; i < r.size() && i < earlier.seconds_.size(); ++i)
    r[i].seconds -= earlier.seconds_[i];
  return r;
}

void print_timing_table(std::ostream& out, const std::string& title,
                        const std::vector<TimingRow>& rows, double wall,
                        const std::vector<std::string>& notes) {
  char line[256];
  out << "\n" << title << "\n\n";
  std::snprintf(line, sizeof line, "%-22s| %10s | %7s\n", "Section", "time (s)", "%total");
  out << line << "----------------------+------------+--------\n";
  for (const TimingRow& r : rows) {
    std::snprintf(line, sizeof line, "%-22s| %10.3f | %6.2f\n", r.section.c_str(), r.seconds,
                  wall > 0 ? 100 * r.seconds / wall : 0.0);
    out << line;
  }
  if (!notes.empty()) out << "\n";
  for (const std::string& n : notes) out << n << "\n";
  out.flush();
}

}  // namespace cosim
