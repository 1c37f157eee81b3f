// cosim_master --resume (docs/protocol.md#checkpoints-and-resume): a run whose participant is
// killed (kill -9) or whose master is interrupted (SIGINT) mid-run, continued from its last
// checkpoint with restarted participants, ends with a record whose every dataset is
// bit-identical to an uninterrupted run's, except the run metadata that record_compare.hpp lists. Also the
// refusals of --resume and of the checkpoint keys. Participants are started by hand (as across
// hosts), each test on its own UDP port.
#include <cosim/bus.hpp>
#include <hdf5.h>

#include <filesystem>
#include <regex>

#include "harness.hpp"
#include "record_compare.hpp"
#include "recorder.hpp"
#include "resume.hpp"

namespace fs = std::filesystem;

namespace {

// What differs between two runs of the same config by nature, and nothing else, is left out
// (record_compare::run_metadata: wall times, the bus counters, the resume log). The config,
// every coupling quantity sent, predicted and received, every participant output and
// diagnostic, the deviations, power, energy residuals, iteration counts, /status and
// /checkpoint/steps_done are compared.
using record_compare::Comparison;

Comparison compare_records(const std::string& a, const std::string& b) {
  Comparison c = record_compare::compare(a, b);
  EXPECT_TRUE(c.opened) << a << " or " << b << " cannot be opened";
  return c;
}

// The largest N of the participant's checkpoint files <folder>/<name>_<run>_<N>.ckpt (-1: none).
int64_t latest_checkpoint(const std::string& folder, const std::string& name) {
  int64_t best = -1;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec)) {
    const std::string f = e.path().filename().string();
    std::smatch m;
    if (std::regex_match(f, m, std::regex(name + "_[0-9a-f]{16}_([0-9]+)\\.ckpt")))
      best = std::max<int64_t>(best, std::stoll(m[1]));
  }
  return best;
}

// Polls until `name` has written a checkpoint after at least `steps` steps.
bool wait_for_checkpoint(const std::string& folder, const std::string& name, int64_t steps, double timeout_s) {
  const cosim::Stopwatch w;
  while (w.seconds() < timeout_s) {
    if (latest_checkpoint(folder, name) >= steps) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return false;
}

// --output and --csv are not part of the recorded config (config_effective), so two runs to
// compare may write to different files.
std::vector<std::string> master_args(const std::string& config, const std::string& h5,
                                     const std::vector<std::string>& sets, const std::string& csv = "") {
  std::vector<std::string> a{harness::bin("cosim_master"), harness::source(config), "--output", h5};
  if (!csv.empty()) a.insert(a.end(), {"--csv", csv});
  for (const auto& s : sets) a.insert(a.end(), {"--set", s});
  return a;
}

// ---- the oscillator: both halves save their state ----

struct Oscillator {
  std::string url = harness::bus_url();
  std::string csv_of(const std::string& h5) const { return h5 + ".csv"; }
  std::vector<std::string> sets(const std::string& h5) const {
    return {"bus.url=" + url, "participants.mass1.launch=null", "participants.mass2.launch=null",
            "bus.authenticate=false",
            "participants.mass2.timeout=0.3", "time.end=5", "checkpoints.every=0.05",
            "output.progress=off"};
  }
  std::vector<harness::Process> start(const std::string& log) const {
    std::vector<harness::Process> p;
    for (const char* side : {"mass1", "mass2"})
      p.push_back(harness::spawn({harness::bin("oscillator_adapter"), "--side", side, "--bus", url,
                                  "--wait", "60"},
                                 log + "." + side + ".log"));
    return p;
  }
  // An uninterrupted run: 10000 macro steps, a checkpoint every 100.
  void full(const std::string& h5) const {
    auto parts = start(h5);
    auto master = harness::spawn(master_args("configs/oscillator.yaml", h5, sets(h5), csv_of(h5)), h5 + ".log");
    ASSERT_EQ(harness::wait_for(master, 120), 0) << harness::read_text(h5 + ".log");
    for (auto& p : parts) EXPECT_EQ(harness::wait_for(p, 10), 0);
  }
  int resume(const std::string& h5, const std::string& tag) const {
    auto parts = start(h5 + tag);
    auto master = harness::spawn({harness::bin("cosim_master"), "--resume", h5}, h5 + tag + ".log");
    const int code = harness::wait_for(master, 120);
    // A participant that refused its configuration stays free for another master: stop it.
    if (code != 0)
      for (auto& p : parts) kill(p.pid, SIGTERM);
    for (auto& p : parts) harness::wait_for(p, 10);
    return code;
  }
};

void expect_identical(const std::string& full, const std::string& resumed, int min_compared) {
  const Comparison c = compare_records(full, resumed);
  EXPECT_TRUE(c.differ.empty() && c.missing.empty()) << full << " vs " << resumed << ":\n" << c.text();
  EXPECT_GE(c.compared, min_compared) << "too few datasets compared";
  std::printf("%d datasets bit-identical, %d run metadata skipped\n", c.compared, c.skipped);
}

}  // namespace

