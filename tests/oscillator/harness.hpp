// Test harness for the oscillator: the same schedule in one process (in-process transport)
// or as three processes over LCM on loopback, each test on its own UDP port.
#pragma once

#include <cosim/link.hpp>
#include <cosim/stopwatch.hpp>
#include <hdf5.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <gtest/gtest.h>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "config.hpp"
#include "cosimulation.hpp"
#include "oscillator_adapter.hpp"

namespace harness {

struct Series {
  std::vector<double> t, x1, v1, force;
};

inline std::string source(const std::string& rel) { return std::string(SOURCE_DIR) + "/" + rel; }
inline std::string bin(const std::string& name) { return std::string(BIN_DIR) + "/" + name; }

inline master::Config oscillator_config(std::vector<std::string> overrides) {
  return master::load_config(source("configs/oscillator.yaml"), overrides);
}

class Collector final : public master::Observer {
 public:
  Series s;
  void on_start(const master::RunSetup& setup) override {
    s.t.push_back(cosim::to_seconds(setup.config->t_start));
    push(setup.participants.at("mass1").initial_outputs, setup.participants.at("mass2").initial_outputs);
  }
  void on_step(const master::StepRecord& r) override {
    s.t.push_back(cosim::to_seconds(r.t_end));
    push(r.outputs.at("mass1"), r.outputs.at("mass2"));
  }

 private:
  void push(const cosim::Signals& a, const cosim::Signals& b) {
    s.x1.push_back(a.at("x").value[0]);
    s.v1.push_back(a.at("v").value[0]);
    s.force.push_back(b.at("force").value[0]);
  }
};

inline Series run_in_process(const master::Config& config) {
  oscillator::OscillatorAdapter m1(oscillator::Side::Mass1), m2(oscillator::Side::Mass2);
  cosim::ParticipantCore c1("mass1", m1), c2("mass2", m2);
  auto transport = cosim::make_in_process_transport(1234, {{"mass1", &c1}, {"mass2", &c2}});
  master::CoSimulation sim(config, *transport);
  Collector col;
  sim.add_observer(&col);
  sim.connect();
  sim.run();
  return col.s;
}

// Largest |x1 - x1_exact| over the macro time points.
inline double max_error(const master::Config& config, const Series& s) {
  oscillator::Parameters p;
  double e = 0;
  for (std::size_t i = 0; i < s.t.size(); ++i)
    e = std::max(e, std::abs(s.x1[i] - oscillator::monolithic_solution(p, s.t[i])(0)));
  return e;
}

// A UDP port of its own for each test, so tests running in parallel never hear each other.
inline std::string bus_url() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string name = std::string(info->test_suite_name()) + "." + info->name();
  const unsigned port = 20000 + static_cast<unsigned>(std::hash<std::string>{}(name) % 20000);
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0";
}

struct Process {
  pid_t pid = -1;
  std::string log;
};

inline Process spawn(const std::vector<std::string>& args, const std::string& log) {
  Process p;
  p.log = log;
  p.pid = fork();
  if (p.pid == 0) {
    FILE* f = std::fopen(log.c_str(), "w");
    if (f) {
      dup2(fileno(f), 1);
      dup2(fileno(f), 2);
    }
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return p;
}

// Waits for the process; returns its exit code (128 + signal if killed, -1 on timeout).
inline int wait_for(Process& p, double timeout_s) {
  const cosim::Stopwatch waited;
  while (waited.seconds() < timeout_s) {
    int status = 0;
    if (waitpid(p.pid, &status, WNOHANG) == p.pid) {
      p.pid = -1;
      return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  kill(p.pid, SIGKILL);
  waitpid(p.pid, nullptr, 0);
  p.pid = -1;
  return -1;
}

inline std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline std::string temp_path(const std::string& suffix) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = std::string(info->test_suite_name()) + "_" + info->name();
  for (auto& c : name)
    if (c == '/') c = '_';
  return std::string(TEST_TMP_DIR) + "/" + name + suffix;
}

// Runs cosim_master with the given overrides (the bus URL is added); returns its exit code.
inline int run_master(const std::vector<std::string>& overrides, const std::string& h5,
                      double timeout_s = 120, const std::string& config = "configs/oscillator.yaml") {
  std::vector<std::string> args{bin("cosim_master"), source(config), "--output", h5,
                                "--set", "bus.url=" + bus_url(), "--set", "output.csv=",
                                "--set", "output.progress=off"};
  for (const auto& o : overrides) args.insert(args.end(), {"--set", o});
  Process p = spawn(args, h5 + ".log");
  return wait_for(p, timeout_s);
}

inline std::vector<double> read_dataset(const std::string& file, const std::string& name) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  std::vector<double> out;
  hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return out;
  hid_t d = H5Dopen2(f, name.c_str(), H5P_DEFAULT);
  if (d >= 0) {
    hid_t s = H5Dget_space(d);
    out.resize(static_cast<std::size_t>(H5Sget_simple_extent_npoints(s)));
    if (!out.empty()) H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data());
    H5Sclose(s);
    H5Dclose(d);
  }
  H5Fclose(f);
  return out;
}

inline std::string read_string(const std::string& file, const std::string& name) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  std::string out;
  hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return out;
  hid_t d = H5Dopen2(f, name.c_str(), H5P_DEFAULT);
  if (d >= 0) {
    hid_t t = H5Dget_type(d);
    out.resize(H5Tget_size(t));
    hid_t mt = H5Tcopy(H5T_C_S1);
    H5Tset_size(mt, out.size());
    H5Dread(d, mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data());
    H5Tclose(mt);
    H5Tclose(t);
    H5Dclose(d);
  }
  H5Fclose(f);
  return out;
}

}  // namespace harness
