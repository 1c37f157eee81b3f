// Where the wall time goes: named sections accumulated by a stopwatch, and the one timing table
// that dem_run, dem_service and cosim_master print (the idea of LAMMPS's Timer and its "Loop
// time" table). Section names are the names of the timing fields in the HDF5 output and the
// diagnostics, so the table, the files and the diagnostics say the same thing. Bus-free.
#pragma once

#include <cstddef>
#include <ostream>
#include <string>
#include <vector>

#include "cosim/stopwatch.hpp"

namespace cosim {

struct TimingRow {
  std::string section;
  double seconds = 0;
};

class Timer {
 public:
  // The sections, in table order; a section is addressed by its index in this list.
  explicit Timer(std::vector<std::string> sections);

  void add(std::size_t section, double seconds) { seconds_[section] += seconds; }
  // Adds the stopwatch's lap to `section` (consecutive sections timed by one stopwatch).
  void lap(std::size_t section, Stopwatch& watch) { seconds_[section] += watch.lap(); }
  double seconds(std::size_t section) const { return seconds_[section]; }
  const std::string& name(std::size_t section) const { return names_[section]; }
  std::size_t size() const { return names_.size(); }
  double sum() const;  // of all sections
  void reset();        // every section to zero

  // The sections as table rows, each minus what `earlier` (the same timer at an earlier time)
  // had: the time spent since then.
  std::vector<TimingRow> rows() const;
  std::vector<TimingRow> rows_since(const Timer& earlier) const;

 private:
  std::vector<std::string> names_;
  std::vector<double> seconds_;
};

// Prints the timing table: `title`, then one line per row (section, seconds, percent of
// `wall`), then `notes` one a line:
//
//   Loop time of 0.979 s for 2000 steps with 5000 particles on 1 thread(s)
//
//   Section               |   time (s) |  %total
//   ----------------------+------------+--------
//   broad_phase           |      0.422 |  43.12
//   ...
void print_timing_table(std::ostream& out, const std::string& title,
                        const std::vector<TimingRow>& rows, double wall,
                        const std::vector<std::string>& notes = {});

}  // namespace cosim