TEST(Resume, OscillatorAfterAKilledParticipantEqualsAnUninterruptedRun) {
  const Oscillator osc;
  const std::string full = harness::temp_path("_full.h5"), h5 = harness::temp_path(".h5");
  const std::string folder = h5 + ".checkpoints";
  fs::remove_all(folder);
  osc.full(full);
  ASSERT_FALSE(fs::exists(full + ".checkpoints")) << "a finished run leaves its checkpoints behind";

  auto parts = osc.start(h5);
  auto master = harness::spawn(master_args("configs/oscillator.yaml", h5, osc.sets(h5), osc.csv_of(h5)), h5 + ".log");
  ASSERT_TRUE(wait_for_checkpoint(folder, "mass2", 1000, 60)) << harness::read_text(h5 + ".log");
  kill(parts[1].pid, SIGKILL);
  EXPECT_EQ(harness::wait_for(master, 30), 1);
  EXPECT_EQ(harness::wait_for(parts[0], 10), 1) << "mass1 was not told to stop";
  harness::wait_for(parts[1], 5);
  const std::string log = harness::read_text(h5 + ".log");
  EXPECT_NE(log.find("participant 'mass2' stopped answering"), std::string::npos) << log;
  EXPECT_NE(log.find("then cosim_master --resume " + h5), std::string::npos) << log;
  // The message names the last step mass2 answered, not only a heartbeat that may be older.
  // mass2 writes its checkpoint after step index 999 before it replies to that step, so the
  // kill can fall between the two (seen in CI under load): the last reply is then to step 998,
  // which the master had to receive before it asked for step 999.
  {
    const auto at_reply = log.find("last reply ");
    ASSERT_NE(at_reply, std::string::npos) << log;
    const auto step = log.find("(step ", at_reply);
    ASSERT_NE(step, std::string::npos) << log;
    EXPECT_GE(std::stol(log.substr(step + 6)), 998) << log;
  }
  const double at = harness::read_dataset(h5, "checkpoint/steps_done").at(0);
  const std::size_t rows = harness::read_dataset(h5, "time").size();
  // mass2 had written its checkpoint after 1000 steps or later: the common one (recorded once
  // both confirmed) is that one or the one before.
  EXPECT_GE(at, 900);
  EXPECT_EQ(std::fmod(at, 100.0), 0.0) << "checkpoints.every is 100 macro steps";
  EXPECT_GE(rows, at + 1) << "the record ends before its checkpoint";
  EXPECT_LT(rows, 10001u) << "the run was not interrupted";
  std::printf("mass2 killed after %zu of 10000 steps; last common checkpoint after %.0f\n", rows - 1, at);
  // The comparison does see a difference: the interrupted record is not the full one.
  const std::string before = harness::temp_path("_before_resume.h5");
  fs::copy_file(h5, before, fs::copy_options::overwrite_existing);
  EXPECT_FALSE(compare_records(full, before).differ.empty());

  ASSERT_EQ(osc.resume(h5, ".resume"), 0) << harness::read_text(h5 + ".resume.log");
  EXPECT_NE(harness::read_text(h5 + ".resume.log").find("resuming " + h5 + " after " + std::to_string(static_cast<int>(at))),
            std::string::npos);
  expect_identical(full, h5, 20);
  EXPECT_EQ(harness::read_dataset(h5, "checkpoint/resumed_at"), std::vector<double>{at});
  EXPECT_EQ(harness::read_string(h5, "status"), "finished");
  // The CSV export: the rows before the checkpoint rewritten from the record, then the rest.
  const std::string csv_full = harness::read_text(osc.csv_of(full)), csv = harness::read_text(osc.csv_of(h5));
  EXPECT_GT(csv_full.size(), 100000u);
  EXPECT_TRUE(csv == csv_full) << "the resumed run's CSV differs from the uninterrupted one";
  EXPECT_FALSE(fs::exists(folder)) << "the finished run's checkpoints were not deleted";
}

