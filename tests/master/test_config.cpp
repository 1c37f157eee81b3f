// docs/config.md gives the master's defaults in its key table. This test reads every row whose
// default is a literal in backticks and checks it against the code: a config that sets the key
// to the documented value must parse to the same Config as one that leaves it out (the parser
// falls back to the field initialisers in config.hpp, the one place a default is declared).
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "config.hpp"
#include "cosimulation.hpp"

namespace {

// Only the required keys: two participants and one connection.
const char* kMinimal = R"(
time: {end: 1.0, macro_step: 1.0e-3}
participants: {a: null, b: {}}
connections: [{from: a.x, to: b.x}]
)";

// Every parsed field except the config's own text.
std::string describe(const master::Config& c) {
  std::ostringstream o;
  o.precision(17);
  auto parameters = [](const std::string& yaml) {
    // what the participant receives: no parameters and an empty map are the same
    const YAML::Node n = YAML::Load(yaml);
    return n.IsNull() || (n.IsMap() && n.size() == 0) ? std::string("{}") : yaml;
  };
  o << "bus '" << c.bus_url << "' time " << c.t_start.time_since_epoch().count() << ' '
    << c.t_end.time_since_epoch().count() << ' ' << c.macro_step.count() << " scheme " << static_cast<int>(c.scheme) << " order";
  for (const auto& n : c.order) o << ' ' << n;
  o << " startup " << c.startup_iterations << " connect " << c.connect_timeout << '\n';
  for (const auto& p : c.participants) {
    o << "participant " << p.name << " launch";
    for (const auto& a : p.launch) o << " '" << a << "'";
    o << " timeout " << p.link.timeout_s << " retries " << p.link.retries << " parameters "
      << parameters(p.parameters_yaml) << '\n';
  }
  for (const auto& k : c.connections)
    o << "connection " << k.from.str() << ' ' << k.to.str() << ' ' << k.predictor.order << ' '
      << k.predictor.samples << " '" << k.predictor_name << "' use " << master::use_name(k.use) << "\n";
  for (const auto& p : c.power)
    o << "power " << p.name << ' ' << p.force.str() << ' ' << p.velocity.str() << '\n';
  o << "output '" << c.output.file << "' '" << c.output.csv_file << "' " << c.output.progress
    << " faults " << c.faults.drop_request.size() << ' ' << c.faults.drop_reply.size() << '\n';
  o << "checkpoints " << c.checkpoints.every.count() << " '" << c.checkpoints.folder << "'\n";
  return o.str();
}

master::Config parse(const std::vector<std::string>& sets) {
  YAML::Node root = YAML::Load(kMinimal);
  for (const auto& s : sets) cosim::config::apply_override(root, s);
  return master::parse_config(root, kMinimal);
}

struct Documented {
  std::string key, value;
};

// Rows "| `key` | meaning | `value` ... |" of docs/config.md's first table.
std::vector<Documented> documented_defaults() {
  std::ifstream in(std::string(SOURCE_DIR) + "/docs/config.md");
  EXPECT_TRUE(in) << "cannot read docs/config.md";
  std::vector<Documented> out;
  const std::regex row(R"(^\| `([^`]+)` \|.*\| `([^`]*)`( \([^|]*\))? \|$)");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("## ", 0) == 0) break;  // the participants' parameters follow
    std::smatch m;
    if (std::regex_match(line, m, row)) out.push_back({m[1], m[2]});
  }
  return out;
}

TEST(master_ConfigDefaults, DocsMatchTheCode) {
  const std::string base = describe(parse({}));
  const auto rows = documented_defaults();
  EXPECT_GE(rows.size(), 9u) << "docs/config.md: the defaults in backticks went missing";
  for (const Documented& d : rows) {
    const std::string key = std::regex_replace(std::regex_replace(d.key, std::regex("<name>"), "a"),
                                               std::regex("<i>"), "0");
    std::string with;
    try {
      with = describe(parse({key + "=" + d.value}));
    } catch (const std::exception& e) {
      ADD_FAILURE() << "docs/config.md: `" << d.key << "` = `" << d.value << "`: " << e.what();
      continue;
    }
    EXPECT_EQ(with, base) << "docs/config.md documents `" << d.key << "` = `" << d.value
                          << "`, but the code's default differs";
  }
}

// The check above can fail: a different value changes the parsed config.
TEST(master_ConfigDefaults, AWrongDefaultIsNoticed) {
  const std::string base = describe(parse({}));
  for (const char* set : {"scheme=gauss_seidel", "startup_iterations=3", "connect_timeout=31",
                          "participants.a.timeout=2.5", "participants.a.retries=4",
                          "participants.a.parameters={k: 1}", "output.progress=on",
                          "output.file=x.h5", "time.start=0.5", "connections.0.use=average",
                          "checkpoints.every=0.002", "checkpoints.folder=ck"})
    EXPECT_NE(describe(parse({set})), base) << set;
}

