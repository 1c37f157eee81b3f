// A small participant for the message fuzzer and its seed generator: one input and one output
// of each kind, inner step 1 ms, outputs = the inputs at the step's end.
#pragma once

#include <cosim/configure_t.hpp>
#include <cosim/ready_t.hpp>
#include <cosim/step_request_t.hpp>

#include "cosim/bus.hpp"
#include "cosim/participant_core.hpp"
#include "cosim/polynomial.hpp"
#include "cosim/signal.hpp"
#include "cosim/yaml_config.hpp"

namespace fuzz {

inline constexpr int64_t kSession = 7;
inline constexpr const char* kName = "p";

inline cosim::Ports ports() {
  return {{"s", cosim::SignalKind::Scalar}, {"k", cosim::SignalKind::Kinematics},
          {"w", cosim::SignalKind::Wrench}};
}

inline cosim::Value identity(cosim::SignalKind kind) {
  cosim::Value v(static_cast<std::size_t>(cosim::value_size(kind)), 0.0);
  if (kind == cosim::SignalKind::Kinematics) v[3] = 1;  // qw
  return v;
}

class Model final : public cosim::Model {
 public:
  void configure(const YAML::Node& parameters, const cosim::RunInfo&) override {
    if (parameters.IsMap() && parameters.size() > 0)
      throw cosim::config::ConfigError("parameters: this participant takes none");
  }
  cosim::Ports inputs() const override { return ports(); }
  cosim::Ports outputs() const override { return ports(); }
  cosim::Duration inner_step() const override { return std::chrono::milliseconds(1); }
  cosim::Signals initial_outputs() override {
    cosim::Signals out;
    for (const auto& p : ports()) out[p.name] = {p.kind, identity(p.kind)};
    return out;
  }
  cosim::StepResult step(const cosim::StepInputs& in, bool want_average) override {
    cosim::StepResult r;
    for (auto t = in.t_start(); t < in.t_end(); t += inner_step())
      for (const auto& p : ports()) (void)in.at(p.name, t);
    for (const auto& p : ports()) r.outputs[p.name] = {p.kind, in.at(p.name, in.t_end())};
    if (want_average) r.average = r.outputs;
    r.diagnostics.push_back({"steps", 1.0});
    return r;
  }
};

inline cosim::configure_t configure_message() {
  cosim::configure_t m{};
  m.protocol_version = cosim::kProtocolVersion;
  m.session_id = kSession;
  m.participant = kName;
  m.t_start_ns = 0;
  m.t_end_ns = 1'000'000'000;
  m.macro_step_ns = 10'000'000;
  return m;
}

inline cosim::step_request_t request_message() {
  cosim::step_request_t q{};
  q.session_id = kSession;
  q.participant = kName;
  q.step_index = 0;
  q.t_start_ns = 0;
  q.t_end_ns = 10'000'000;
  cosim::Polynomials in;
  for (const auto& p : ports()) in[p.name] = cosim::InputPolynomial::constant(p.kind, identity(p.kind));
  q.inputs = cosim::to_message(in);
  return q;
}

inline cosim::ready_t ready_message() {
  Model model;
  cosim::ParticipantCore core(kName, model);
  return *core.configure(configure_message());
}

}  // namespace fuzz
