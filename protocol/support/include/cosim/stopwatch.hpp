// The one wall clock of the project (monotonic) and a stopwatch on it: every timing row,
// timeout, progress line and flush interval is measured with these. Bus-free, header-only.
#pragma once

#include <chrono>

namespace cosim {

using WallClock = std::chrono::steady_clock;

// Seconds between two wall-clock instants.
inline double seconds_between(WallClock::time_point from, WallClock::time_point to) {
  return std::chrono::duration<double>(to - from).count();
}

// Seconds from `from` until now.
inline double seconds_since(WallClock::time_point from) {
  return seconds_between(from, WallClock::now());
}

class Stopwatch {
 public:
  Stopwatch() : start_(WallClock::now()) {}
  // Seconds since construction or the last restart()/lap().
  double seconds() const { return seconds_between(start_, WallClock::now()); }
  void restart() { start_ = WallClock::now(); }
  // seconds(), and starts again from now: consecutive laps add up to the whole.
  double lap() {
    const WallClock::time_point now = WallClock::now();
    const double s = seconds_between(start_, now);
    start_ = now;
    return s;
  }

 private:
  WallClock::time_point start_;
};

}  // namespace cosim