TEST(Resume, InterruptedMasterResumesAndAMissingCheckpointIsNamed) {
  const Oscillator osc;
  const std::string full = harness::temp_path("_full.h5"), h5 = harness::temp_path(".h5");
  const std::string folder = h5 + ".checkpoints";
  fs::remove_all(folder);
  osc.full(full);

  auto parts = osc.start(h5);
  auto master = harness::spawn(master_args("configs/oscillator.yaml", h5, osc.sets(h5), osc.csv_of(h5)), h5 + ".log");
  ASSERT_TRUE(wait_for_checkpoint(folder, "mass1", 500, 60)) << harness::read_text(h5 + ".log");
  kill(master.pid, SIGINT);
  const cosim::Stopwatch since;
  EXPECT_EQ(harness::wait_for(master, 10), 130);
  for (auto& p : parts) EXPECT_EQ(harness::wait_for(p, 10), 1);
  EXPECT_LT(since.seconds(), 2.0) << "participants still there 2 s after SIGINT on the master";
  EXPECT_EQ(harness::read_string(h5, "status"), "stopped: interrupted");
  const double at = harness::read_dataset(h5, "checkpoint/steps_done").at(0);
  EXPECT_GE(at, 400);

  // A participant whose checkpoint is gone (started elsewhere, deleted) refuses, naming it;
  // the record is left as it was.
  std::string run_id;  // from the checkpoint file names: <name>_<run id>_<steps>.ckpt
  for (const auto& e : fs::directory_iterator(folder))
    if (e.path().filename().string().rfind("mass1_", 0) == 0) run_id = e.path().filename().string().substr(6, 16);
  const std::string ckpt = cosim::ParticipantCore::checkpoint_path(folder, "mass1", cosim::parse_id_hex(run_id),
                                                                   static_cast<int64_t>(at));
  ASSERT_TRUE(fs::exists(ckpt)) << ckpt;
  fs::rename(ckpt, ckpt + ".away");
  const std::string record = harness::read_text(h5);
  EXPECT_EQ(osc.resume(h5, ".refused"), 2);
  const std::string refused = harness::read_text(h5 + ".refused.log");
  EXPECT_NE(refused.find("participants.mass1.parameters: participant 'mass1'"), std::string::npos) << refused;
  EXPECT_NE(refused.find("has no checkpoint after " + std::to_string(static_cast<int>(at)) + " steps"),
            std::string::npos) << refused;
  EXPECT_NE(refused.find("'" + ckpt + "' is missing"), std::string::npos) << refused;
  EXPECT_TRUE(harness::read_text(h5) == record) << "a refused resume changed the record";
  fs::rename(ckpt + ".away", ckpt);

  ASSERT_EQ(osc.resume(h5, ".resume"), 0) << harness::read_text(h5 + ".resume.log");
  expect_identical(full, h5, 20);
  EXPECT_TRUE(harness::read_text(osc.csv_of(h5)) == harness::read_text(osc.csv_of(full)));
}

