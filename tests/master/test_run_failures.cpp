// Failures at the edges of a run (docs/output.md#when-a-record-cannot-be-written): a record that
// cannot start stops the participants and closes the other records, as a failure during the
// steps does; the notes added to the record at the end (RunNotes: /bus/recording, /replay) are
// checked as every other write of a record.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cosim/participant_core.hpp>

#include <filesystem>
#include <stdexcept>

#include "bus_log.hpp"
#include "config.hpp"
#include "cosimulation.hpp"
#include "oscillator_adapter.hpp"
#include "replay.hpp"

namespace {

namespace fs = std::filesystem;
const std::string kSource = SOURCE_DIR;

master::Config config() {
  return master::load_config(kSource + "/configs/oscillator.yaml",
                             {"output.file=", "output.csv=", "time.end=0.01"});
}

// The in-process transport, with terminate() written down.
class Spy final : public cosim::Transport {
 public:
  explicit Spy(cosim::Transport& inner) : inner_(inner) {}
  int terminated = 0;
  bool error = false;
  std::string reason;
  int64_t session() const override { return inner_.session(); }
  std::map<std::string, cosim::ParticipantInfo> connect(const std::vector<cosim::configure_t>& c,
                                                        double timeout_s) override {
    return inner_.connect(c, timeout_s);
  }
  std::vector<cosim::StepAnswer> exchange(const std::vector<cosim::step_request_t>& q) override {
    return inner_.exchange(q);
  }
  void terminate(bool e, const std::string& r) override {
    ++terminated;
    error = e;
    reason = r;
    inner_.terminate(e, r);
  }
  std::string describe() const override { return inner_.describe(); }

 private:
  cosim::Transport& inner_;
};

class CannotStart final : public master::Observer {
 public:
  void on_start(const master::RunSetup&) override {
    throw std::runtime_error("cannot write 'record.h5': File too large");
  }
};

class Finish final : public master::Observer {
 public:
  int started = 0, steps = 0, finished = 0;
  bool ok = true;
  std::string message;
  void on_start(const master::RunSetup&) override { ++started; }
  void on_step(const master::StepRecord&) override { ++steps; }
  void on_finish(bool o, const std::string& m) override {
    ++finished;
    ok = o;
    message = m;
  }
};

}  // namespace

// CoSimulation::run used to call on_start outside its try: the exception left the run with the
// participants never told to stop and the other records never closed.
TEST(RunFailures, ARecordThatCannotStartStopsTheParticipantsAndClosesTheOtherRecords) {
  oscillator::OscillatorAdapter m1(oscillator::Side::Mass1), m2(oscillator::Side::Mass2);
  cosim::ParticipantCore c1("mass1", m1), c2("mass2", m2);
  auto inner = cosim::make_in_process_transport(1234, {{"mass1", &c1}, {"mass2", &c2}});
  Spy spy(*inner);
  const master::Config c = config();  // CoSimulation keeps a reference
  master::CoSimulation sim(c, spy);
  Finish before, after;
  CannotStart broken;
  sim.add_observer(&before);
  sim.add_observer(&broken);
  sim.add_observer(&after);
  sim.connect();
  try {
    sim.run();
    ADD_FAILURE() << "the run went on without its record";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "cannot write 'record.h5': File too large");
  }
  EXPECT_EQ(spy.terminated, 1);
  EXPECT_TRUE(spy.error);
  EXPECT_EQ(spy.reason, "cannot write 'record.h5': File too large");
  for (const Finish* f : {&before, &after}) {
    EXPECT_EQ(f->steps, 0);
    EXPECT_EQ(f->finished, 1);
    EXPECT_FALSE(f->ok);
    EXPECT_EQ(f->message, "cannot write 'record.h5': File too large");
  }
}

