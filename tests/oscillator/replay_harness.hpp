// Helpers of the recording and replay tests (docs/replay.md): cosim_master with any arguments,
// bit-for-bit comparison of recorded datasets, LCM log files read and rewritten with LCM's own
// C++ API (lcm::LogFile, what lcm-logger and lcm-logplayer use).
#pragma once

#include <lcm/lcm-cpp.hpp>

#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "harness.hpp"

namespace replay_harness {

inline bool bit_identical(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

inline bool key_in_environment() {
  for (const char* name : {"COSIM_KEY_FILE", "COSIM_KEY"})
    if (const char* v = std::getenv(name); v && *v) return true;
  return false;
}

// cosim_master CONFIG ARGS... --output H5 with the test's own bus URL; the log is H5.log.
// Returns the exit code. Without a key in the environment the run is unkeyed
// (bus.authenticate=false), as the recordings these tests take apart are: a default run would
// seal its messages with a fresh key of its own (docs/security.md).
inline int run_cosim_master(const std::string& config, const std::string& h5, const std::vector<std::string>& args,
                  double timeout_s = 120) {
  std::vector<std::string> a{harness::bin("cosim_master"), harness::source(config), "--output", h5,
                             "--set", "bus.url=" + harness::bus_url(), "--set", "output.csv=",
                             "--set", "output.progress=off"};
  if (!key_in_environment()) a.insert(a.end(), {"--set", "bus.authenticate=false"});
  a.insert(a.end(), args.begin(), args.end());
  harness::Process p = harness::spawn(a, h5 + ".log");
  return harness::wait_for(p, timeout_s);
}

inline double number(const std::string& h5, const std::string& name) {
  const auto v = harness::read_dataset(h5, name);
  return v.size() == 1 ? v[0] : -12345;
}

// A string dataset without the padding HDF5 may keep.
inline std::string text(const std::string& h5, const std::string& name) {
  std::string s = harness::read_string(h5, name);
  while (!s.empty() && s.back() == '\0') s.pop_back();
  return s;
}

struct Event {
  int64_t timestamp;
  std::string channel;
  std::vector<std::uint8_t> data;
};

// Every event of an LCM log, read with lcm::LogFile.
inline std::vector<Event> read_log(const std::string& path) {
  std::vector<Event> out;
  lcm::LogFile f(path, "r");
  if (!f.good()) return out;
  while (const lcm::LogEvent* e = f.readNextEvent()) {
    const auto* d = static_cast<const std::uint8_t*>(e->data);
    out.push_back({e->timestamp, e->channel, std::vector<std::uint8_t>(d, d + e->datalen)});
  }
  return out;
}

inline void write_log(const std::string& path, const std::vector<Event>& events) {
  lcm::LogFile f(path, "w");
  for (const auto& e : events) {
    lcm::LogEvent le{};
    le.timestamp = e.timestamp;
    le.channel = e.channel;
    le.datalen = static_cast<int32_t>(e.data.size());
    le.data = const_cast<std::uint8_t*>(e.data.data());
    f.writeEvent(&le);
  }
}

inline bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

// Sets (or clears, with "") an environment variable for the processes a test starts; puts the
// old value back at the end.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    set(value);
  }
  void set(const std::string& value) {
    if (value.empty()) unsetenv(name_);
    else setenv(name_, value.c_str(), 1);
  }
  ~ScopedEnv() { set(old_.value_or("")); }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

}  // namespace replay_harness
