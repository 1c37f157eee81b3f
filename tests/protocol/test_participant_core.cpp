// Participant-side protocol: configure, step identity, cached replies, validation.
#include <cosim/bus.hpp>
#include <cosim/participant_core.hpp>
#include <cosim/yaml_config.hpp>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

using namespace cosim;

namespace {
// Integrates x' = u with an inner step of 1 ms; counts the steps it really takes.
class Counter final : public Model {
 public:
  int steps_taken = 0, saves = 0, skips = 0;
  double x = 0, saved = 0;
  void configure(const YAML::Node& p, const RunInfo&) override {
    config::check_keys(p, "parameters", {"x0"});
    x = config::get_double_or(p, "parameters", "x0", 0.0);
  }
  Ports inputs() const override { return {{"u", SignalKind::Scalar}}; }
  Ports outputs() const override { return {{"x", SignalKind::Scalar}}; }
  Duration inner_step() const override { return nanoseconds(1'000'000); }
  Signals initial_outputs() override { return {{"x", {SignalKind::Scalar, {x}}}}; }
  StepResult step(const StepInputs& in, bool) override {
    ++steps_taken;
    for (TimePoint t = in.t_start(); t < in.t_end(); t += inner_step()) x += in.at("u", t)[0] * 1e-3;
    // An input found bad halfway through the step (after the state changed).
    if (in.at("u", in.t_start())[0] == 999) throw InputError("u = 999 is refused after the step began");
    return {{{"x", {SignalKind::Scalar, {x}}}}, std::nullopt, {}};
  }
  bool can_repeat() const override { return true; }
  void save_snapshot() override { saved = x, ++saves; }
  void restore_snapshot() override { x = saved; }
  void skip_snapshot() override { ++skips; }
};

configure_t configure_message(const std::string& params = "x0: 1") {
  configure_t c{};
  c.protocol_version = kProtocolVersion;
  c.session_id = 42;
  c.participant = "p";
  c.t_start_ns = 0;
  c.t_end_ns = 1'000'000'000;
  c.macro_step_ns = 10'000'000;
  c.parameters_yaml = params;
  return c;
}

step_request_t request(int64_t step, double u, int iteration = 0) {
  step_request_t q{};
  q.session_id = 42;
  q.participant = "p";
  q.step_index = step;
  q.iteration = iteration;
  q.t_start_ns = step * 10'000'000;
  q.t_end_ns = (step + 1) * 10'000'000;
  Polynomials in;
  in["u"] = InputPolynomial::constant(SignalKind::Scalar, {u});
  q.inputs = to_message(in);
  return q;
}
}  // namespace

TEST(ParticipantCore, RefusesBadParametersAndStaysFree) {
  Counter m;
  ParticipantCore core("p", m);
  auto r = core.configure(configure_message("x1: 3"));
  ASSERT_TRUE(r);
  EXPECT_FALSE(r->ok);
  EXPECT_NE(r->error.find("unknown key 'x1'"), std::string::npos) << r->error;
  EXPECT_FALSE(core.bound());
  r = core.configure(configure_message());
  ASSERT_TRUE(r && r->ok);
  EXPECT_EQ(r->inner_step_ns, 1'000'000);
}

TEST(ParticipantCore, RepeatedRequestGetsTheCachedReplyWithoutSteppingTwice) {
  Counter m;
  ParticipantCore core("p", m);
  ASSERT_TRUE(core.configure(configure_message())->ok);
  auto a = core.handle(request(0, 2.0));
  ASSERT_TRUE(a);
  EXPECT_EQ(a->status, step_reply_t::OK);
  auto again = request(0, 2.0);
  again.attempt = 1;
  auto b = core.handle(again);
  ASSERT_TRUE(b);
  EXPECT_EQ(m.steps_taken, 1);
  EXPECT_EQ(b->outputs.scalars[0].value, a->outputs.scalars[0].value);
  EXPECT_EQ(b->attempt, 1);
  EXPECT_NEAR(a->outputs.scalars[0].value, 1.0 + 2.0 * 0.01, 1e-12);
}

