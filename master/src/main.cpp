// cosim_master CONFIG.yaml [--set dotted.key=value ...] [--output FILE.h5] [--csv FILE.csv]
// cosim_master --new-key FILE   (writes a new shared key, mode 600; docs/security.md)
// --record FILE: the session's bus messages as an LCM log; --replay LOG --replay-side NAME:
// rerun NAME live against the recorded messages of the others (docs/replay.md).
// cosim_master --resume FILE.h5 [--set key=value ...] [--csv FILE.csv]
//   continues a stopped run from its last checkpoint, appending to FILE.h5
//   (docs/protocol.md#checkpoints-and-resume)
// The bus key comes from $COSIM_KEY_FILE or $COSIM_KEY, never from the command line; the
// participants the master launches inherit it. Without one, a run whose participants are all
// launched gets a fresh key (run_key.hpp); bus.authenticate: false for an unkeyed bus.
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
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <new>
#include <optional>

#include <cosim/auth.hpp>
#include <cosim/bus.hpp>
#include <cosim/files.hpp>
#include <cosim/sealed_bus.hpp>

#include "bus_check.hpp"
#include "bus_log.hpp"
#include "config.hpp"
#include "cosimulation.hpp"
#include "launcher.hpp"
#include "recorder.hpp"
#include "replay.hpp"
#include "resume.hpp"
#include "run_key.hpp"

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
               "never from the command line; participants the master launches inherit it. Without one, a\n"
               "run whose participants the master launches all gets a fresh key of its own; one with\n"
               "participants started by hand needs a key, or bus.authenticate: false for an unkeyed bus.\n"
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

// Ends the program with `code` from wherever it is raised (a refused command line or config).
struct Exit {
  int code;
};

// The command line.
struct Options {
  std::string config_path, output, csv, resume;
  std::vector<std::string> overrides;
  std::string record;                   // --record
  master::replay::Options replay;       // --replay, --replay-side, --replay-session
  bool replaying() const { return !replay.log.empty(); }
};

// One option and its value; raises Exit for a command line that cannot be run.
void parse_option(Options& o, const std::string& a, const std::function<std::string()>& value) {
  if (a == "--set") o.overrides.push_back(value());
  else if (a == "--output") o.output = value();
  else if (a == "--csv") o.csv = value();
  else if (a == "--new-key") throw Exit{write_new_key(value())};
  else if (a == "--record") o.record = value();
  else if (a == "--resume") o.resume = value();
  else if (a == "--replay") o.replay.log = value();
  else if (a == "--replay-side") o.replay.live.push_back(value());
  else if (a == "--replay-session") {
    const std::string v = value();
    try {
      o.replay.session = cosim::parse_id_hex(v);
    } catch (const std::invalid_argument& e) {
      std::cerr << "cosim_master: --replay-session: " << e.what() << "\n";
      throw Exit{2};
    }
  }
  else if (a == "-h" || a == "--help") { usage(); throw Exit{0}; }
  else if (!a.empty() && a[0] == '-') { std::cerr << "cosim_master: unknown option " << a << "\n"; usage(); throw Exit{2}; }
  else if (o.config_path.empty()) o.config_path = a;
  else { std::cerr << "cosim_master: more than one config file given\n"; usage(); throw Exit{2}; }
}

// Options that do not combine, or need one another.
void check_options(const Options& o) {
  auto refuse = [](const char* text) {
    std::cerr << "cosim_master: " << text << "\n";
    throw Exit{2};
  };
  if (!o.resume.empty() && (!o.config_path.empty() || !o.output.empty()))
    refuse("--resume takes the config from the record and continues that file: give neither a config "
           "file nor --output with it");
  if (!o.resume.empty() && o.replaying())
    refuse("--resume and --replay do not combine: resume the run, then replay its recorded sessions one by one");
  if (o.config_path.empty() && o.resume.empty()) { usage(); throw Exit{2}; }
  if (!o.replaying() && (!o.replay.live.empty() || o.replay.session != 0))
    refuse("--replay-side and --replay-session need --replay LOG");
  if (o.replaying() && o.replay.live.empty())
    refuse("--replay needs --replay-side NAME: the participant to rerun live (every other one is played "
           "from the log)");
}

