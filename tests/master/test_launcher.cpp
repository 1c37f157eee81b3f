// Launcher::stop: a participant that is still running at the end gets SIGTERM and time to
// finish its outputs (term_grace) before it is killed; one that ignores SIGTERM is killed.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <cosim/auth.hpp>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <thread>

#include "launcher.hpp"
#include "run_key.hpp"

namespace {

master::ParticipantSpec shell(const std::string& name, const std::string& script) {
  master::ParticipantSpec spec;
  spec.name = name;
  // sh -c SCRIPT takes the appended --name/--bus/--session as $0, $1, ...
  spec.launch = {"/bin/sh", "-c", script};
  return spec;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

TEST(Launcher, ParticipantThatExitsByItselfIsReaped) {
  master::Launcher launcher;
  launcher.start(shell("quick", "exit 0"), "udpm://239.255.76.67:7667?ttl=0", 1);
  const auto t0 = std::chrono::steady_clock::now();
  launcher.stop(5.0);
  EXPECT_LT(seconds_since(t0), 2.0);
  EXPECT_EQ(launcher.exit_description("quick"), "exited with code 0");
  EXPECT_EQ(launcher.exit_description("other"), "not launched");
}

TEST(Launcher, SlowSigtermHandlerFinishesInsteadOfBeingKilled) {
  // Finishing takes 0.6 s after SIGTERM (longer than the 200 ms the launcher used to allow).
  master::Launcher launcher;
  launcher.start(shell("slow", "trap 'kill $! 2>/dev/null; sleep 0.6; exit 3' TERM; sleep 30 & wait"),
                 "udpm://239.255.76.67:7667?ttl=0", 1);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the trap is set
  const auto t0 = std::chrono::steady_clock::now();
  launcher.stop(0.2, 5.0);
  const double took = seconds_since(t0);
  EXPECT_EQ(launcher.exit_description("slow"), "exited with code 3");
  EXPECT_GT(took, 0.7);  // 0.2 s grace + 0.6 s of the handler
  EXPECT_LT(took, 4.0);
}

TEST(Launcher, ParticipantIgnoringSigtermIsKilledAfterTermGrace) {
  master::Launcher launcher;
  launcher.start(shell("stubborn", "trap '' TERM; while :; do sleep 0.05; done"),
                 "udpm://239.255.76.67:7667?ttl=0", 1);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto t0 = std::chrono::steady_clock::now();
  launcher.stop(0.1, 0.3);
  const double took = seconds_since(t0);
  EXPECT_EQ(launcher.exit_description("stubborn"), "was killed by signal 9");
  EXPECT_GT(took, 0.4);
  EXPECT_LT(took, 3.0);
}

// share_key: a launched participant finds the key as COSIM_KEY_FILE, a file only its owner can
// read that it inherited (not a path anyone can open, not on its command line), and no
// $COSIM_KEY of the master's environment.
TEST(Launcher, SharedKeyIsInheritedAsAPrivateFileAndNothingElse) {
  const cosim::auth::Key key = cosim::auth::parse_key_hex(cosim::auth::new_key_hex(), "test");
  const int fd = master::key_as_unnamed_file(key);
  ASSERT_GE(fd, 0);
  const std::string out = std::string(TEST_TMP_DIR) + "/launcher_key.txt";
  std::remove(out.c_str());
  setenv("COSIM_KEY", "00", 1);
  master::Launcher launcher;
  launcher.share_key(fd);
  launcher.start(shell("keyed", "{ echo \"$COSIM_KEY_FILE\"; stat -L -c %a \"$COSIM_KEY_FILE\"; cat \"$COSIM_KEY_FILE\"; "
                                "echo \"${COSIM_KEY:-unset}\"; cat /proc/$$/cmdline | tr '\\0' ' '; echo; } > " + out),
                 "udpm://239.255.76.67:7667?ttl=0", 1);
  launcher.stop(10.0);
  unsetenv("COSIM_KEY");
  EXPECT_EQ(master::key_hex(cosim::auth::read_key_file("/proc/self/fd/" + std::to_string(fd))), master::key_hex(key));
  ::close(fd);
  EXPECT_EQ(launcher.exit_description("keyed"), "exited with code 0");
  std::ifstream in(out);
  std::string path, mode, hex, env_key, cmdline;
  std::getline(in, path);
  std::getline(in, mode);
  std::getline(in, hex);
  std::getline(in, env_key);
  std::getline(in, cmdline);
  EXPECT_EQ(path.rfind("/proc/self/fd/", 0), 0u) << path;
  EXPECT_EQ(mode, "600");
  EXPECT_EQ(hex, master::key_hex(key));
  EXPECT_EQ(env_key, "unset");
  EXPECT_EQ(cmdline.find(hex), std::string::npos) << cmdline;
}

// Participants that write their lines in pieces (an unbuffered stderr does: one write per <<)
// at the same time into the log the master writes to: every line arrives whole. Without the
// relay, the pieces of the two writers interleave ("mass1cosim_master: ...").
TEST(Launcher, LinesOfParticipantsSharingTheMastersLogArriveWhole) {
  const std::string log = std::string(TEST_TMP_DIR) + "/launcher_lines.log";
  const int file = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  ASSERT_GE(file, 0);
  std::fflush(stderr);
  const int saved_err = ::dup(STDERR_FILENO), saved_out = ::dup(STDOUT_FILENO);
  ::dup2(file, STDERR_FILENO);
  ::dup2(file, STDOUT_FILENO);
  // Each line: its writer's name, then 20 pieces, each its own write() (printf is a shell
  // builtin), the newline last; to stderr and stdout alike.
  auto script = [](const std::string& who) {
    return "i=0; while [ $i -lt 150 ]; do printf '" + who + ":' >&2; j=0; while [ $j -lt 20 ]; do printf ' " + who +
           "' >&2; j=$((j+1)); done; printf '\\n' >&2; printf '" + who + "-out\\n'; i=$((i+1)); done";
  };
  {
    master::Launcher launcher;
    launcher.relay_lines(true);
    launcher.start(shell("a", script("aa")), "udpm://239.255.76.67:7667?ttl=0", 1);
    launcher.start(shell("b", script("bb")), "udpm://239.255.76.67:7667?ttl=0", 1);
    launcher.stop(30.0);
    EXPECT_EQ(launcher.exit_description("a"), "exited with code 0");
  }
  ::dup2(saved_err, STDERR_FILENO);
  ::dup2(saved_out, STDOUT_FILENO);
  ::close(saved_err);
  ::close(saved_out);
  ::close(file);
  std::string whole_a = "aa:", whole_b = "bb:";
  for (int j = 0; j < 20; ++j) whole_a += " aa", whole_b += " bb";
  std::ifstream in(log);
  std::string line;
  int a = 0, b = 0, a_out = 0, b_out = 0, broken = 0;
  while (std::getline(in, line)) {
    if (line == whole_a) ++a;
    else if (line == whole_b) ++b;
    else if (line == "aa-out") ++a_out;
    else if (line == "bb-out") ++b_out;
    else if (++broken <= 3) ADD_FAILURE() << "a line cut by another writer: '" << line << "'";
  }
  EXPECT_EQ(broken, 0);
  EXPECT_EQ(a, 150);
  EXPECT_EQ(b, 150);
  EXPECT_EQ(a_out, 150);
  EXPECT_EQ(b_out, 150);
}