TEST(ParticipantCore, IgnoresOtherSessionsAndRefusesSkippedSteps) {
  Counter m;
  ParticipantCore core("p", m);
  ASSERT_TRUE(core.configure(configure_message())->ok);
  auto q = request(0, 1.0);
  q.session_id = 43;
  EXPECT_FALSE(core.handle(q));
  EXPECT_EQ(core.ignored_messages(), 1u);
  auto skip = core.handle(request(3, 1.0));
  ASSERT_TRUE(skip);
  EXPECT_EQ(skip->status, step_reply_t::REJECTED);
  EXPECT_NE(skip->message.find("next step is 0"), std::string::npos);
  EXPECT_EQ(m.steps_taken, 0);
}

TEST(ParticipantCore, RejectsBadInputsAndKeepsServing) {
  Counter m;
  ParticipantCore core("p", m);
  ASSERT_TRUE(core.configure(configure_message())->ok);
  auto nan = request(0, std::nan(""));
  auto r = core.handle(nan);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, step_reply_t::REJECTED);
  EXPECT_NE(r->message.find("NaN"), std::string::npos) << r->message;
  auto wrong = request(0, 1.0);
  wrong.inputs.scalars[0].name = "w";
  r = core.handle(wrong);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, step_reply_t::REJECTED);
  EXPECT_NE(r->message.find("'w' is not declared (declared: u)"), std::string::npos) << r->message;
  r = core.handle(request(0, 1.0));  // still serving, state untouched
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, step_reply_t::OK);
  EXPECT_NEAR(r->outputs.scalars[0].value, 1.01, 1e-12);
}

TEST(ParticipantCore, RedoOfAStepStartsFromItsSnapshot) {
  Counter m;
  ParticipantCore core("p", m);
  ASSERT_TRUE(core.configure(configure_message())->ok);
  core.handle(request(0, 1.0));
  auto first = core.handle(request(1, 1.0));
  auto redo = core.handle(request(1, 3.0, 1));
  ASSERT_TRUE(first && redo);
  EXPECT_NEAR(first->outputs.scalars[0].value, 1.02, 1e-12);
  EXPECT_NEAR(redo->outputs.scalars[0].value, 1.01 + 0.03, 1e-12);
  auto same = core.handle(request(1, 1.0, 1));  // repeat of iteration 1: cached, not recomputed
  EXPECT_EQ(same->outputs.scalars[0].value, redo->outputs.scalars[0].value);
  EXPECT_EQ(m.steps_taken, 3);
}

// step_request_t.no_redo: the master will not redo the step, so no snapshot of its start is
// taken (skip_snapshot instead of save_snapshot); the results are the same; a redo asked anyway
// is refused, naming why, and the participant keeps serving.
TEST(ParticipantCore, StepsSentWithNoRedoKeepNoSnapshotAndRefuseARedo) {
  Counter keep, skip;
  ParticipantCore a("p", keep), b("p", skip);
  ASSERT_TRUE(a.configure(configure_message())->ok);
  ASSERT_TRUE(b.configure(configure_message())->ok);
  const double u[] = {0.3, -1.7, 2.9, 0.1, 1e-3};
  // Step 0 iterated as at start-up (may be redone), then steps the master will not redo.
  for (int k = 0; k < 5; ++k) {
    auto qa = request(k, u[k]), qb = request(k, u[k]);
    qb.no_redo = k > 0;
    auto ra = a.handle(qa), rb = b.handle(qb);
    ASSERT_TRUE(ra && rb && ra->status == step_reply_t::OK && rb->status == step_reply_t::OK);
    EXPECT_EQ(ra->outputs.scalars[0].value, rb->outputs.scalars[0].value) << "step " << k;
    if (k == 0) {  // the start-up redo works alike
      ra = a.handle(request(0, 2.0, 1)), rb = b.handle(request(0, 2.0, 1));
      ASSERT_TRUE(ra && rb && ra->status == step_reply_t::OK && rb->status == step_reply_t::OK);
      EXPECT_EQ(ra->outputs.scalars[0].value, rb->outputs.scalars[0].value);
    }
  }
  EXPECT_EQ(keep.saves, 5);
  EXPECT_EQ(keep.skips, 0);
  EXPECT_EQ(skip.saves, 1);
  EXPECT_EQ(skip.skips, 4);
  // A redo of a no_redo step: refused (state unchanged), not restored from a stale snapshot.
  auto redo = b.handle(request(4, 5.0, 1));
  ASSERT_TRUE(redo);
  EXPECT_EQ(redo->status, step_reply_t::REJECTED);
  EXPECT_NE(redo->message.find("step 4 cannot be redone: the state at its start was not kept (the master "
                               "sent it with no_redo)"),
            std::string::npos) << redo->message;
  EXPECT_EQ(skip.steps_taken, 6);
  auto qa = request(5, 1.0), qb = request(5, 1.0);
  qb.no_redo = true;
  EXPECT_EQ(a.handle(qa)->outputs.scalars[0].value, b.handle(qb)->outputs.scalars[0].value);
  // A model's InputError after the state changed: with a snapshot it is put back (REJECTED);
  // without one it cannot be, and the step fails, saying so.
  auto bad_a = a.handle(request(6, 999)), bad_b = [&] { auto q = request(6, 999); q.no_redo = true; return b.handle(q); }();
  ASSERT_TRUE(bad_a && bad_b);
  EXPECT_EQ(bad_a->status, step_reply_t::REJECTED);
  EXPECT_EQ(bad_b->status, step_reply_t::FAILED);
  EXPECT_NE(bad_b->message.find("u = 999 is refused after the step began; the step was sent with no_redo, so its "
                                "start was not kept"),
            std::string::npos) << bad_b->message;
  // The one with a snapshot goes on from the state before the refused step.
  EXPECT_NEAR(a.handle(request(6, 1.0))->outputs.scalars[0].value, keep.saved + 0.01, 1e-12);
}

