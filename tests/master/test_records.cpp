// What a run records is checked (docs/output.md#when-a-record-cannot-be-written): a full disk
// (a file-size limit, RLIMIT_FSIZE, in the master's process) stops the run with a non-zero exit
// and a message naming the file and the cause, never says "finished", and leaves the earlier
// record of that name as it was; and one output file has one writer
// (docs/output.md#one-writer-per-file): a second master aiming at a file a live master writes
// is refused before it starts, naming the other's pid and host, and a lock left by a killed run
// is taken over with a note. The oscillator, its halves launched by the master.
#include <hdf5.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cosim/files.hpp>
#include <cosim/h5.hpp>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <regex>

#include "harness.hpp"

namespace fs = std::filesystem;

namespace {

// A fresh folder for the test's files.
std::string folder() {
  const std::string d = harness::temp_path("_files");
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::vector<std::string> master_args(const std::string& h5, const std::string& csv,
                                     const std::vector<std::string>& sets, const std::string& url) {
  std::vector<std::string> a{harness::bin("cosim_master"), harness::source("configs/oscillator.yaml"),
                             "--output", h5, "--csv", csv, "--set", "bus.url=" + url,
                             "--set", "output.progress=off"};
  for (const auto& s : sets) a.insert(a.end(), {"--set", s});
  return a;
}

// As harness::spawn, with the size of any file the process writes limited to `max_bytes`
// (RLIMIT_FSIZE, what a full disk looks like to a writer: a write past it fails with EFBIG,
// "File too large") and SIGXFSZ ignored so the write fails instead of killing the process.
harness::Process spawn_limited(const std::vector<std::string>& args, const std::string& log,
                               rlim_t max_bytes) {
  harness::Process p;
  p.log = log;
  p.pid = fork();
  if (p.pid == 0) {
    FILE* f = std::fopen(log.c_str(), "w");
    if (f) {
      dup2(fileno(f), 1);
      dup2(fileno(f), 2);
    }
    std::signal(SIGXFSZ, SIG_IGN);
    const rlimit limit{max_bytes, max_bytes};
    if (setrlimit(RLIMIT_FSIZE, &limit) != 0) _exit(126);
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return p;
}

std::string bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Files the run left beside its outputs: temporary names, kept earlier files, locks.
std::vector<std::string> leftovers(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (n.find(".partial-") != std::string::npos || n.find(".previous-") != std::string::npos ||
        n.find(".lock") != std::string::npos)
      out.push_back(n);
  }
  return out;
}

std::int64_t complete_flag(const std::string& h5) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  cosim::h5::Handle f(H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!f.ok()) return -1;
  return cosim::h5::read_int_attribute(f, "complete");
}

std::string host_name() {
  char buf[256] = {};
  gethostname(buf, sizeof buf - 1);
  return buf;
}

}  // namespace

// HDF5 past a file-size limit: the earlier record (and the run's CSV) stay as they were.
TEST(Records, AFullDiskForTheHdf5RecordStopsTheRunAndKeepsTheEarlierRecord) {
  const std::string dir = folder(), h5 = dir + "/o.h5", csv = dir + "/o.csv", url = harness::bus_url();
  auto first = harness::spawn(master_args(h5, csv, {"time.end=0.2"}, url), dir + "/first.log");
  ASSERT_EQ(harness::wait_for(first, 120), 0) << harness::read_text(dir + "/first.log");
  EXPECT_EQ(complete_flag(h5), 1) << "a finished run's record says it is complete";
  EXPECT_EQ(harness::read_string(h5, "status"), "finished");
  const std::string earlier_h5 = bytes(h5), earlier_csv = bytes(csv);
  ASSERT_GT(earlier_h5.size(), 100000u);

  // 4000 steps need about 3 MB; 400 kB hold the start (the run takes the file's name) and fail
  // at a later flush.
  const std::string log = dir + "/full.log";
  auto full = spawn_limited(master_args(h5, csv, {"time.end=2"}, url), log, 400 * 1024);
  const int code = harness::wait_for(full, 120);
  const std::string text = harness::read_text(log);
  EXPECT_EQ(code, 1) << text;
  EXPECT_NE(text.find("cannot write '" + h5 + "': File too large"), std::string::npos) << text;
  EXPECT_EQ(text.find("finished after"), std::string::npos) << "a run that could not record said finished:\n" << text;
  EXPECT_EQ(text.find("recorded to"), std::string::npos) << text;
  EXPECT_NE(text.find("the earlier '" + h5 + "' is back in place"), std::string::npos) << text;
  EXPECT_NE(text.find("the earlier '" + csv + "' is back in place"), std::string::npos) << text;
  EXPECT_TRUE(bytes(h5) == earlier_h5) << "the earlier record was changed";
  EXPECT_TRUE(bytes(csv) == earlier_csv) << "the earlier CSV was changed";
  EXPECT_EQ(complete_flag(h5), 1);
  EXPECT_EQ(harness::read_dataset(h5, "time").size(), 401u);
  EXPECT_TRUE(leftovers(dir).empty()) << leftovers(dir).front();

  // No earlier file: nothing half-written is left under the name.
  fs::remove(h5);
  fs::remove(csv);
  auto fresh = spawn_limited(master_args(h5, csv, {"time.end=2"}, url), log, 400 * 1024);
  EXPECT_EQ(harness::wait_for(fresh, 120), 1) << harness::read_text(log);
  EXPECT_FALSE(fs::exists(h5)) << harness::read_text(log);
  EXPECT_FALSE(fs::exists(csv));
  EXPECT_TRUE(leftovers(dir).empty()) << leftovers(dir).front();
}