// The master itself killed (kill -9) with participants it launched: the record as of its last
// flush (always one at a checkpoint) is resumed, the master launching the participants again.
// The orphans of the killed master leave by their idle timeout (2 s here, 60 by default).
TEST(Resume, KilledMasterWithLaunchedParticipantsResumes) {
  const std::string url = harness::bus_url();
  const std::string full = harness::temp_path("_full.h5"), h5 = harness::temp_path(".h5");
  fs::remove_all(h5 + ".checkpoints");
  const std::vector<std::string> sets{
      "bus.url=" + url, "time.end=5", "checkpoints.every=0.05", "output.progress=off", "output.csv=",
      "participants.mass1.launch=[oscillator_adapter, --side, mass1, --idle-timeout, 2]",
      "participants.mass2.launch=[oscillator_adapter, --side, mass2, --idle-timeout, 2]"};
  auto first = harness::spawn(master_args("configs/oscillator.yaml", full, sets), full + ".log");
  ASSERT_EQ(harness::wait_for(first, 120), 0) << harness::read_text(full + ".log");
  auto master = harness::spawn(master_args("configs/oscillator.yaml", h5, sets), h5 + ".log");
  ASSERT_TRUE(wait_for_checkpoint(h5 + ".checkpoints", "mass1", 1000, 60)) << harness::read_text(h5 + ".log");
  kill(master.pid, SIGKILL);
  harness::wait_for(master, 10);
  const double at = harness::read_dataset(h5, "checkpoint/steps_done").at(0);
  EXPECT_GE(at, 900);
  EXPECT_TRUE(harness::read_string(h5, "status").empty()) << "a killed master writes no /status";
  auto resumed = harness::spawn({harness::bin("cosim_master"), "--resume", h5}, h5 + ".resume.log");
  ASSERT_EQ(harness::wait_for(resumed, 120), 0) << harness::read_text(h5 + ".resume.log");
  expect_identical(full, h5, 20);
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));  // the orphans' idle timeout
}

// The DEM co-simulation of tests/dem_service/cosim.yaml (1500 spheres, a blade played by the
// prescribed participant), 400 macro steps of 5 DEM steps, a checkpoint every 20: dem_service
// is killed after its checkpoint at 100 steps or later.
TEST(Resume, DemCoSimulationAfterAKilledDemServiceEqualsAnUninterruptedRun) {
  const std::string url = harness::bus_url();
  const std::string full = harness::temp_path("_full.h5"), h5 = harness::temp_path(".h5");
  const std::string folder = h5 + ".checkpoints";
  fs::remove_all(folder);
  const std::vector<std::string> sets{
      "bus.url=" + url, "participants.dem.launch=null", "participants.tool.launch=null", "bus.authenticate=false",
      "participants.dem.timeout=1", "time.end=0.02", "time.macro_step=5e-5",
      "checkpoints.every=1e-3", "output.progress=off"};
  auto start = [&](const std::string& log) {
    return std::vector<harness::Process>{
        harness::spawn({harness::bin("dem_service"), harness::source("tests/dem_service/scene.yaml"), "--bus",
                        url, "--wait", "60"},
                       log + ".dem.log"),
        harness::spawn({harness::bin("prescribed_adapter"), "--name", "tool", "--bus", url, "--wait", "60"},
                       log + ".tool.log")};
  };
  {
    auto parts = start(full);
    auto master = harness::spawn(master_args("tests/dem_service/cosim.yaml", full, sets), full + ".log");
    ASSERT_EQ(harness::wait_for(master, 300), 0) << harness::read_text(full + ".log");
    for (auto& p : parts) harness::wait_for(p, 20);
  }
  auto parts = start(h5);
  auto master = harness::spawn(master_args("tests/dem_service/cosim.yaml", h5, sets), h5 + ".log");
  ASSERT_TRUE(wait_for_checkpoint(folder, "dem", 100, 120)) << harness::read_text(h5 + ".log");
  kill(parts[0].pid, SIGKILL);
  EXPECT_EQ(harness::wait_for(master, 30), 1);
  EXPECT_EQ(harness::wait_for(parts[1], 10), 1) << "the tool was not told to stop";
  harness::wait_for(parts[0], 5);
  const std::string log = harness::read_text(h5 + ".log");
  EXPECT_NE(log.find("participant 'dem' stopped answering"), std::string::npos) << log;
  const double at = harness::read_dataset(h5, "checkpoint/steps_done").at(0);
  const std::size_t rows = harness::read_dataset(h5, "time").size();
  EXPECT_GE(at, 80);
  EXPECT_EQ(std::fmod(at, 20.0), 0.0) << "checkpoints.every is 20 macro steps";
  EXPECT_LT(rows, 401u) << "the run was not interrupted";
  std::printf("dem_service killed after %zu of 400 steps; last common checkpoint after %.0f\n", rows - 1, at);

  {
    auto again = start(h5 + ".resume");
    auto resumed = harness::spawn({harness::bin("cosim_master"), "--resume", h5}, h5 + ".resume.log");
    ASSERT_EQ(harness::wait_for(resumed, 300), 0) << harness::read_text(h5 + ".resume.log");
    for (auto& p : again) harness::wait_for(p, 20);
  }
  expect_identical(full, h5, 30);
  // The wrench the blade felt is in the comparison and is not trivially zero.
  const auto w = harness::read_dataset(h5, "participants/dem/outputs/blade");
  double peak = 0;
  for (std::size_t i = 0; i < w.size(); i += 9) peak = std::max(peak, std::abs(w[i]));
  EXPECT_GT(peak, 1.0) << "the blade never met the bed";
  EXPECT_FALSE(fs::exists(folder));
}

