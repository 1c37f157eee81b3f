// cosim_master CONFIG.yaml [--set dotted.key=value ...] [--output FILE.h5] [--csv FILE.csv]
// cosim_master --new-key FILE   (writes a new shared key, mode 600; docs/security.md)
// --record FILE: the session's bus messages as an LCM log; --replay LOG --replay-side NAME:
// rerun NAME live against the recorded messages of the others (docs/replay.md).
// cosim_master --resume FILE.h5 [--set key=value ...] [--csv FILE.csv]
//   continues a stopped run from its last checkpoint, appending to FILE.h5
//   (docs/protocol.md#checkpoints-and-resume)
// The bus key comes from $COSIM_KEY_FILE or $COSIM_KEY, never from the command line; the
// participants the master launches inherit it.
// Exit codes: 0 finished, 1 the run failed (participant lost, refused or failed a step),
// 2 the configuration was refused before any step, 130 / 143 interrupted by SIGINT / SIGTERM
// (the step under way is abandoned, /status says "stopped: interrupted", participants are
// told to stop).
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>

#include <signal.h>

#include <csignal>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <new>

#include <cosim/auth.hpp>
#include <cosim/bus.hpp>
#include <cosim/files.hpp>
#include <cosim/sealed_bus.hpp>

#include "bus_log.hpp"
#include "config.hpp"
#include "cosimulation.hpp"
#include "launcher.hpp"
#include "recorder.hpp"
#include "replay.hpp"
#include "resume.hpp"

namespace {

volatile std::sig_atomic_t g_stop_signal = 0;
void on_stop_signal(int signal) { g_stop_signal = signal; }

void usage() {
  std::cerr << "usage: cosim_master CONFIG.yaml [--set dotted.key=value ...] [--output FILE.h5] [--csv FILE.csv]\n"
               "                    [--record FILE.lcmlog] [--replay LOG --replay-side NAME ...]\n"
               "  --set     override a config value, e.g. --set time.macro_step=5e-4 --set predictors.force.order=1\n"
               "  --output  HDF5 file to record to (overrides output.file)\n"
               "  --csv     CSV export of every participant output (overrides output.csv)\n"
               "  --record  write every message of the run's session to FILE.lcmlog in LCM's log format\n"
               "            (lcm-logplayer plays it; docs/replay.md)\n"
               "  --replay LOG --replay-side NAME [--replay-side NAME2 ...] [--replay-session HEX]\n"
               "            rerun NAME live against the recorded replies of every other participant\n"
               "            (not started); reports where the run diverges from the recording; the\n"
               "            session only when LOG holds several runs (lcm-logger)\n"
               "       cosim_master --resume FILE.h5 [--set key=value ...] [--csv FILE.csv]\n"
               "  --resume  continue the stopped run recorded in FILE.h5 from its last checkpoint\n"
               "            (its config had checkpoints.every; restart participants started by hand\n"
               "            first, where they ran). FILE.h5 is continued in place; --set only for\n"
               "            bus.url, connect_timeout, output.progress, participants.<name>.launch,\n"
               "            .timeout, .retries\n"
               "       cosim_master --new-key FILE\n"
               "  --new-key write a new random key for the bus to FILE (mode 600; an existing file is\n"
               "            not overwritten); give it to every process of a run as COSIM_KEY_FILE=FILE\n"
               "The bus key comes from $COSIM_KEY_FILE (a file only its owner can read) or $COSIM_KEY,\n"
               "never from the command line; participants the master launches inherit it.\n"
               "See docs/config.md for the config keys, docs/output.md for the recorded layout,\n"
               "docs/security.md for the key and docs/replay.md for recording and replay.\n";
}

// Writes a new key to `path`, readable by its owner only; refuses an existing file.
int write_new_key(const std::string& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    if (errno == EEXIST)
      std::cerr << "cosim_master: --new-key: '" << path
                << "' exists; a key file is never overwritten (remove it first if you mean to "
                   "replace the key: every process of a run needs the new one)\n";
    else
      std::cerr << "cosim_master: --new-key: cannot create '" << path << "': " << std::strerror(errno) << "\n";
    return 2;
  }
  const std::string text = cosim::auth::new_key_hex() + "\n";
  const bool ok = ::fchmod(fd, 0600) == 0 &&  // whatever the umask left
                  ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size()) &&
                  ::fsync(fd) == 0;
  const int err = errno;
  ::close(fd);
  if (!ok) {
    ::unlink(path.c_str());
    std::cerr << "cosim_master: --new-key: cannot write '" << path << "': " << std::strerror(err) << "\n";
    return 2;
  }
  std::cerr << "cosim_master: wrote a new key to " << path
            << " (mode 600). Give every process of a run the same key: export COSIM_KEY_FILE=" << path
            << " (copy the file to the other hosts over a trusted channel, e.g. scp)\n";
  return 0;
}