// A resumed run writes into the record itself: past the limit it puts the record back as it
// was, and the record can be resumed again once there is room.
TEST(Records, AFullDiskDuringAResumePutsTheRecordBackAndItResumesLater) {
  const std::string dir = folder(), h5 = dir + "/o.h5", url = harness::bus_url();
  const std::vector<std::string> sets{
      "bus.url=" + url, "time.end=5", "checkpoints.every=0.05", "output.progress=off", "output.csv=",
      "participants.mass1.launch=[oscillator_adapter, --side, mass1, --idle-timeout, 2]",
      "participants.mass2.launch=[oscillator_adapter, --side, mass2, --idle-timeout, 2]"};
  std::vector<std::string> args{harness::bin("cosim_master"), harness::source("configs/oscillator.yaml"),
                                "--output", h5};
  for (const auto& s : sets) args.insert(args.end(), {"--set", s});
  auto master = harness::spawn(args, dir + "/first.log");
  // Stopped by SIGINT once mass1 saved a checkpoint after 500 steps or later.
  const cosim::Stopwatch waited;
  auto latest = [&] {  // steps of mass1's newest checkpoint, <folder>/mass1_<run>_<steps>.ckpt
    long n = -1;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(h5 + ".checkpoints", ec)) {
      std::smatch m;
      const std::string f = e.path().filename().string();
      if (std::regex_match(f, m, std::regex("mass1_[0-9a-f]{16}_([0-9]+)\\.ckpt"))) n = std::max(n, std::stol(m[1]));
    }
    return n;
  };
  while (latest() < 500 && waited.seconds() < 60) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  kill(master.pid, SIGINT);
  ASSERT_EQ(harness::wait_for(master, 30), 130) << harness::read_text(dir + "/first.log");
  const double at = harness::read_dataset(h5, "checkpoint/steps_done").at(0);
  ASSERT_GT(at, 0) << harness::read_text(dir + "/first.log");
  EXPECT_EQ(complete_flag(h5), 0) << "a stopped run's record says it is not complete";
  const std::string before = bytes(h5);

  const std::string log = dir + "/resume_full.log";
  auto full = spawn_limited({harness::bin("cosim_master"), "--resume", h5}, log, before.size() + 100 * 1024);
  const int code = harness::wait_for(full, 120);
  const std::string text = harness::read_text(log);
  EXPECT_EQ(code, 1) << text;
  EXPECT_NE(text.find("cannot write '" + h5 + "': File too large"), std::string::npos) << text;
  EXPECT_EQ(text.find("finished after"), std::string::npos) << text;
  EXPECT_NE(text.find("the earlier '" + h5 + "' is back in place"), std::string::npos) << text;
  EXPECT_TRUE(bytes(h5) == before) << "the record of the stopped run was changed";
  EXPECT_TRUE(leftovers(dir).empty()) << leftovers(dir).front();

  std::this_thread::sleep_for(std::chrono::milliseconds(2500));  // the orphans' idle timeout
  auto again = harness::spawn({harness::bin("cosim_master"), "--resume", h5}, dir + "/resume.log");
  ASSERT_EQ(harness::wait_for(again, 120), 0) << harness::read_text(dir + "/resume.log");
  EXPECT_EQ(harness::read_string(h5, "status"), "finished");
  EXPECT_EQ(complete_flag(h5), 1);
  EXPECT_EQ(harness::read_dataset(h5, "time").size(), 10001u);
  EXPECT_TRUE(leftovers(dir).empty()) << leftovers(dir).front();
}

// The CSV export past the limit (the run writes no HDF5 file): no half-written number under the
// name and a non-zero exit.
TEST(Records, AFullDiskForTheCsvStopsTheRunAndKeepsTheEarlierCsv) {
  const std::string dir = folder(), csv = dir + "/o.csv", url = harness::bus_url();
  std::vector<std::string> args{harness::bin("cosim_master"), harness::source("configs/oscillator.yaml"),
                                "--csv", csv, "--set", "bus.url=" + url, "--set", "output.progress=off",
                                "--set", "output.file="};
  auto a = args;
  a.insert(a.end(), {"--set", "time.end=0.5"});
  auto earlier = harness::spawn(a, dir + "/earlier.log");
  ASSERT_EQ(harness::wait_for(earlier, 120), 0) << harness::read_text(dir + "/earlier.log");
  const std::string earlier_csv = bytes(csv);
  ASSERT_GT(earlier_csv.size(), 40000u);

  auto b = args;
  b.insert(b.end(), {"--set", "time.end=2"});  // about 300 kB of text
  const std::string log = dir + "/full.log";
  auto full = spawn_limited(b, log, 20 * 1024);
  const int code = harness::wait_for(full, 120);
  const std::string text = harness::read_text(log);
  EXPECT_EQ(code, 1) << text;
  EXPECT_NE(text.find("cannot write '" + csv + "': File too large"), std::string::npos) << text;
  EXPECT_EQ(text.find("finished after"), std::string::npos) << text;
  EXPECT_NE(text.find("the earlier '" + csv + "' is back in place"), std::string::npos) << text;
  EXPECT_TRUE(bytes(csv) == earlier_csv) << "the earlier CSV was changed";
  EXPECT_TRUE(leftovers(dir).empty()) << leftovers(dir).front();
}