// ---- refusals ----

namespace {

std::pair<int, std::string> run(const std::vector<std::string>& args, const std::string& log) {
  auto p = harness::spawn(args, log);
  const int code = harness::wait_for(p, 60);
  return {code, harness::read_text(log)};
}

}  // namespace

TEST(Resume, RefusesWhatCannotBeResumedNamingWhy) {
  const std::string url = harness::bus_url();
  const std::string log = harness::temp_path(".log");
  const std::string done = harness::temp_path("_done.h5"), plain = harness::temp_path("_plain.h5");
  // A finished run with checkpoints, and one without (launched participants, 20 steps).
  for (const auto& [h5, every] : {std::pair{done, "0.0025"}, std::pair{plain, "0"}})
    ASSERT_EQ(harness::run_master({"time.end=0.01", std::string("checkpoints.every=") + every}, h5), 0)
        << harness::read_text(h5 + ".log");
  const std::string cm = harness::bin("cosim_master");
  struct Case {
    std::vector<std::string> args;
    const char* message;
  };
  const std::string text = harness::temp_path("_text.h5");
  std::ofstream(text) << "not hdf5\n";
  const std::vector<Case> cases{
      {{cm, "--resume", done}, "is a finished run (/status: finished): there is nothing to resume"},
      {{cm, "--resume", plain}, "has no checkpoints: its run had checkpoints.every: 0"},
      {{cm, "--resume", text}, "is missing or not an HDF5 file"},
      {{cm, "--resume", harness::temp_path("_none.h5")}, "is missing or not an HDF5 file"},
      {{cm, harness::source("configs/oscillator.yaml"), "--resume", done}, "give neither a config file nor --output"},
      {{cm, "--resume", done, "--output", plain}, "give neither a config file nor --output"},
      {{cm, "--resume", done, "--replay", text, "--replay-side", "mass1"}, "--resume and --replay do not combine"},
      {{cm, harness::source("configs/oscillator.yaml"), "--output", harness::temp_path("_x.h5"), "--set",
        "checkpoints.every=0.00033"},
       "checkpoints.every: 0.00033 s is not a whole number of macro steps (time.macro_step = 0.0005 s)"},
      {{cm, harness::source("configs/oscillator.yaml"), "--output", "", "--set", "output.file=", "--set",
        "checkpoints.every=0.05"},
       "checkpoints.every: needs output.file (or --output)"},
      {{cm, harness::source("configs/oscillator.yaml"), "--output", harness::temp_path("_x.h5"), "--set",
        "checkpoints.every=-1"},
       "checkpoints.every: -1 is not allowed"},
      {{cm, harness::source("configs/oscillator.yaml"), "--output", harness::temp_path("_x.h5"), "--set",
        "checkpoints.evry=1"},
       "checkpoints.evry"},
  };
  for (const auto& c : cases) {
    const auto [code, out] = run(c.args, log);
    EXPECT_EQ(code, 2) << out;
    EXPECT_NE(out.find(c.message), std::string::npos) << "expected '" << c.message << "' in:\n" << out;
  }
  EXPECT_FALSE(fs::exists(harness::temp_path("_x.h5")));

  // A stopped run with a checkpoint: --set of a key that changes results is refused by name.
  const std::string stopped = harness::temp_path("_stopped.h5");
  {
    auto m1 = harness::spawn({harness::bin("oscillator_adapter"), "--side", "mass1", "--bus", url, "--wait", "60"},
                             stopped + ".mass1.log");
    auto m2 = harness::spawn({harness::bin("oscillator_adapter"), "--side", "mass2", "--bus", url, "--wait", "60"},
                             stopped + ".mass2.log");
    auto master = harness::spawn(master_args("configs/oscillator.yaml", stopped,
                                              {"bus.url=" + url, "participants.mass1.launch=null", "bus.authenticate=false",
                                               "participants.mass2.launch=null", "participants.mass2.timeout=0.3",
                                               "time.end=100", "checkpoints.every=0.01", "output.csv=",
                                               "output.progress=off"}),
                                 stopped + ".log");
    ASSERT_TRUE(wait_for_checkpoint(stopped + ".checkpoints", "mass2", 20, 60));
    kill(m2.pid, SIGKILL);
    EXPECT_EQ(harness::wait_for(master, 30), 1);
    harness::wait_for(m1, 10);
    harness::wait_for(m2, 5);
  }
  const std::string before = harness::read_text(stopped);
  for (const char* set : {"time.end=200", "predictors.force.order=1", "checkpoints.every=0.02",
                          "participants.mass1.parameters.mass=2"}) {
    const auto [code, out] = run({cm, "--resume", stopped, "--set", set}, log);
    EXPECT_EQ(code, 2) << out;
    EXPECT_NE(out.find(std::string("--set ") + std::string(set).substr(0, std::string(set).find('=')) +
                       ": not allowed with --resume"),
              std::string::npos)
        << out;
  }
  EXPECT_TRUE(harness::read_text(stopped) == before) << "a refused resume changed the record";
  fs::remove_all(stopped + ".checkpoints");
}