Options parse_command_line(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    parse_option(o, a, [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "cosim_master: " << a << " needs a value\n";
        usage();
        throw Exit{2};
      }
      return argv[++i];
    });
  }
  check_options(o);
  return o;
}

// One run of cosim_master: the config, the bus, the participants, the records, the steps.
class Application {
 public:
  explicit Application(Options options) : o_(std::move(options)) {}
  ~Application() {
    if (key_fd_ >= 0) ::close(key_fd_);
  }
  int run();

 private:
  void load_config();
  void load_new_config();
  void choose_key();
  void load_replay();
  void install_signal_handlers();
  void open_bus();
  void start_participants();
  bool played(const std::string& name) const { return recording_ && recording_->played_side(name); }
  std::map<std::string, cosim::LinkSettings> links() const;
  void print_replay_banner() const;
  void announce_run(const master::CoSimulation& sim) const;
  // The handshake; returns an exit code when the config is refused by a participant.
  std::optional<int> connect(master::CoSimulation& sim);
  void open_records(master::CoSimulation& sim);
  int steps(master::CoSimulation& sim);
  int finished();
  int interrupted(const cosim::Interrupted& e);
  int failed(const cosim::LinkError& e);
  void close_recording(const std::string& status) {
    if (bus_recorder_) bus_recorder_->finish(status);
  }
  void print_auth() const;
  void print_where_steps_are() const;
  void resume_hint() const;

  Options o_;
  master::Config config_;
  master::ResumeRecord resume_record_;
  int64_t run_id_ = 0;
  std::string checkpoint_folder_;
  std::string url_;
  master::RunKey key_;
  int key_fd_ = -1;  // a fresh key as an unnamed file, for the launched participants
  std::optional<master::replay::Recording> recording_;  // --replay: the log, checked
  master::Launcher launcher_;
  // Created once the participants are connected; each replaces a file of its name only when
  // the run starts writing it.
  std::unique_ptr<master::H5Recorder> recorder_;
  std::unique_ptr<master::CsvWriter> csv_writer_;
  std::unique_ptr<master::Progress> progress_;
  std::unique_ptr<master::replay::RunNotes> notes_;
  std::unique_ptr<cosim::Transport> transport_;
  std::unique_ptr<master::BusRecorder> bus_recorder_;  // --record
  master::replay::ReplayTransport* replay_ = nullptr;  // --replay: inside `transport_`
  std::vector<std::unique_ptr<cosim::OutputLock>> output_locks_;  // one writer per output file
};

// The config (a new run's, or the record's for --resume) and the checkpoints' run id and
// folder; raises on a config that cannot run.
void Application::load_config() {
  if (o_.resume.empty()) {
    load_new_config();
  } else {
    resume_record_ = master::read_resume_record(o_.resume);
    config_ = master::resume_config(resume_record_, o_.overrides);
    config_.output.file = o_.resume;
    config_.output.csv_file = o_.csv.empty() ? resume_record_.csv : o_.csv;
    run_id_ = resume_record_.run_id;
    checkpoint_folder_ = resume_record_.folder;
  }
  check_files(config_, o_.config_path, !o_.output.empty() || !o_.resume.empty(), !o_.csv.empty(), o_.record,
              o_.replay.log);
  output_locks_ = cosim::lock_outputs(
      {{o_.output.empty() && o_.resume.empty() ? "output.file" : "--output", config_.output.file},
       {o_.csv.empty() ? "output.csv" : "--csv", config_.output.csv_file},
       {"--record", o_.record}},
      "cosim_master", std::cerr);
}

void Application::load_new_config() {
  config_ = master::load_config(o_.config_path, o_.overrides);
  if (!o_.output.empty()) config_.output.file = o_.output;
  if (!o_.csv.empty()) config_.output.csv_file = o_.csv;
  if (config_.checkpoints.every <= cosim::Duration::zero()) return;
  if (config_.output.file.empty())
    throw cosim::config::ConfigError(
        "checkpoints.every: needs output.file (or --output): a stopped run is resumed from its record");
  run_id_ = cosim::new_session_id();
  // An absolute path: the participants may run in other folders (or on other hosts).
  checkpoint_folder_ = std::filesystem::absolute(config_.checkpoints.folder.empty()
                                                     ? config_.output.file + ".checkpoints"
                                                     : config_.checkpoints.folder)
                           .lexically_normal()
                           .string();
}