TEST(ParticipantCore, JoinsOneSessionAndRefusesAnotherNamingItself) {
  Counter m;
  ParticipantCore core("p", m);
  core.set_identity(77, "hostA", 1234);
  ASSERT_TRUE(core.configure(configure_message())->ok);
  auto other = configure_message();
  other.session_id = 43;
  auto r = core.configure(other);
  ASSERT_TRUE(r);
  EXPECT_FALSE(r->ok);
  EXPECT_EQ(r->bound_session_id, 42);
  EXPECT_EQ(r->session_id, 43);  // goes back to the master that asked
  EXPECT_NE(r->error.find("participant 'p' (pid 1234 on hostA) is already in session 000000000000002a"),
            std::string::npos) << r->error;
  EXPECT_EQ(core.session(), 42);
  auto again = core.configure(configure_message());  // its own master resent: same answer
  ASSERT_TRUE(again && again->ok);
  EXPECT_EQ(again->instance_id, 77);
}

TEST(ParticipantCore, StartedForASessionTakesNoOtherAndIgnoresOtherInstances) {
  Counter m;
  ParticipantCore core("p", m);
  core.set_identity(77, "hostA", 1234);
  core.reserve_for(42);
  auto c = configure_message();
  c.session_id = 43;
  auto r = core.configure(c);
  ASSERT_TRUE(r);
  EXPECT_FALSE(r->ok);
  EXPECT_NE(r->error.find("was started for session 000000000000002a (--session) and takes no other"),
            std::string::npos) << r->error;
  EXPECT_FALSE(core.bound());
  auto elsewhere = configure_message();
  elsewhere.instance_id = 78;  // meant for another process
  EXPECT_FALSE(core.configure(elsewhere));
  auto mine = configure_message();
  mine.instance_id = 77;
  ASSERT_TRUE(core.configure(mine)->ok);
  EXPECT_EQ(core.session(), 42);
}

// ---- checkpoints and resume (docs/protocol.md#checkpoints-and-resume) ----