// ---- in process: every resume point, through the start-up iterations and the schemes ----

namespace {

// Stops the run (as a crash of the master would) once `at` steps are recorded.
struct StopAfter final : master::Observer {
  int64_t at;
  explicit StopAfter(int64_t n) : at(n) {}
  void on_step(const master::StepRecord& r) override {
    if (r.step_index + 1 == at) throw std::runtime_error("stopped on purpose");
  }
};

// One in-process run of the oscillator into `h5`: from the start (stop_after > 0: stopped
// there), or resumed from `h5` itself.
void run_in_process(const std::vector<std::string>& sets, const std::string& h5, const std::string& folder,
                    int64_t stop_after, bool resume) {
  oscillator::OscillatorAdapter m1(oscillator::Side::Mass1), m2(oscillator::Side::Mass2);
  cosim::ParticipantCore c1("mass1", m1), c2("mass2", m2);
  auto transport = cosim::make_in_process_transport(99, {{"mass1", &c1}, {"mass2", &c2}});
  master::Config config;
  std::unique_ptr<master::H5Recorder> recorder;
  std::optional<master::ResumePoint> point;
  int64_t run_id = 0x5eed;
  if (resume) {
    const master::ResumeRecord record = master::read_resume_record(h5);
    config = master::resume_config(record, {});
    run_id = record.run_id;
    EXPECT_EQ(record.folder, folder);
    point = master::read_resume_point(record, config);
    recorder = std::make_unique<master::H5Recorder>(master::H5Recorder::Continue{}, h5);
  } else {
    config = harness::oscillator_config(sets);
    recorder = std::make_unique<master::H5Recorder>(h5);
  }
  master::CoSimulation sim(config, *transport);
  sim.set_checkpoints(run_id, folder);
  if (point) sim.set_resume(*point);
  StopAfter stop(stop_after);
  sim.add_observer(recorder.get());
  if (stop_after > 0) sim.add_observer(&stop);
  sim.connect();
  try {
    sim.run();
  } catch (const std::exception& e) {
    EXPECT_GT(stop_after, 0) << e.what();
  }
}

}  // namespace