// Outputs that are the same file as each other or as an input are refused before anything
// starts (docs/output.md#file-safety). The inputs: the config file and every launch argument
// that names an existing file (a participant's config, its program).
void check_files(const master::Config& c, const std::string& config_path, bool output_option,
                 bool csv_option, const std::string& record, const std::string& replay_log) {
  std::vector<cosim::NamedFile> inputs{{"the config file", config_path}, {"--replay", replay_log}};
  for (const auto& p : c.participants)
    for (std::size_t i = 0; i < p.launch.size(); ++i) {
      std::error_code ec;
      if (std::filesystem::is_regular_file(p.launch[i], ec))
        inputs.push_back({"participants." + p.name + ".launch[" + std::to_string(i) + "]", p.launch[i]});
    }
  cosim::check_output_files({{output_option ? "--output" : "output.file", c.output.file},
                             {csv_option ? "--csv" : "output.csv", c.output.csv_file},
                             {"--record", record}},
                            inputs);
}

}  // namespace

int main(int argc, char** argv) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  std::string config_path, output, csv, resume;
  std::vector<std::string> overrides;
  std::string record;                    // --record
  master::replay::Options replay_options;  // --replay, --replay-side, --replay-session
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
    else if (a == "--new-key") return write_new_key(value());
    else if (a == "--record") record = value();
    else if (a == "--resume") resume = value();
    else if (a == "--replay") replay_options.log = value();
    else if (a == "--replay-side") replay_options.live.push_back(value());
    else if (a == "--replay-session") {
      const std::string v = value();
      try {
        replay_options.session = cosim::parse_id_hex(v);
      } catch (const std::invalid_argument& e) {
        std::cerr << "cosim_master: --replay-session: " << e.what() << "\n";
        return 2;
      }
    }
    else if (a == "-h" || a == "--help") { usage(); return 0; }
    else if (!a.empty() && a[0] == '-') { std::cerr << "cosim_master: unknown option " << a << "\n"; usage(); return 2; }
    else if (config_path.empty()) config_path = a;
    else { std::cerr << "cosim_master: more than one config file given\n"; usage(); return 2; }
  }
  if (!resume.empty() && (!config_path.empty() || !output.empty())) {
    std::cerr << "cosim_master: --resume takes the config from the record and continues that file: "
                 "give neither a config file nor --output with it\n";
    return 2;
  }
  if (!resume.empty() && !replay_options.log.empty()) {
    std::cerr << "cosim_master: --resume and --replay do not combine: resume the run, then replay its "
                 "recorded sessions one by one\n";
    return 2;
  }
  if (config_path.empty() && resume.empty()) { usage(); return 2; }
  const bool replaying = !replay_options.log.empty();
  if (!replaying && (!replay_options.live.empty() || replay_options.session != 0)) {
    std::cerr << "cosim_master: --replay-side and --replay-session need --replay LOG\n";
    return 2;
  }
  if (replaying && replay_options.live.empty()) {
    std::cerr << "cosim_master: --replay needs --replay-side NAME: the participant to rerun live (every other "
                 "one is played from the log)\n";
    return 2;
  }

  master::Config config;
  master::ResumeRecord resume_record;
  int64_t run_id = 0;
  std::string checkpoint_folder;
  std::vector<std::unique_ptr<cosim::OutputLock>> output_locks;  // one writer per output file
  try {
    if (!resume.empty()) {
      resume_record = master::read_resume_record(resume);
      config = master::resume_config(resume_record, overrides);
      config.output.file = resume;
      config.output.csv_file = csv.empty() ? resume_record.csv : csv;
      run_id = resume_record.run_id;
      checkpoint_folder = resume_record.folder;
    } else {
      config = master::load_config(config_path, overrides);
      if (!output.empty()) config.output.file = output;
      if (!csv.empty()) config.output.csv_file = csv;
      if (config.checkpoints.every > cosim::Duration::zero()) {
        if (config.output.file.empty())
          throw cosim::config::ConfigError(
              "checkpoints.every: needs output.file (or --output): a stopped run is resumed from "
              "its record");
        run_id = cosim::new_session_id();
        // An absolute path: the participants may run in other folders (or on other hosts).
        checkpoint_folder = std::filesystem::absolute(config.checkpoints.folder.empty()
                                                          ? config.output.file + ".checkpoints"
                                                          : config.checkpoints.folder)
                                .lexically_normal()
                                .string();
      }
    }
    check_files(config, config_path, !output.empty() || !resume.empty(), !csv.empty(), record,
                replay_options.log);
    output_locks = cosim::lock_outputs({{output.empty() && resume.empty() ? "output.file" : "--output", config.output.file},
                                        {csv.empty() ? "output.csv" : "--csv", config.output.csv_file},
                                        {"--record", record}}, "cosim_master", std::cerr);
  } catch (const std::exception& e) {  // ConfigError, and anything a malformed file raises
    std::cerr << "cosim_master: config refused: " << e.what() << "\n";
    return 2;
  }
  const std::string url = cosim::resolve_bus_url(config.bus_url);
  std::optional<cosim::auth::Key> key;
  try {
    key = cosim::auth::key_from_environment();
  } catch (const cosim::auth::AuthError& e) {
    std::cerr << "cosim_master: bus key refused: " << e.what() << "\n";
    return 2;
  }

  std::optional<master::replay::Recording> recording;  // --replay: the log, checked
  if (replaying) {
    try {
      recording = master::replay::load(replay_options, config, key);
    } catch (const std::exception& e) {  // ReplayError, LogError
      std::cerr << "cosim_master: replay refused: " << e.what() << "\n";
      return 2;
    }
  }
  auto played = [&](const std::string& name) { return recording && recording->played_side(name); };

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
  std::unique_ptr<cosim::Transport> transport;
  std::unique_ptr<master::BusRecorder> bus_recorder;  // --record
  master::replay::ReplayTransport* replay = nullptr;  // --replay: inside `transport`
  // --record: the log ends with the run's status, also when the run never started.
  auto close_recording = [&](const std::string& status) {
    if (bus_recorder) bus_recorder->finish(status);
  };
  // After a failure: how to continue, if a checkpoint was recorded.
  auto resume_hint = [&] {
    if (!recorder || !recorder->started() || run_id == 0) return;
    const int64_t n = recorder->checkpoint_steps();
    if (n > 0)
      std::cerr << "cosim_master: to continue from the last checkpoint (after " << n << " steps, t = "
                << cosim::to_seconds(config.t_start + n * config.macro_step)
                << " s): restart the participants started by hand, then cosim_master --resume "
                << config.output.file << "\n";
    else
      std::cerr << "cosim_master: no checkpoint was completed yet, so the run cannot be resumed\n";
  };
  // The messages dropped (forged, replayed, ...) also when the run fails.
  auto print_auth = [&] {
    if (!transport) return;
    const auto& a = transport->stats().auth;
    if (a.counts.rejected() > 0 || a.unreadable > 0) std::cerr << "cosim_master: " << cosim::auth_summary(a) << "\n";
  };
  try {
    transport = cosim::make_lcm_transport(url, cosim::new_session_id(), [&] {
      std::map<std::string, cosim::LinkSettings> links;
      for (const auto& p : config.participants) {
        if (played(p.name)) continue;  // answered from the log
        links[p.name] = p.link;
        links[p.name].launched = !p.launch.empty();
      }
      return links;
    }(), key);
    transport->set_fault_plan(config.faults);
    transport->set_liveness_check([&] {
      if (g_stop_signal) throw cosim::Interrupted(g_stop_signal);
      launcher.check();
      if (bus_recorder) bus_recorder->poll();
    });
    if (!record.empty()) {
      bus_recorder = std::make_unique<master::BusRecorder>(record, url, transport->session(), key,
                                                           config.effective_yaml);
      std::cerr << "cosim_master: recording the bus (session " << cosim::id_hex(transport->session()) << ") to "
                << record << " (LCM log: lcm-logplayer plays it, --replay replays it)\n";
    }
    if (recording) {
      auto r = std::make_unique<master::replay::ReplayTransport>(std::move(transport), *recording);
      replay = r.get();
      transport = std::move(r);
      std::string live;
      for (const auto& n : recording->live) live += (live.empty() ? "" : ", ") + n;
      std::string played_names;
      for (const auto& n : recording->played) played_names += (played_names.empty() ? "" : ", ") + n;
      std::cerr << "cosim_master: replaying " << played_names << " from " << recording->path << " (session "
                << cosim::id_hex(recording->session) << ", " << recording->events << " events"
                << (recording->keyed ? ", sealed: each checked with the key" : "")
                << (recording->complete ? ", complete: end record and digest checked" : "") << "); " << live
                << " run" << (recording->live.size() == 1 ? "s" : "") << " live\n";
      for (const auto& note : recording->notes) std::cerr << "cosim_master: replay: " << note << "\n";
    }
    for (const auto& p : config.participants)
      if (!p.launch.empty() && !played(p.name)) launcher.start(p, url, transport->session());

    master::CoSimulation sim(config, *transport);
    if (run_id != 0) sim.set_checkpoints(run_id, checkpoint_folder);
    if (!resume.empty()) {
      sim.set_resume(master::read_resume_point(resume_record, config));
      std::cerr << "cosim_master: resuming " << resume << " after " << resume_record.steps_done << " of "
                << (config.t_end - config.t_start) / config.macro_step << " steps (t = "
                << cosim::to_seconds(config.t_start + resume_record.steps_done * config.macro_step)
                << " s; it had recorded " << resume_record.steps_recorded << ", status '"
                << resume_record.status << "'); participants restore their checkpoints from "
                << checkpoint_folder << "\n";
    }
    std::cerr << "cosim_master: session " << std::hex << transport->session() << std::dec << " on " << url
              << ", waiting for " << config.participants.size() << " participant(s)\n";
    if (key)
      std::cerr << "cosim_master: bus authenticated: every message sealed with the key from "
                << (std::getenv("COSIM_KEY_FILE") && *std::getenv("COSIM_KEY_FILE") ? "$COSIM_KEY_FILE" : "$COSIM_KEY")
                << "; messages without it are dropped\n";
    else
      std::cerr << "cosim_master: bus not authenticated (no $COSIM_KEY_FILE or $COSIM_KEY): any process "
                   "that reaches it can forge messages (docs/security.md)\n";
    try {
      sim.connect();
    } catch (const cosim::ParticipantConfigError& e) {
      transport->terminate(true, e.what());
      close_recording(std::string("stopped: ") + e.what());
      std::cerr << "cosim_master: config refused: participants." << e.participant() << ".parameters: " << e.what() << "\n";
      return 2;
    } catch (const cosim::config::ConfigError& e) {
      transport->terminate(true, e.what());
      close_recording(std::string("stopped: ") + e.what());
      std::cerr << "cosim_master: config refused: " << e.what() << "\n";
      return 2;
    } catch (const cosim::LinkError& e) {
      transport->terminate(true, e.what());  // participants that joined leave at once
      throw;
    }
    for (const auto& [name, sends] : transport->stats().configure_sends)
      if (sends > 1)
        std::cerr << "cosim_master: the configuration of '" << name << "' went out " << sends
                  << " times before it answered (a copy was lost, or it took long to configure)\n";

    if (!resume.empty())
      recorder = std::make_unique<master::H5Recorder>(master::H5Recorder::Continue{}, config.output.file);
    else if (!config.output.file.empty())
      recorder = std::make_unique<master::H5Recorder>(config.output.file);
    if (!config.output.csv_file.empty()) {
      csv_writer = std::make_unique<master::CsvWriter>(config.output.csv_file);
      if (!resume.empty()) csv_writer->continue_from(config.output.file);
    }
    const bool live = config.output.progress == "on" || (config.output.progress == "auto" && isatty(STDERR_FILENO));
    master::Progress progress(live);
    if (recorder) sim.add_observer(recorder.get());
    if (csv_writer) sim.add_observer(csv_writer.get());
    sim.add_observer(&progress);
    // After the HDF5 recorder: closes the bus log and adds /bus/recording and /replay.
    master::replay::RunNotes notes(recorder ? config.output.file : "", bus_recorder.get(),
                                   recording ? &*recording : nullptr, replay);
    sim.add_observer(&notes);

    sim.run();
    const auto& st = transport->stats();
    std::cerr << "cosim_master: " << st.resends << " request(s) resent, " << st.dropped_by_plan
              << " dropped by the fault plan, " << st.ignored_replies << " stale replies ignored\n";
    if (const std::string a = cosim::auth_summary(st.auth); !a.empty()) std::cerr << "cosim_master: " << a << "\n";
    if (recorder) std::cerr << "cosim_master: recorded to " << config.output.file << "\n";
    launcher.stop(5.0);
    return 0;
  } catch (const cosim::Interrupted& e) {
    close_recording("stopped: interrupted");
    print_auth();
    std::cerr << "cosim_master: interrupted by " << (e.signal() == SIGINT ? "SIGINT" : "SIGTERM")
              << ": the step under way was abandoned and the participants told to stop\n";
    if (recorder && recorder->started())
      std::cerr << "cosim_master: the steps completed so far are in " << config.output.file
                << " (/status: stopped: interrupted)\n";
    else if (!config.output.file.empty())
      std::cerr << "cosim_master: no step was recorded; " << config.output.file << " was not written\n";
    resume_hint();
    launcher.stop(2.0);
    return 128 + e.signal();
  } catch (const cosim::LinkError& e) {
    close_recording(std::string("stopped: ") + e.what());
    std::cerr << "cosim_master: run failed: " << e.what() << "\n";
    print_auth();
    if (recorder && recorder->started())
      std::cerr << "cosim_master: the steps completed so far are in " << config.output.file << "\n";
    else if (!config.output.file.empty())
      std::cerr << "cosim_master: no step was recorded; " << config.output.file << " was not written\n";
    resume_hint();
    return 1;
  } catch (const cosim::config::ConfigError& e) {
    std::cerr << "cosim_master: config refused: " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    close_recording("stopped: out of memory");
    std::cerr << "cosim_master: out of memory (std::bad_alloc): the run is stopped; run it where more "
                 "memory is free, or with fewer or shorter outputs\n";
    return 1;
  } catch (const std::exception& e) {
    close_recording(std::string("stopped: ") + e.what());
    std::cerr << "cosim_master: error: " << e.what() << "\n";
    return 1;
  }
}