namespace {

// The counter with checkpoints: x as exact hexadecimal text.
class Saving final : public Model {
 public:
  Counter inner;
  void configure(const YAML::Node& p, const RunInfo& r) override { inner.configure(p, r); }
  Ports inputs() const override { return inner.inputs(); }
  Ports outputs() const override { return inner.outputs(); }
  Duration inner_step() const override { return inner.inner_step(); }
  Signals initial_outputs() override { return inner.initial_outputs(); }
  StepResult step(const StepInputs& in, bool a) override { return inner.step(in, a); }
  bool can_repeat() const override { return true; }
  void save_snapshot() override { inner.save_snapshot(); }
  void restore_snapshot() override { inner.restore_snapshot(); }
  bool can_checkpoint() const override { return true; }
  void save_checkpoint(const std::string& path) override {
    char text[64];
    std::snprintf(text, sizeof text, "%a\n", inner.x);
    std::ofstream(path) << text;
  }
  void load_checkpoint(const std::string& path) override {
    std::ifstream in(path);
    std::string text;
    if (!(in >> text)) throw std::runtime_error("empty");
    inner.x = std::strtod(text.c_str(), nullptr);
  }
};

std::string fresh_folder(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("cosim_ckpt_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  return dir.string();
}

configure_t with_checkpoints(const std::string& folder, int64_t resume_steps = 0);
configure_t with_checkpoint_folderless() {
  configure_t c = configure_message();
  c.run_id = 0x1234;
  c.resume_steps_done = 4;
  c.resume_t_ns = 4 * c.macro_step_ns;
  return c;
}
configure_t with_checkpoints(const std::string& folder, int64_t resume_steps) {
  configure_t c = configure_message();
  c.checkpoint_folder = folder;
  c.run_id = 0x1234;
  c.resume_steps_done = resume_steps;
  c.resume_t_ns = resume_steps * c.macro_step_ns;
  return c;
}

double x_of(const step_reply_t& r) { return r.outputs.scalars.at(0).value; }

}  // namespace

TEST(ParticipantCore, CheckpointsAreWrittenTheLastTwoKeptAndARestoredRunContinuesBitIdentically) {
  const std::string folder = fresh_folder("keep");
  Saving m;
  ParticipantCore core("p", m);
  auto ready = core.configure(with_checkpoints(folder));
  ASSERT_TRUE(ready && ready->ok) << (ready ? ready->error : "");
  EXPECT_TRUE(ready->can_checkpoint);
  EXPECT_TRUE(std::filesystem::is_directory(folder)) << "the folder is created at configure";
  const double u[] = {0.3, -1.7, 2.9, 0.1, 1e-3, 7.0, -0.25, 3.5};
  for (int k = 0; k < 6; ++k) {
    auto q = request(k, u[k]);
    q.checkpoint = k % 2 == 1;  // after 2, 4 and 6 steps
    auto r = core.handle(q);
    ASSERT_TRUE(r && r->status == step_reply_t::OK) << (r ? r->message : "");
    EXPECT_EQ(r->checkpointed, static_cast<bool>(q.checkpoint));
  }
  auto path = [&](int n) { return ParticipantCore::checkpoint_path(folder, "p", 0x1234, n); };
  EXPECT_EQ(path(4), folder + "/p_0000000000001234_4.ckpt");
  EXPECT_FALSE(std::filesystem::exists(path(2))) << "only the last two are kept";
  EXPECT_TRUE(std::filesystem::exists(path(4)));
  EXPECT_TRUE(std::filesystem::exists(path(6)));
  EXPECT_FALSE(std::filesystem::exists(path(6) + ".tmp"));

  // Another process restores after 4 steps and redoes steps 4 and 5 exactly.
  Saving m2;
  ParticipantCore resumed("p", m2);
  auto ready2 = resumed.configure(with_checkpoints(folder, 4));
  ASSERT_TRUE(ready2 && ready2->ok) << (ready2 ? ready2->error : "");
  EXPECT_EQ(resumed.last_step(), 3);
  EXPECT_FALSE(std::filesystem::exists(path(6))) << "a later checkpoint than the resume point is stale";
  // Not step 3 again, nor a redo of it (no snapshot of its start), nor step 5.
  EXPECT_EQ(resumed.handle(request(3, u[3]))->status, step_reply_t::REJECTED);
  auto redo = resumed.handle(request(3, u[3], 1));
  ASSERT_TRUE(redo.has_value());
  EXPECT_EQ(redo->status, step_reply_t::REJECTED);
  EXPECT_EQ(resumed.handle(request(5, u[5]))->status, step_reply_t::REJECTED);
  Saving m3;  // an uninterrupted run for comparison
  ParticipantCore straight("p", m3);
  ASSERT_TRUE(straight.configure(configure_message())->ok);
  double expected = 0, got = 0;
  for (int k = 0; k < 8; ++k) {
    expected = x_of(*straight.handle(request(k, u[k])));
    if (k >= 4) {
      auto r = resumed.handle(request(k, u[k]));
      ASSERT_TRUE(r && r->status == step_reply_t::OK) << (r ? r->message : "");
      got = x_of(*r);
      EXPECT_EQ(got, expected) << "step " << k;  // bit for bit
    }
  }
  EXPECT_EQ(m3.inner.steps_taken, 8);
  EXPECT_EQ(m2.inner.steps_taken, 4);
  // A finished session deletes the checkpoints this process wrote or restored, and the folder.
  resumed.end_session(true);
  EXPECT_FALSE(std::filesystem::exists(path(4)));
  EXPECT_FALSE(std::filesystem::exists(folder));
  core.end_session(false);  // a failed one keeps nothing it does not have
  std::filesystem::remove_all(folder);
}

TEST(ParticipantCore, ResumesAndCheckpointsItCannotDoAreRefusedByName) {
  const std::string folder = fresh_folder("refuse");
  {  // a model without checkpoints cannot resume
    Counter m;
    ParticipantCore core("p", m);
    auto r = core.configure(with_checkpoints(folder, 4));
    ASSERT_TRUE(r.has_value());
    EXPECT_FALSE(r->ok);
    EXPECT_NE(r->error.find("cannot resume a run: this model does not save checkpoints"), std::string::npos) << r->error;
    EXPECT_FALSE(core.bound());
  }
  {  // it declares so, and a checkpoint asked of it anyway fails the step, naming why
    Counter m;
    ParticipantCore core("p", m);
    auto r = core.configure(with_checkpoints(folder));
    ASSERT_TRUE(r && r->ok);
    EXPECT_FALSE(r->can_checkpoint);
    auto q = request(0, 1.0);
    q.checkpoint = true;
    auto reply = core.handle(q);
    EXPECT_EQ(reply->status, step_reply_t::FAILED);
    EXPECT_NE(reply->message.find("the checkpoint after step 0 failed: this participant does not save checkpoints"),
              std::string::npos) << reply->message;
  }
  {  // a missing checkpoint file is named
    Saving m;
    ParticipantCore core("p", m);
    auto r = core.configure(with_checkpoints(folder, 4));
    EXPECT_FALSE(r->ok);
    EXPECT_NE(r->error.find("has no checkpoint after 4 steps of run 0000000000001234: '" + folder +
                            "/p_0000000000001234_4.ckpt' is missing"),
              std::string::npos) << r->error;
  }
  {  // resume points outside the run, a time that does not match, no folder
    Saving m;
    ParticipantCore core("p", m);
    configure_t c = with_checkpoints(folder, 100);  // the run has 100 steps: the resume time is its end
    EXPECT_NE(core.configure(c)->error.find("resume after 100 steps at " + std::to_string(c.t_end_ns) +
                                            " ns, which is not inside the run"),
              std::string::npos);
    c = with_checkpoints(folder, 4);
    c.resume_t_ns = c.t_start_ns;
    EXPECT_NE(core.configure(c)->error.find("which is not inside the run"), std::string::npos);
    c = with_checkpoint_folderless();
    EXPECT_NE(core.configure(c)->error.find("a resume needs the checkpoint folder"), std::string::npos);
    c = with_checkpoints(folder, -1);
    EXPECT_NE(core.configure(c)->error.find("resume_steps_done -1 is negative"), std::string::npos);
    EXPECT_FALSE(core.bound());
  }
  {  // a folder that cannot be made
    Saving m;
    ParticipantCore core("p", m);
    auto r = core.configure(with_checkpoints("/proc/no_such_place/ckpt"));
    EXPECT_FALSE(r->ok);
    EXPECT_NE(r->error.find("checkpoints.folder: cannot create '/proc/no_such_place/ckpt'"), std::string::npos) << r->error;
  }
  std::filesystem::remove_all(folder);
}