TEST(ResumeInProcess, EveryResumePointThroughTheStartUpIterationsIsBitIdentical) {
  struct Variant {
    const char* name;
    std::vector<std::string> sets;
  };
  const std::vector<Variant> variants{
      {"jacobi_1_0", {}},
      {"gauss_seidel_2_2_average",
       {"scheme=gauss_seidel", "predictors.kinematics.order=2", "predictors.force.order=2", "connections.2.use=average"}},
      {"jacobi_3_3_least_squares",
       {"predictors.kinematics={order: 3, samples: 6}", "predictors.force={order: 3, samples: 5}"}}};
  for (const auto& v : variants) {
    std::vector<std::string> sets = v.sets;
    sets.insert(sets.end(), {"time.end=0.005", "checkpoints.every=0.0005", "output.csv="});  // 10 steps
    const std::string folder = harness::temp_path(std::string("_") + v.name + ".checkpoints");
    const std::string full = harness::temp_path(std::string("_") + v.name + "_full.h5");
    fs::remove_all(folder);
    run_in_process(sets, full, folder, 0, false);
    ASSERT_EQ(harness::read_string(full, "status"), "finished") << v.name;
    for (int64_t n : {1, 2, 3, 4, 7}) {  // steps 0..2 are start-up iterations for order 3
      SCOPED_TRACE(std::string(v.name) + ", resumed after " + std::to_string(n) + " steps");
      const std::string h5 = harness::temp_path(std::string("_") + v.name + "_" + std::to_string(n) + ".h5");
      run_in_process(sets, h5, folder, n, false);
      ASSERT_EQ(harness::read_dataset(h5, "checkpoint/steps_done"), std::vector<double>{static_cast<double>(n)});
      ASSERT_EQ(harness::read_string(h5, "status"), "stopped: stopped on purpose");
      run_in_process(sets, h5, folder, 0, true);
      const Comparison c = compare_records(full, h5);
      EXPECT_TRUE(c.differ.empty() && c.missing.empty()) << c.text();
      EXPECT_GE(c.compared, 20);
    }
    fs::remove_all(folder);
  }
}