// The key from the environment (or the replayed log's); the rest is settled once the replay
// says which participants are played (choose_key after load_replay).
void Application::choose_key() {
  master::settle_run_key(key_, config_, master::hand_started(config_, [&](const std::string& n) { return played(n); }));
  // A key from the environment reaches the launched participants with it; any other one as an
  // unnamed file they inherit.
  if (!key_.key || key_.source == master::RunKey::Source::environment) return;
  key_fd_ = master::key_as_unnamed_file(*key_.key);
  launcher_.share_key(key_fd_);
  if (key_.source != master::RunKey::Source::per_run) return;
  if (o_.record.empty()) return;
  // The log is sealed with this key: keep it beside the log, readable by its owner only, so
  // that --replay can check the log later.
  master::save_key_file(*key_.key, o_.record + ".key");
}

void Application::load_replay() {
  if (!o_.replaying()) return;
  recording_ = master::replay::load(o_.replay, config_, key_.key);
}

void Application::install_signal_handlers() {
  std::signal(SIGPIPE, SIG_IGN);
  // No SA_RESTART: a wait on the bus returns at once and the run stops (exit 128 + signal).
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

std::map<std::string, cosim::LinkSettings> Application::links() const {
  std::map<std::string, cosim::LinkSettings> links;
  for (const auto& p : config_.participants) {
    if (played(p.name)) continue;  // answered from the log
    links[p.name] = p.link;
    links[p.name].launched = !p.launch.empty();
  }
  return links;
}

// The transport (wrapped by the replay's when replaying) and the bus recorder.
void Application::open_bus() {
  master::check_bus_can_bind(url_);
  transport_ = cosim::make_lcm_transport(url_, cosim::new_session_id(), links(), key_.key);
  transport_->set_fault_plan(config_.faults);
  transport_->set_liveness_check([this] {
    if (g_stop_signal) throw cosim::Interrupted(g_stop_signal);
    launcher_.check();
    if (bus_recorder_) bus_recorder_->poll();
  });
  if (!o_.record.empty()) {
    bus_recorder_ = std::make_unique<master::BusRecorder>(o_.record, url_, transport_->session(), key_.key,
                                                          config_.effective_yaml);
    std::cerr << "cosim_master: recording the bus (session " << cosim::id_hex(transport_->session()) << ") to "
              << o_.record << " (LCM log: lcm-logplayer plays it, --replay replays it)\n";
    if (key_.source == master::RunKey::Source::per_run)
      std::cerr << "cosim_master: the log is sealed with this run's key, kept in " << o_.record
                << ".key (mode 600), where --replay finds it\n";
  }
  if (!recording_) return;
  auto r = std::make_unique<master::replay::ReplayTransport>(std::move(transport_), *recording_);
  replay_ = r.get();
  transport_ = std::move(r);
  print_replay_banner();
}

void Application::print_replay_banner() const {
  const auto& rec = *recording_;
  std::string live, played_names;
  for (const auto& n : rec.live) live += (live.empty() ? "" : ", ") + n;
  for (const auto& n : rec.played) played_names += (played_names.empty() ? "" : ", ") + n;
  std::cerr << "cosim_master: replaying " << played_names << " from " << rec.path << " (session "
            << cosim::id_hex(rec.session) << ", " << rec.events << " events"
            << (rec.keyed ? ", sealed: each checked with the key" : "")
            << (rec.complete ? ", complete: end record and digest checked" : "") << "); " << live << " run"
            << (rec.live.size() == 1 ? "s" : "") << " live\n";
  for (const auto& note : rec.notes) std::cerr << "cosim_master: replay: " << note << "\n";
}

void Application::start_participants() {
  for (const auto& p : config_.participants)  // every program found before any is started
    if (!p.launch.empty() && !played(p.name)) master::Launcher::check_startable(p);
  for (const auto& p : config_.participants)
    if (!p.launch.empty() && !played(p.name)) launcher_.start(p, url_, transport_->session());
}

void Application::announce_run(const master::CoSimulation& sim) const {
  if (!o_.resume.empty())
    std::cerr << "cosim_master: resuming " << o_.resume << " after " << resume_record_.steps_done
              << " steps (t = " << cosim::to_seconds(sim.time_after(resume_record_.steps_done)) << " of "
              << cosim::to_seconds(config_.t_end) << " s; it had recorded " << resume_record_.steps_recorded << ", status '"
              << resume_record_.status << "'); participants restore their checkpoints from "
              << checkpoint_folder_ << "\n";
  std::cerr << "cosim_master: session " << std::hex << transport_->session() << std::dec << " on " << url_
            << ", waiting for " << config_.participants.size() << " participant(s) ("
            << sim.algorithm().name() << ")\n";
  std::cerr << "cosim_master: " << master::describe(key_) << "\n";
}

std::optional<int> Application::connect(master::CoSimulation& sim) {
  try {
    sim.connect();
  } catch (const cosim::ParticipantConfigError& e) {
    transport_->terminate(true, e.what());
    close_recording(std::string("stopped: ") + e.what());
    std::cerr << "cosim_master: config refused: participants." << e.participant() << ".parameters: " << e.what() << "\n";
    return 2;
  } catch (const cosim::config::ConfigError& e) {
    transport_->terminate(true, e.what());
    close_recording(std::string("stopped: ") + e.what());
    std::cerr << "cosim_master: config refused: " << e.what() << "\n";
    return 2;
  } catch (const cosim::LinkError& e) {
    transport_->terminate(true, e.what());  // participants that joined leave at once
    throw;
  }
  launcher_.remove_key_files();  // every participant has joined: an MPI job's key file is read
  for (const auto& [name, sends] : transport_->stats().configure_sends)
    if (sends > 1)
      std::cerr << "cosim_master: the configuration of '" << name << "' went out " << sends
                << " times before it answered (a copy was lost, or it took long to configure)\n";
  return std::nullopt;
}

// The HDF5 record, the CSV, the progress line and the replay's notes, as observers.
void Application::open_records(master::CoSimulation& sim) {
  if (!o_.resume.empty())
    recorder_ = std::make_unique<master::H5Recorder>(master::H5Recorder::Continue{}, config_.output.file);
  else if (!config_.output.file.empty())
    recorder_ = std::make_unique<master::H5Recorder>(config_.output.file);
  if (!config_.output.csv_file.empty()) {
    csv_writer_ = std::make_unique<master::CsvWriter>(config_.output.csv_file);
    if (!o_.resume.empty()) csv_writer_->continue_from(config_.output.file);
  }
  const bool live = config_.output.progress == "on" || (config_.output.progress == "auto" && isatty(STDERR_FILENO));
  progress_ = std::make_unique<master::Progress>(live);
  if (recorder_) sim.add_observer(recorder_.get());
  if (csv_writer_) sim.add_observer(csv_writer_.get());
  // After the HDF5 recorder: closes the bus log and adds /bus/recording and /replay. Before the
  // progress line, which says "finished": a note that cannot be written stops that.
  notes_ = std::make_unique<master::replay::RunNotes>(recorder_ ? config_.output.file : "", bus_recorder_.get(),
                                                      recording_ ? &*recording_ : nullptr, replay_);
  sim.add_observer(notes_.get());
  sim.add_observer(progress_.get());
}

// From the bus to the end of the steps; the failures of the run itself are caught in run().
int Application::steps(master::CoSimulation& sim) {
  if (run_id_ != 0) sim.set_checkpoints(run_id_, checkpoint_folder_);
  if (!o_.resume.empty()) sim.set_resume(master::read_resume_point(resume_record_, config_));
  announce_run(sim);
  if (auto code = connect(sim)) return *code;
  open_records(sim);
  sim.run();
  return finished();
}

int Application::finished() {
  const auto& st = transport_->stats();
  std::cerr << "cosim_master: " << st.resends << " request(s) resent, " << st.dropped_by_plan
            << " dropped by the fault plan, " << st.ignored_replies << " stale replies ignored\n";
  if (const std::string a = cosim::auth_summary(st.auth); !a.empty()) std::cerr << "cosim_master: " << a << "\n";
  if (recorder_) std::cerr << "cosim_master: recorded to " << config_.output.file << "\n";
  launcher_.stop(5.0);
  return 0;
}

// The messages dropped (forged, replayed, ...) also when the run fails.
void Application::print_auth() const {
  if (!transport_) return;
  const auto& a = transport_->stats().auth;
  if (a.counts.rejected() > 0 || a.unreadable > 0) std::cerr << "cosim_master: " << cosim::auth_summary(a) << "\n";
}

void Application::print_where_steps_are() const {
  if (recorder_ && recorder_->started())
    std::cerr << "cosim_master: the steps completed so far are in " << config_.output.file << "\n";
  else if (!config_.output.file.empty())
    std::cerr << "cosim_master: no step was recorded; " << config_.output.file << " was not written\n";
}

// After a failure: how to continue, if a checkpoint was recorded.
void Application::resume_hint() const {
  if (!recorder_ || !recorder_->started() || run_id_ == 0) return;
  const int64_t n = recorder_->checkpoint_steps();
  if (n > 0)
    std::cerr << "cosim_master: to continue from the last checkpoint (after " << n << " steps, t = "
              << cosim::to_seconds(config_.t_start + n * config_.macro_step)
              << " s): restart the participants started by hand, then cosim_master --resume "
              << config_.output.file << "\n";
  else
    std::cerr << "cosim_master: no checkpoint was completed yet, so the run cannot be resumed\n";
}

int Application::interrupted(const cosim::Interrupted& e) {
  close_recording("stopped: interrupted");
  print_auth();
  std::cerr << "cosim_master: interrupted by " << (e.signal() == SIGINT ? "SIGINT" : "SIGTERM")
            << ": the step under way was abandoned and the participants told to stop\n";
  if (recorder_ && recorder_->started())
    std::cerr << "cosim_master: the steps completed so far are in " << config_.output.file
              << " (/status: stopped: interrupted)\n";
  else if (!config_.output.file.empty())
    std::cerr << "cosim_master: no step was recorded; " << config_.output.file << " was not written\n";
  resume_hint();
  launcher_.stop(2.0);
  return 128 + e.signal();
}

int Application::failed(const cosim::LinkError& e) {
  close_recording(std::string("stopped: ") + e.what());
  std::cerr << "cosim_master: run failed: " << e.what() << "\n";
  print_auth();
  print_where_steps_are();
  resume_hint();
  return 1;
}

int Application::run() {
  try {  // ConfigError, and anything a malformed file raises
    load_config();
  } catch (const std::exception& e) {
    std::cerr << "cosim_master: config refused: " << e.what() << "\n";
    return 2;
  }
  url_ = cosim::resolve_bus_url(config_.bus_url);
  try {
    key_ = master::key_from_environment_or_log(o_.replay.log);
  } catch (const cosim::auth::AuthError& e) {
    std::cerr << "cosim_master: bus key refused: " << e.what() << "\n";
    return 2;
  }
  try {
    load_replay();
  } catch (const std::exception& e) {  // ReplayError, LogError
    std::cerr << "cosim_master: replay refused: " << e.what() << "\n";
    return 2;
  }
  try {
    choose_key();
  } catch (const cosim::config::ConfigError& e) {
    std::cerr << "cosim_master: config refused: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cosim_master: bus key: " << e.what() << "\n";
    return 2;
  }
  install_signal_handlers();
  try {
    open_bus();
    start_participants();
    master::CoSimulation sim(config_, *transport_);
    return steps(sim);
  } catch (const cosim::Interrupted& e) {
    return interrupted(e);
  } catch (const cosim::LinkError& e) {
    return failed(e);
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

}  // namespace

int main(int argc, char** argv) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  try {
    Application app(parse_command_line(argc, argv));
    return app.run();
  } catch (const Exit& e) {
    return e.code;
  }
}