// Two masters given the same --output: the second is refused before it starts anything, naming
// the first's pid and host; the first is not disturbed.
TEST(Records, ASecondMasterOnTheSameOutputIsRefusedNamingTheFirst) {
  const std::string dir = folder(), h5 = dir + "/o.h5", url = harness::bus_url();
  const std::string lock = dir + "/.o.h5.lock";
  // Long enough to be running when the second starts; stopped by SIGINT below.
  auto first = harness::spawn(master_args(h5, dir + "/a.csv", {"time.end=1000"}, url), dir + "/first.log");
  const cosim::Stopwatch waited;
  while (!fs::exists(lock) && waited.seconds() < 30) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_TRUE(fs::exists(lock)) << harness::read_text(dir + "/first.log");

  // Another port: if it were not refused, it would not meet the first run's participants.
  const std::string url2 = "udpm://239.255.76.67:" +
                           std::to_string(40000 + (std::hash<std::string>{}(url) % 1000)) + "?ttl=0";
  auto second = harness::spawn(master_args(h5, dir + "/b.csv", {"time.end=0.1"}, url2), dir + "/second.log");
  const int code = harness::wait_for(second, 60);
  const std::string text = harness::read_text(dir + "/second.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("--output '" + h5 + "' is being written by another run: cosim_master pid " +
                      std::to_string(first.pid) + " on host " + host_name()),
            std::string::npos)
      << text;
  EXPECT_EQ(text.find("waiting for"), std::string::npos) << "refused only after it started:\n" << text;
  EXPECT_FALSE(fs::exists(dir + "/b.csv"));

  kill(first.pid, SIGINT);
  EXPECT_EQ(harness::wait_for(first, 60), 128 + SIGINT) << harness::read_text(dir + "/first.log");
  EXPECT_FALSE(fs::exists(lock)) << "the lock outlived its run";
}

// A lock file whose writer was killed (no process holds it) is taken over with a note.
TEST(Records, AStaleLockIsTakenOverWithANote) {
  const std::string dir = folder(), h5 = dir + "/o.h5", url = harness::bus_url();
  std::ofstream(dir + "/.o.h5.lock") << "pid=999999\nhost=" << host_name()
                                     << "\nprogram=cosim_master\nsince=2026-01-01T00:00:00Z\n";
  auto run = harness::spawn(master_args(h5, dir + "/o.csv", {"time.end=0.05"}, url), dir + "/run.log");
  const std::string text = (harness::wait_for(run, 120), harness::read_text(dir + "/run.log"));
  EXPECT_NE(text.find("cosim_master: took over the lock of --output '" + h5 +
                      "' left by cosim_master pid 999999 on host " + host_name()),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("recorded to " + h5), std::string::npos) << text;
  EXPECT_TRUE(leftovers(dir).empty()) << leftovers(dir).front();
}

// The lock itself, in one process: a second holder is refused while the first lives, and the
// file goes with the first.
TEST(Records, AnOutputLockRefusesASecondWriterUntilReleased) {
  const std::string dir = folder(), out = dir + "/x.h5";
  {
    cosim::OutputLock a({"--output", out}, "test");
    EXPECT_TRUE(a.note().empty());
    const std::string text = harness::read_text(a.lock_path());
    EXPECT_NE(text.find("pid=" + std::to_string(getpid()) + "\n"), std::string::npos) << text;
    EXPECT_NE(text.find("host=" + host_name() + "\n"), std::string::npos) << text;
    try {
      cosim::OutputLock b({"output.file", dir + "/./x.h5"}, "test");
      ADD_FAILURE() << "a second writer of the same file was not refused";
    } catch (const cosim::OutputBusy& e) {
      EXPECT_NE(std::string(e.what()).find("test pid " + std::to_string(getpid()) + " on host " + host_name()),
                std::string::npos)
          << e.what();
    }
    cosim::OutputLock other({"--csv", dir + "/x.csv"}, "test");  // another file: no conflict
  }
  EXPECT_TRUE(leftovers(dir).empty()) << leftovers(dir).front();
  cosim::OutputLock again({"--output", out}, "test");
  EXPECT_TRUE(again.note().empty()) << again.note();
}