namespace {

// An HDF5 file as the recorder leaves it, and a bus recording that has finished.
struct Notes {
  std::string dir, h5, log;
  std::unique_ptr<master::BusRecorder> recorder;
  explicit Notes(const std::string& name) {
    dir = std::string(TEST_TMP_DIR) + "/run_notes_" + name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    h5 = dir + "/record.h5";
    log = dir + "/bus.lcmlog";
    const hid_t f = H5Fcreate(h5.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    EXPECT_GE(f, 0);
    H5Fclose(f);
    const unsigned port = 20000 + static_cast<unsigned>(std::hash<std::string>{}(name) % 20000);
    recorder = std::make_unique<master::BusRecorder>(
        log, "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0", 0x1234, std::nullopt,
        "config: as run\n");
    recorder->finish("finished", 0.0);  // the notes' own call then does nothing more
  }
};

}  // namespace

TEST(RunFailures, RunNotesAreAddedToTheRecord) {
  Notes n("written");
  master::replay::RunNotes notes(n.h5, n.recorder.get(), nullptr, nullptr);
  notes.on_finish(true, "");
  const hid_t f = H5Fopen(n.h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  EXPECT_GT(H5Lexists(f, "bus", H5P_DEFAULT), 0);
  EXPECT_GT(H5Lexists(f, "bus/recording", H5P_DEFAULT), 0);
  EXPECT_GT(H5Lexists(f, "bus/recording/file", H5P_DEFAULT), 0);
  EXPECT_GT(H5Lexists(f, "bus/recording/events", H5P_DEFAULT), 0);
  H5Fclose(f);
}

// A full disk (a file-size limit at the record's size) while the notes are added: the failure
// names the file and the cause and is raised (the run does not say "finished"). It used to pass
// unseen. In a child process, which the limit does not outlive.
TEST(RunFailures, RunNotesThatCannotBeWrittenNameTheFileAndStopTheRun) {
  Notes n("full");
  const auto size = static_cast<rlim_t>(fs::file_size(n.h5));
  const std::string message_file = n.dir + "/message";
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    signal(SIGXFSZ, SIG_IGN);
    rlimit limit{};
    getrlimit(RLIMIT_FSIZE, &limit);
    const rlim_t before = limit.rlim_cur;
    limit.rlim_cur = size;
    setrlimit(RLIMIT_FSIZE, &limit);
    master::replay::RunNotes notes(n.h5, n.recorder.get(), nullptr, nullptr);
    int code = 1;  // not raised
    std::string message;
    try {
      notes.on_finish(true, "");
    } catch (const std::runtime_error& e) {
      message = e.what();
      code = 0;
    }
    limit.rlim_cur = before;  // the message file below
    setrlimit(RLIMIT_FSIZE, &limit);
    if (FILE* out = std::fopen(message_file.c_str(), "w")) {
      std::fputs(message.c_str(), out);
      std::fclose(out);
    }
    _exit(code);
  }
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "the child died of signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 0) << "RunNotes wrote past the limit without raising";
  std::string message;
  if (FILE* in = std::fopen(message_file.c_str(), "r")) {
    char buf[1024] = {0};
    message = std::string(buf, std::fread(buf, 1, sizeof buf - 1, in));
    std::fclose(in);
  }
  EXPECT_NE(message.find("cannot write '" + n.h5 + "'"), std::string::npos) << message;
}

// When the run failed already, a note that cannot be written is printed, not raised: the run's
// own failure is the one reported.
TEST(RunFailures, RunNotesOfAFailedRunDoNotHideItsFailure) {
  Notes n("failed");
  fs::resize_file(n.h5, 10);  // no longer an HDF5 file
  master::replay::RunNotes notes(n.h5, n.recorder.get(), nullptr, nullptr);
  testing::internal::CaptureStderr();
  EXPECT_NO_THROW(notes.on_finish(false, "participant 'mass1' failed"));
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("cannot write '" + n.h5 + "'"), std::string::npos) << err;
  EXPECT_THROW(notes.on_finish(true, ""), std::runtime_error);
}
