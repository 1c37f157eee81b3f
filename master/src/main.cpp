// cosim_master CONFIG.yaml [--set dotted.key=value ...] [--output FILE.h5] [--csv FILE.csv]
// Exit codes: 0 finished, 1 the run failed (participant lost, refused or failed a step),
// 2 the configuration was refused before any step, 130 / 143 interrupted by SIGINT / SIGTERM
// (the step under way is abandoned, /status says "stopped: interrupted", participants are
// told to stop).
#include <cstdio>
#include <unistd.h>

#include <signal.h>

#include <csignal>
#include <cstring>
#include <filesystem>
#include <iostream>

#include <cosim/bus.hpp>
#include <cosim/files.hpp>

#include "config.hpp"
#include "cosimulation.hpp"
#include "launcher.hpp"
#include "recorder.hpp"

namespace {

volatile std::sig_atomic_t g_stop_signal = 0;
void on_stop_signal(int signal) { g_stop_signal = signal; }

void usage() {
  std::cerr << "usage: cosim_master CONFIG.yaml [--set dotted.key=value ...] [--output FILE.h5] [--csv FILE.csv]\n"
               "  --set     override a config value, e.g. --set time.macro_step=5e-4 --set predictors.force.order=1\n"
               "  --output  HDF5 file to record to (overrides output.file)\n"
               "  --csv     CSV export of every participant output (overrides output.csv)\n"
               "See docs/config.md for the config keys and docs/output.md for the recorded layout.\n";
}

// Outputs that are the same file as each other or as an input are refused before anything
// starts (docs/output.md#file-safety). The inputs: the config file and every launch argument
// that names an existing file (a participant's config, its program).
void check_files(const master::Config& c, const std::string& config_path, bool output_option,
                 bool csv_option) {
  std::vector<cosim::NamedFile> inputs{{"the config file", config_path}};
  for (const auto& p : c.participants)
    for (std::size_t i = 0; i < p.launch.size(); ++i) {
      std::error_code ec;
      if (std::filesystem::is_regular_file(p.launch[i], ec))
        inputs.push_back({"participants." + p.name + ".launch[" + std::to_string(i) + "]", p.launch[i]});
    }
  cosim::check_output_files({{output_option ? "--output" : "output.file", c.output.file},
                             {csv_option ? "--csv" : "output.csv", c.output.csv_file}},
                            inputs);
}

}  // namespace

int main(int argc, char** argv) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  std::string config_path, output, csv;
  std::vector<std::string> overrides;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "cosim_master: " << a << " needs a value\n";
        usage();
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--set") overrides.push_back(value());
    else if (a == "--output") output = value();
    else if (a == "--csv") csv = value();
    else if (a == "-h" || a == "--help") { usage(); return 0; }
    else if (!a.empty() && a[0] == '-') { std::cerr << "cosim_master: unknown option " << a << "\n"; usage(); return 2; }
    else if (config_path.empty()) config_path = a;
    else { std::cerr << "cosim_master: more than one config file given\n"; usage(); return 2; }
  }
  if (config_path.empty()) { usage(); return 2; }

  master::Config config;
  try {
    config = master::load_config(config_path, overrides);
    if (!output.empty()) config.output.file = output;
    if (!csv.empty()) config.output.csv_file = csv;
    check_files(config, config_path, !output.empty(), !csv.empty());
  } catch (const std::exception& e) {  // ConfigError, and anything a malformed file raises
    std::cerr << "cosim_master: config refused: " << e.what() << "\n";
    return 2;
  }
  const std::string url = cosim::resolve_bus_url(config.bus_url);

  std::signal(SIGPIPE, SIG_IGN);
  {  // no SA_RESTART: a wait on the bus returns at once and the run stops (exit 128 + signal)
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
  }
  master::Launcher launcher;
  // Created once the participants are connected; each replaces a file of its name only when
  // the run starts writing it.
  std::unique_ptr<master::H5Recorder> recorder;
  std::unique_ptr<master::CsvWriter> csv_writer;
  try {
    auto transport = cosim::make_lcm_transport(url, cosim::new_session_id(), [&] {
      std::map<std::string, cosim::LinkSettings> links;
      for (const auto& p : config.participants) {
        links[p.name] = p.link;
        links[p.name].launched = !p.launch.empty();
      }
      return links;
    }());
    transport->set_fault_plan(config.faults);
    transport->set_liveness_check([&] {
      if (g_stop_signal) throw cosim::Interrupted(g_stop_signal);
      launcher.check();
    });
    for (const auto& p : config.participants)
      if (!p.launch.empty()) launcher.start(p, url, transport->session());

    master::CoSimulation sim(config, *transport);
    std::cerr << "cosim_master: session " << std::hex << transport->session() << std::dec << " on " << url
              << ", waiting for " << config.participants.size() << " participant(s)\n";
    try {
      sim.connect();
    } catch (const cosim::ParticipantConfigError& e) {
      transport->terminate(true, e.what());
      std::cerr << "cosim_master: config refused: participants." << e.participant() << ".parameters: " << e.what() << "\n";
      return 2;
    } catch (const cosim::config::ConfigError& e) {
      transport->terminate(true, e.what());
      std::cerr << "cosim_master: config refused: " << e.what() << "\n";
      return 2;
    } catch (const cosim::LinkError& e) {
      transport->terminate(true, e.what());  // participants that joined leave at once
      throw;
    }

    if (!config.output.file.empty()) recorder = std::make_unique<master::H5Recorder>(config.output.file);
    if (!config.output.csv_file.empty()) csv_writer = std::make_unique<master::CsvWriter>(config.output.csv_file);
    const bool live = config.output.progress == "on" || (config.output.progress == "auto" && isatty(STDERR_FILENO));
    master::Progress progress(live);
    if (recorder) sim.add_observer(recorder.get());
    if (csv_writer) sim.add_observer(csv_writer.get());
    sim.add_observer(&progress);

    sim.run();
    const auto& st = transport->stats();
    std::cerr << "cosim_master: " << st.resends << " request(s) resent, " << st.dropped_by_plan
              << " dropped by the fault plan, " << st.ignored_replies << " stale replies ignored\n";
    if (recorder) std::cerr << "cosim_master: recorded to " << config.output.file << "\n";
    launcher.stop(5.0);
    return 0;
  } catch (const cosim::Interrupted& e) {
    std::cerr << "cosim_master: interrupted by " << (e.signal() == SIGINT ? "SIGINT" : "SIGTERM")
              << ": the step under way was abandoned and the participants told to stop\n";
    if (recorder && recorder->started())
      std::cerr << "cosim_master: the steps completed so far are in " << config.output.file
                << " (/status: stopped: interrupted)\n";
    else if (!config.output.file.empty())
      std::cerr << "cosim_master: no step was recorded; " << config.output.file << " was not written\n";
    launcher.stop(2.0);
    return 128 + e.signal();
  } catch (const cosim::LinkError& e) {
    std::cerr << "cosim_master: run failed: " << e.what() << "\n";
    if (recorder && recorder->started())
      std::cerr << "cosim_master: the steps completed so far are in " << config.output.file << "\n";
    else if (!config.output.file.empty())
      std::cerr << "cosim_master: no step was recorded; " << config.output.file << " was not written\n";
    return 1;
  } catch (const cosim::config::ConfigError& e) {
    std::cerr << "cosim_master: config refused: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cosim_master: error: " << e.what() << "\n";
    return 1;
  }
}