// Implicit coupling (IQN-ILS reusing past steps' columns) and an adaptive step that rejects
// steps take checkpoints too: the algorithm's state after the checkpoint's step (the reused
// columns, the connection scales, the next step's length, the last error) is kept in the record
// (/checkpoint/algorithm_state) and a resumed run continues bit-identically, also across a
// rejected step (the explicit adaptive run rejects steps 0 and 9, the implicit one steps 7 and
// 8; resumed after 7 steps these rejections happen in the resumed process).
TEST(ResumeInProcess, ImplicitAndAdaptiveRunsResumeBitIdentically) {
  struct Variant {
    const char* name;
    std::vector<std::string> sets;
    std::vector<int64_t> resume_after;
    std::vector<std::size_t> rejected_rows;  // rows of /coupling/rejected that hold 1 (step + 1)
  };
  const std::string conv =
      "coupling.convergence=[{connection: mass1.force, measure: absolute_or_relative, absolute: 1.0e-9, relative: 1.0e-9}]";
  const std::string iqn = "coupling.acceleration={type: iqn_ils, relaxation: 0.1, reuse: 8}";
  // Jacobi: steps of 0.315, 0.315, 0.945, ... ms; implicit Gauss-Seidel: 0.5, 1.5, 0.89, ... ms.
  // Every step from the second (Jacobi) or the first on reaches a multiple of checkpoints.every
  // = 0.5 ms, so the runs checkpoint after each.
  const std::string adaptive =
      "coupling.adaptive={min_step: 2.5e-4, max_step: 2.0e-3, abs_tolerance: 1.0e-3, rel_tolerance: 1.0e-2, "
      "reject_above: 1.0, max_change: 3, safety: 1.0}";
  const std::vector<Variant> variants{
      {"implicit_gauss_seidel_iqn",
       {"scheme=gauss_seidel", "order=[mass1, mass2]", "coupling.type=implicit", conv, iqn, "time.macro_step=1.0e-3",
        "time.end=0.01", "checkpoints.every=0.001"},
       {1, 2, 3, 4, 7},
       {}},
      {"adaptive_rejecting_jacobi", {adaptive, "time.end=0.01", "checkpoints.every=0.0005"}, {2, 3, 7, 10}, {1, 10}},
      {"adaptive_rejecting_implicit_iqn",
       {"scheme=gauss_seidel", "order=[mass1, mass2]", "coupling.type=implicit", conv, iqn, adaptive, "time.end=0.01",
        "checkpoints.every=0.0005"},
       {1, 2, 7, 8},
       {8, 9}}};
  for (const auto& v : variants) {
    std::vector<std::string> sets = v.sets;
    sets.push_back("output.csv=");
    const std::string folder = harness::temp_path(std::string("_") + v.name + ".checkpoints");
    const std::string full = harness::temp_path(std::string("_") + v.name + "_full.h5");
    fs::remove_all(folder);
    run_in_process(sets, full, folder, 0, false);
    ASSERT_EQ(harness::read_string(full, "status"), "finished") << v.name;
    {  // The energy residual is the trapezoid over each step's own length (an adaptive step's
       // is not time.macro_step): row i = row i-1 + (r_(i-1) + r_i) / 2 (t_i - t_(i-1)).
      const auto t = harness::read_dataset(full, "time");
      const auto r = harness::read_dataset(full, "power/coupling/residual");
      const auto e = harness::read_dataset(full, "power/coupling/energy_residual");
      ASSERT_EQ(t.size(), e.size());
      ASSERT_EQ(r.size(), e.size());
      double sum = 0;
      for (std::size_t i = 1; i < e.size(); ++i) {
        sum += (i == 1 ? r[i] : 0.5 * (r[i - 1] + r[i])) * (t[i] - t[i - 1]);
        EXPECT_NEAR(e[i], sum, 1e-12 * (1 + std::abs(sum))) << v.name << ", row " << i;
      }
    }
    if (!v.rejected_rows.empty()) {  // the scene this test means: these steps rejected once each
      const auto rejected = harness::read_dataset(full, "coupling/rejected");
      for (std::size_t row = 0; row < rejected.size(); ++row) {
        const bool expected = std::find(v.rejected_rows.begin(), v.rejected_rows.end(), row) != v.rejected_rows.end();
        EXPECT_EQ(rejected[row], expected ? 1.0 : 0.0) << v.name << ", row " << row;
      }
    }
    for (int64_t n : v.resume_after) {
      SCOPED_TRACE(std::string(v.name) + ", resumed after " + std::to_string(n) + " steps");
      const std::string h5 = harness::temp_path(std::string("_") + v.name + "_" + std::to_string(n) + ".h5");
      run_in_process(sets, h5, folder, n, false);
      ASSERT_EQ(harness::read_dataset(h5, "checkpoint/steps_done"), std::vector<double>{static_cast<double>(n)});
      ASSERT_EQ(harness::read_string(h5, "status"), "stopped: stopped on purpose");
      run_in_process(sets, h5, folder, 0, true);
      const Comparison c = compare_records(full, h5);
      EXPECT_TRUE(c.differ.empty() && c.missing.empty()) << c.text();
      EXPECT_GE(c.compared, 20);
    }
    fs::remove_all(folder);
  }
}
