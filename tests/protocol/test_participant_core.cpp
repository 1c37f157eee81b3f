// Participant-side protocol: configure, step identity, cached replies, validation.
#include <cosim/bus.hpp>
#include <cosim/participant.hpp>
#include <cosim/yaml_config.hpp>
#include <gtest/gtest.h>

using namespace cosim;

namespace {
// Integrates x' = u with an inner step of 1 ms; counts the steps it really takes.
class Counter final : public Model {
 public:
  int steps_taken = 0;
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
    return {{{"x", {SignalKind::Scalar, {x}}}}, std::nullopt, {}};
  }
  bool can_repeat() const override { return true; }
  void save_snapshot() override { saved = x; }
  void restore_snapshot() override { x = saved; }
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