// ---- connections[].use ----

std::string parse_error(const std::vector<std::string>& sets) {
  try {
    parse(sets);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

TEST(master_ConnectionUse, ParsesEndAndAverageAndNamesTheAllowedValues) {
  EXPECT_EQ(parse({}).connections[0].use, master::Use::End);
  EXPECT_EQ(parse({"connections.0.use=average"}).connections[0].use, master::Use::Average);
  EXPECT_EQ(parse({"connections.0.use=end"}).connections[0].use, master::Use::End);
  EXPECT_EQ(parse_error({"connections.0.use=mean"}),
            "connections.0.use: 'mean' is not allowed (allowed: end, average)");
  EXPECT_EQ(parse_error({"connections.0.use=Average"}),
            "connections.0.use: 'Average' is not allowed (allowed: end, average)");
  EXPECT_NE(parse_error({"connections.0.use=[end]"}).find("connections.0.use"), std::string::npos);
}

cosim::ParticipantInfo info(cosim::Ports inputs, cosim::Ports outputs) {
  cosim::ParticipantInfo i;
  i.inputs = std::move(inputs);
  i.outputs = std::move(outputs);
  i.inner_step = cosim::Duration(1000);
  return i;
}

TEST(master_ConnectionUse, AverageOnKinematicsIsRefusedAtTheWiringCheck) {
  using cosim::SignalKind;
  const auto parts = [](SignalKind kind) {
    return std::map<std::string, cosim::ParticipantInfo>{
        {"a", info({}, {{"x", kind}})}, {"b", info({{"x", kind}}, {})}};
  };
  const auto config = parse({"connections.0.use=average"});
  EXPECT_NO_THROW(master::check_wiring(config, parts(SignalKind::Scalar)));
  EXPECT_NO_THROW(master::check_wiring(config, parts(SignalKind::Wrench)));
  EXPECT_NO_THROW(master::check_wiring(parse({}), parts(SignalKind::Kinematics)));
  try {
    master::check_wiring(config, parts(SignalKind::Kinematics));
    ADD_FAILURE() << "use: average on kinematics was accepted";
  } catch (const std::exception& e) {
    EXPECT_STREQ(e.what(),
                 "connections.0.use: 'average' is not allowed for a.x, a kinematics signal (a pose "
                 "has no plain average); use: end (allowed for kinematics: end)");
  }
}

// A participant that cannot average: one scalar output, never an average.
class NoAverage final : public cosim::Model {
 public:
  explicit NoAverage(bool has_input) : has_input_(has_input) {}
  void configure(const YAML::Node&, const cosim::RunInfo&) override {}
  cosim::Ports inputs() const override {
    return has_input_ ? cosim::Ports{{"x", cosim::SignalKind::Scalar}} : cosim::Ports{};
  }
  cosim::Ports outputs() const override {
    return has_input_ ? cosim::Ports{} : cosim::Ports{{"x", cosim::SignalKind::Scalar}};
  }
  cosim::Duration inner_step() const override { return cosim::Duration(1'000'000); }
  cosim::Signals initial_outputs() override { return outputs_now(); }
  cosim::StepResult step(const cosim::StepInputs&, bool) override {
    cosim::StepResult r;
    r.outputs = outputs_now();
    return r;
  }

 private:
  cosim::Signals outputs_now() const {
    if (has_input_) return {};
    return {{"x", {cosim::SignalKind::Scalar, {1.0}}}};
  }
  bool has_input_;
};

TEST(master_ConnectionUse, AMissingAverageNamesTheConnectionAndTheFix) {
  const auto config = parse({"connections.0.use=average", "startup_iterations=0"});
  NoAverage a(false), b(true);
  cosim::ParticipantCore ca("a", a), cb("b", b);
  auto transport = cosim::make_in_process_transport(77, {{"a", &ca}, {"b", &cb}});
  master::CoSimulation sim(config, *transport);
  sim.connect();
  try {
    sim.run();
    ADD_FAILURE() << "a missing average was accepted";
  } catch (const cosim::LinkError& e) {
    const std::string m = e.what();
    EXPECT_EQ(e.participant(), "a");
    EXPECT_NE(m.find("connections.0 (a.x -> b.x) has use: average, but participant 'a' step 0"), std::string::npos) << m;
    EXPECT_NE(m.find("the interval average of its outputs was asked for but not sent"), std::string::npos) << m;
    EXPECT_NE(m.find("set use: end on this connection"), std::string::npos) << m;
  }
}

}  // namespace
