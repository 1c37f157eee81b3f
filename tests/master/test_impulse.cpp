// Impulse consistency of `use: average` (docs/stability.md, "Interval averages"): a noisy force
// source and a receiver that integrates the force polynomial it gets, in process. With interval
// averages the impulse received stays within the impulse still in flight of the one produced,
// however noisy the force; with end samples the noise at the sampled instants accumulates.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "config.hpp"
#include "cosimulation.hpp"

namespace {

constexpr double kInner = 1e-4;  // s, the source's inner step; 10 per macro step

// Deterministic noise in [-1, 1] for inner step k.
double noise(int64_t k) {
  uint64_t x = static_cast<uint64_t>(k) * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull;
  x ^= x >> 31;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 29;
  return static_cast<double>(x >> 11) / static_cast<double>(1ull << 52) - 1.0;
}

// Force source: F = sin(2 pi t) + 2 noise, constant over each inner step (so its interval mean
// is the mean of its inner values, exactly); keeps the impulse it produced.
class NoisySource final : public cosim::Model {
 public:
  std::vector<double> produced;  // integral of F over each step done
  void configure(const YAML::Node&, const cosim::RunInfo&) override {}
  cosim::Ports inputs() const override { return {}; }
  cosim::Ports outputs() const override { return {{"f", cosim::SignalKind::Scalar}}; }
  cosim::Duration inner_step() const override { return cosim::seconds_to_duration(kInner, "inner"); }
  cosim::Signals initial_outputs() override { return value(force(0)); }
  cosim::StepResult step(const cosim::StepInputs& in, bool want_average) override {
    const int n = static_cast<int>(in.length() / inner_step());
    double sum = 0, last = 0;
    for (int i = 0; i < n; ++i) {
      last = force(k_++);
      sum += last;
    }
    produced.push_back(sum * kInner);
    cosim::StepResult r;
    r.outputs = value(last);
    if (want_average) r.average = value(sum / n);
    return r;
  }

 private:
  static double force(int64_t k) { return std::sin(2 * M_PI * k * kInner) + 2 * noise(k); }
  static cosim::Signals value(double v) { return {{"f", {cosim::SignalKind::Scalar, {v}}}}; }
  int64_t k_ = 0;
};

// Motion side: integrates the received force polynomial over each step (H * its mean).
class Receiver final : public cosim::Model {
 public:
  std::vector<double> received;  // H * mean of the received polynomial, per step
  void configure(const YAML::Node&, const cosim::RunInfo&) override {}
  cosim::Ports inputs() const override { return {{"f", cosim::SignalKind::Scalar}}; }
  cosim::Ports outputs() const override { return {}; }
  cosim::Duration inner_step() const override { return cosim::seconds_to_duration(kInner, "inner"); }
  cosim::Signals initial_outputs() override { return {}; }
  cosim::StepResult step(const cosim::StepInputs& in, bool) override {
    received.push_back(cosim::to_seconds(in.length()) * in.polynomial("f").mean()[0]);
    return {};
  }
};

// The largest |impulse received - impulse produced| since the start, over the steps.
double run(const std::string& use, int order, double t_end) {
  YAML::Node root = YAML::Load(R"(
time: {end: 1.0, macro_step: 1.0e-3}
startup_iterations: 0  # these models cannot repeat a step (the master refuses iterations then)
participants: {src: null, dst: null}
connections: [{from: src.f, to: dst.f}]
)");
  for (const std::string& s : {"time.end=" + std::to_string(t_end), "connections.0.use=" + use,
                               "connections.0.predictor={order: " + std::to_string(order) + "}"})
    cosim::config::apply_override(root, s);
  const auto config = master::parse_config(root, "");
  NoisySource src;
  Receiver dst;
  cosim::ParticipantCore cs("src", src), cd("dst", dst);
  auto transport = cosim::make_in_process_transport(5, {{"src", &cs}, {"dst", &cd}});
  master::CoSimulation sim(config, *transport);
  sim.connect();
  sim.run();
  double difference = 0, worst = 0;
  for (std::size_t i = 0; i < src.produced.size(); ++i) {
    difference += dst.received.at(i) - src.produced[i];
    worst = std::max(worst, std::abs(difference));
  }
  return worst;
}

TEST(master_ImpulseConsistency, AveragesKeepTheImpulseOfANoisyForceEndSamplesDoNot) {
  const double H = 1e-3;
  for (int order : {0, 1, 2}) {
    const double da = run("average", order, 2.0), de = run("end", order, 2.0);
    std::printf("order %d, 2000 steps: largest |impulse received - produced|: average %.3e, end %.3e N s\n",
                order, da, de);
    // Averages: only the impulse in flight, a few steps of at most |F| <= 3 N.
    EXPECT_LT(da, (order + 2) * 3.0 * H) << "order " << order;
    // End samples: noise of about 1.15 N rms at each sampled instant, a random walk of
    // 1.15 H sqrt(N) (0.05 N s after 2000 steps).
    EXPECT_GT(de, 5 * da) << "order " << order;
  }
}

}  // namespace
