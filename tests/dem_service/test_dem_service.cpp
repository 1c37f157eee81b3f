// dem_service as a participant: repeated steps, refusals that leave it serving (in process),
// and over LCM with the prescribed participant: the same wrench history as dem_run when the
// macro step equals the DEM step, converging to it as the macro step shrinks.
#include <cosim/bus.hpp>
#include <cosim/participant_core.hpp>
#include <cosim/polynomial.hpp>
#include <cosim/yaml_config.hpp>
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "../oscillator/harness.hpp"
#include "dem/checkpoint.hpp"
#include "dem/service.hpp"

namespace {

using cosim::InputPolynomial;
using cosim::Polynomials;
using cosim::SignalKind;

constexpr std::int64_t kDt = 10'000;      // ns: the scene's dt, 1e-5 s
constexpr std::int64_t kMacro = 5 * kDt;  // ns: macro step of the in-process tests

std::string scene_path() { return harness::source("tests/dem_service/scene.yaml"); }

cosim::configure_t configure_message(const std::string& parameters = "") {
  cosim::configure_t c{};
  c.protocol_version = cosim::kProtocolVersion;
  c.session_id = 7;
  c.participant = "dem";
  c.t_start_ns = 0;
  c.t_end_ns = 1'000'000'000;
  c.macro_step_ns = kMacro;
  c.parameters_yaml = parameters;
  return c;
}

// Height where the blade's plate touches the top of a particle in the bed's fifth lattice
// layer: the blade is in contact from the first step on.
double plate_height() {
  static const double z = [] {
    YAML::Node root = cosim::config::load_file(scene_path());
    dem::ServiceModel m(root, harness::source("tests/dem_service"));
    for (std::size_t i = 0; i < m.state().size(); ++i) {
      const auto& x = m.state().x[i];
      if (x.z > 0.06 && x.z < 0.08 && x.x > 0.08 && x.x < 0.15)
        return x.z + m.state().radius[i] - 1e-4;  // resting 0.1 mm deep on its top
    }
    return 0.07;
  }();
  return z;
}

// The blade pushed through the bed at 2 m/s (a particle diameter in 5 ms).
cosim::Value blade_pose(std::int64_t t_ns, double dz = 0) {
  const double s = cosim::to_seconds(cosim::time_point_ns(t_ns));
  return cosim::Kinematics{{0.05 + 2 * s, 0.05, plate_height() + dz}, {1, 0, 0, 0}, {2, 0, 0}, {}}
      .to_value();
}

cosim::step_request_t request(int64_t step, double dz = 0, int iteration = 0) {
  cosim::step_request_t q{};
  q.session_id = 7;
  q.participant = "dem";
  q.step_index = step;
  q.iteration = iteration;
  q.t_start_ns = step * kMacro;
  q.t_end_ns = (step + 1) * kMacro;
  Polynomials in;
  in["blade"] = cosim::fit_polynomial(SignalKind::Kinematics, {0.0, 1.0},
                                      {blade_pose(q.t_start_ns, dz), blade_pose(q.t_end_ns, dz)}, 1, 0);
  q.inputs = cosim::to_message(in);
  return q;
}

struct Service {
  std::unique_ptr<dem::ServiceModel> model;
  std::unique_ptr<cosim::ParticipantCore> core;
  explicit Service(const std::string& parameters = "") {
    model = std::make_unique<dem::ServiceModel>(cosim::config::load_file(scene_path()),
                                                harness::source("tests/dem_service"));
    core = std::make_unique<cosim::ParticipantCore>("dem", *model);
    auto ready = core->configure(configure_message(parameters));
    EXPECT_TRUE(ready && ready->ok) << (ready ? ready->error : "no answer");
  }
  cosim::step_reply_t step(const cosim::step_request_t& q) {
    auto r = core->handle(q);
    EXPECT_TRUE(r.has_value());
    return r ? *r : cosim::step_reply_t{};
  }
};

cosim::Value wrench(const cosim::step_reply_t& r) {
  return cosim::from_message(r.outputs, "reply").at("blade").value;
}

double diagnostic(const cosim::step_reply_t& r, const std::string& name) {
  for (const auto& d : r.diagnostics)
    if (d.name == name) return d.value;
  ADD_FAILURE() << "no diagnostic " << name;
  return NAN;
}

}  // namespace

TEST(DemService, DeclaresOneKinematicInputAndOneWrenchOutputPerTool) {
  Service s;
  const auto in = s.model->inputs(), out = s.model->outputs();
  ASSERT_EQ(in.size(), 1u);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(in[0].name, "blade");
  EXPECT_EQ(in[0].kind, SignalKind::Kinematics);
  EXPECT_EQ(out[0].name, "blade");
  EXPECT_EQ(out[0].kind, SignalKind::Wrench);
  EXPECT_EQ(s.model->inner_step(), cosim::nanoseconds(kDt));
}

TEST(DemService, RepeatedStepIsBitIdenticalAndOtherInputsEqualAFreshRun) {
  // Step until, after some history, the blade carries a force: that step is repeated.
  Service a;
  cosim::step_reply_t last;
  int k = 0;
  for (;; ++k) {
    last = a.step(request(k));
    ASSERT_EQ(last.status, cosim::step_reply_t::OK) << last.message;
    if (k >= 10 && std::abs(cosim::Wrench::from_value(wrench(last)).force[0]) > 1.0) break;
    ASSERT_LT(k, 400) << "the blade never touched the bed again";
  }
  EXPECT_GT(diagnostic(last, "boundary_contacts"), 0);
  EXPECT_GT(diagnostic(last, "particle_contacts"), 10);
  EXPECT_GT(diagnostic(last, "max_overlap"), 0);
  EXPECT_GT(diagnostic(last, "kinetic_energy"), 0);

  // The same step again, a new iteration with identical inputs: the same reply, bit for bit.
  const auto again = a.step(request(k, 0, 1));
  ASSERT_EQ(again.status, cosim::step_reply_t::OK) << again.message;
  EXPECT_EQ(wrench(again), wrench(last));
  EXPECT_EQ(diagnostic(again, "particle_contacts"), diagnostic(last, "particle_contacts"));

  // Other inputs for the same step: the result of a fresh run that took those inputs.
  const auto other = a.step(request(k, -0.001, 2));
  ASSERT_EQ(other.status, cosim::step_reply_t::OK) << other.message;
  EXPECT_NE(wrench(other), wrench(last));
  Service b;
  for (int j = 0; j < k; ++j) ASSERT_EQ(b.step(request(j)).status, cosim::step_reply_t::OK);
  const auto fresh = b.step(request(k, -0.001));
  EXPECT_EQ(wrench(other), wrench(fresh));
  // And the run goes on from the accepted step.
  EXPECT_EQ(wrench(a.step(request(k + 1))), wrench(b.step(request(k + 1))));
}

// The interval average (want_average) is the mean of the DEM steps' wrenches about one point:
// each step's torque is about that step's own reference point, which moves with the tool, so
// the service moves every step's torque to a common point before averaging. Checked against a
// service whose macro step is the DEM step, whose replies are those steps' wrenches.
TEST(DemService, IntervalAverageIsTheMeanOfTheDemStepsWrenchesAboutOnePoint) {
  const auto step_request = [](std::int64_t t0, std::int64_t t1, std::int64_t index, bool average) {
    cosim::step_request_t q{};
    q.session_id = 7;
    q.participant = "dem";
    q.step_index = index;
    q.t_start_ns = t0;
    q.t_end_ns = t1;
    q.want_average = average;
    Polynomials in;
    in["blade"] = cosim::fit_polynomial(SignalKind::Kinematics, {0.0, 1.0},
                                        {blade_pose(t0), blade_pose(t1)}, 1, 0);
    q.inputs = cosim::to_message(in);
    return q;
  };
  Service coarse;  // macro step 5 dt
  dem::ServiceModel fine_model(cosim::config::load_file(scene_path()), harness::source("tests/dem_service"));
  cosim::ParticipantCore fine("dem", fine_model);
  auto cfg = configure_message();
  cfg.macro_step_ns = kDt;
  auto ready = fine.configure(cfg);
  ASSERT_TRUE(ready && ready->ok) << (ready ? ready->error : "no answer");
  const int n = static_cast<int>(kMacro / kDt);
  std::int64_t fine_index = 0;
  for (int k = 0;; ++k) {
    const std::int64_t t0 = k * kMacro, t1 = t0 + kMacro;
    const auto r = coarse.step(step_request(t0, t1, k, true));
    ASSERT_EQ(r.status, cosim::step_reply_t::OK) << r.message;
    ASSERT_TRUE(r.has_average);
    std::vector<cosim::Wrench> steps;
    for (int j = 0; j < n; ++j, ++fine_index) {
      auto q = fine.handle(step_request(t0 + j * kDt, t0 + (j + 1) * kDt, fine_index, false));
      ASSERT_TRUE(q && q->status == cosim::step_reply_t::OK);
      steps.push_back(cosim::Wrench::from_value(cosim::from_message(q->outputs, "reply").at("blade").value));
    }
    const auto avg = cosim::Wrench::from_value(cosim::from_message(r.average, "average").at("blade").value);
    if (k < 10 || std::abs(avg.force[0]) < 1.0) {
      ASSERT_LT(k, 400) << "the blade never touched the bed";
      continue;
    }
    cosim::Vec3 F{}, T{};
    for (const auto& w : steps) {
      const cosim::Wrench about = w.shifted_to(avg.point);
      for (int a = 0; a < 3; ++a) {
        F[a] += about.force[a] / n;
        T[a] += about.torque[a] / n;
      }
    }
    // The reference point of the average is the last DEM step's, like the end sample's.
    EXPECT_EQ(avg.point, steps.back().point);
    // The two services took their poses from different polynomials (rounding apart); the
    // torque of the old average (each step's torque about its own point) was off by
    // |r_j - r_end| |F| ~ 1e-4 m |F|, 1e-3 of the torque here.
    const double tnorm = std::sqrt(T[0] * T[0] + T[1] * T[1] + T[2] * T[2]);
    const double fnorm = std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(avg.force[a], F[a], 1e-7 * fnorm) << a;
      EXPECT_NEAR(avg.torque[a], T[a], 1e-7 * tnorm) << a;
    }
    break;
  }
}

TEST(DemService, BadStepsAreRefusedAndTheServiceKeepsServing) {
  Service s;
  ASSERT_EQ(s.step(request(0)).status, cosim::step_reply_t::OK);

  auto q = request(1);
  q.t_end_ns = q.t_start_ns + kDt * 3 / 2;  // not a multiple of dt
  auto r = s.step(q);
  EXPECT_EQ(r.status, cosim::step_reply_t::REJECTED);
  EXPECT_NE(r.message.find("not a multiple of the inner step 10000 ns"), std::string::npos) << r.message;

  q = request(1);  // a tool the scene does not know
  {
    Polynomials in;
    in["shovel"] = cosim::InputPolynomial::constant(SignalKind::Kinematics, blade_pose(q.t_start_ns));
    q.inputs = cosim::to_message(in);
  }
  r = s.step(q);
  EXPECT_EQ(r.status, cosim::step_reply_t::REJECTED);
  EXPECT_NE(r.message.find("shovel"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("blade"), std::string::npos) << r.message;

  q = request(1);  // a pose whose quaternion is not a unit one
  q.inputs.kinematics[0].orientation_reference[0] = 2.0;
  r = s.step(q);
  EXPECT_EQ(r.status, cosim::step_reply_t::REJECTED);
  EXPECT_NE(r.message.find("quaternion"), std::string::npos) << r.message;

  q = request(1);  // NaN in the pose
  q.inputs.kinematics[0].position[0][2] = NAN;
  r = s.step(q);
  EXPECT_EQ(r.status, cosim::step_reply_t::REJECTED);
  EXPECT_NE(r.message.find("NaN"), std::string::npos) << r.message;

  // Still serving, and the refused requests changed nothing: equal to an undisturbed run.
  const auto ok = s.step(request(1));
  EXPECT_EQ(ok.status, cosim::step_reply_t::OK) << ok.message;
  Service clean;
  clean.step(request(0));
  EXPECT_EQ(wrench(ok), wrench(clean.step(request(1))));
}

// Steps the master will not redo (step_request_t.no_redo, an explicit scheme after its start-up)
// keep no copy of the state: the same bits as steps that keep one, on 1 and 2 threads and
// through the master's checkpoint and a resume; a redo asked anyway is refused and the service
// goes on as before.
TEST(DemService, StepsWithoutRedoKeepNoSnapshotAndGiveTheSameBits) {
  auto same_state = [](const dem::State& a, const dem::State& b) {
    auto bytes = [](const auto& u, const auto& v) {
      return u.size() == v.size() &&
             (u.empty() || std::memcmp(u.data(), v.data(), u.size() * sizeof(u[0])) == 0);
    };
    return a.step == b.step && bytes(a.x, b.x) && bytes(a.v, b.v) && bytes(a.u, b.u) && bytes(a.id, b.id) &&
           bytes(a.pair_offset, b.pair_offset) && bytes(a.pair_j, b.pair_j) &&
           bytes(a.pair_spring, b.pair_spring) && bytes(a.slot_key, b.slot_key) &&
           bytes(a.slot_spring, b.slot_spring) && bytes(a.rest_steps, b.rest_steps) && bytes(a.w, b.w);
  };
  for (const int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    // min_particles_per_thread 1: the 1500 grains really run on 2 threads.
    const std::string p = "{scene.threads: " + std::to_string(threads) +
                          ", performance.min_particles_per_thread: 1}";
    const std::string folder = harness::temp_path("_no_redo_" + std::to_string(threads));
    std::filesystem::remove_all(folder);
    auto make = [&](std::unique_ptr<dem::ServiceModel>& model, std::int64_t resume) {
      model = std::make_unique<dem::ServiceModel>(cosim::config::load_file(scene_path()),
                                                  harness::source("tests/dem_service"));
      auto core = std::make_unique<cosim::ParticipantCore>("dem", *model);
      auto c = configure_message(p);
      c.checkpoint_folder = folder;
      c.run_id = 0x77;
      c.resume_steps_done = resume;
      c.resume_t_ns = resume * kMacro;
      auto ready = core->configure(c);
      EXPECT_TRUE(ready && ready->ok) << (ready ? ready->error : "no answer");
      return core;
    };
    std::unique_ptr<dem::ServiceModel> ma, mb, mc;  // outlive the cores
    auto a = make(ma, 0), b = make(mb, 0);
    std::vector<cosim::Value> wa;
    // On until the blade carries a force (the bed settles first), then the checkpoint two steps
    // later and six steps more.
    int kCheckpoint = -1, kSteps = 400;
    for (int k = 0; k < kSteps; ++k) {
      auto qa = request(k), qb = request(k);
      qb.no_redo = k > 0;
      qb.checkpoint = k == kCheckpoint;
      auto ra = a->handle(qa), rb = b->handle(qb);
      ASSERT_TRUE(ra && rb);
      ASSERT_EQ(ra->status, cosim::step_reply_t::OK) << ra->message;
      ASSERT_EQ(rb->status, cosim::step_reply_t::OK) << rb->message;
      if (k == 0) {  // the start-up iteration: redone from the snapshot in both
        ra = a->handle(request(0, 0, 1)), rb = b->handle(request(0, 0, 1));
        ASSERT_TRUE(ra && rb && ra->status == cosim::step_reply_t::OK && rb->status == cosim::step_reply_t::OK);
      }
      wa.push_back(wrench(*ra));
      ASSERT_EQ(wrench(*rb), wa.back()) << "step " << k;
      if (kCheckpoint < 0 && k >= 10 && std::abs(cosim::Wrench::from_value(wa.back()).force[0]) > 1.0) {
        kCheckpoint = k + 2;
        kSteps = k + 9;
      }
    }
    ASSERT_GT(kCheckpoint, 0) << "the blade never touched the bed";
    EXPECT_GT(std::abs(cosim::Wrench::from_value(wa.back()).force[0]), 1.0) << "the blade must push the bed";
    EXPECT_TRUE(same_state(ma->state(), mb->state()));
    // A redo of a step sent with no_redo: refused, nothing changed.
    auto redo = b->handle(request(kSteps - 1, 0, 1));
    ASSERT_TRUE(redo);
    EXPECT_EQ(redo->status, cosim::step_reply_t::REJECTED);
    EXPECT_NE(redo->message.find("cannot be redone: the state at its start was not kept"), std::string::npos)
        << redo->message;
    EXPECT_TRUE(same_state(ma->state(), mb->state()));
    // Resumed from the checkpoint written after step kCheckpoint, on with no_redo steps.
    auto c = make(mc, kCheckpoint + 1);
    for (int k = kCheckpoint + 1; k <= kSteps; ++k) {
      auto qc = request(k);
      qc.no_redo = true;
      auto rc = c->handle(qc);
      ASSERT_TRUE(rc);
      ASSERT_EQ(rc->status, cosim::step_reply_t::OK) << rc->message;
      if (k < kSteps) {
        EXPECT_EQ(wrench(*rc), wa[static_cast<std::size_t>(k)]) << "resumed, step " << k;
      } else {  // one step past the rest: all three alike
        auto ra = a->handle(request(k));
        auto qb = request(k);
        qb.no_redo = true;
        auto rb = b->handle(qb);
        ASSERT_TRUE(ra && rb);
        EXPECT_EQ(wrench(*rb), wrench(*ra));
        EXPECT_EQ(wrench(*rc), wrench(*ra));
      }
    }
    EXPECT_TRUE(same_state(ma->state(), mc->state()));
    EXPECT_TRUE(same_state(ma->state(), mb->state()));
    c->end_session(true);
    b->end_session(true);
    std::filesystem::remove_all(folder);
  }
}

TEST(DemService, WritesPeriodicCheckpointsThatRestoreTheState) {
  const std::string file = harness::temp_path("_checkpoint.h5");
  std::remove(file.c_str());
  // Every 1e-4 s of co-simulation time, i.e. after every second macro step of 5e-5 s.
  Service s("{service.checkpoint_every: 1.0e-4, service.checkpoint: " + file + "}");
  for (int k = 0; k < 3; ++k) ASSERT_EQ(s.step(request(k)).status, cosim::step_reply_t::OK);
  const dem::State at_2 = dem::load_checkpoint(file);  // written after step 1 (t = 1e-4 s)
  ASSERT_EQ(s.step(request(3)).status, cosim::step_reply_t::OK);
  const dem::State at_4 = dem::load_checkpoint(file);  // overwritten after step 3 (t = 2e-4 s)
  EXPECT_EQ(at_4.step, s.model->state().step);
  EXPECT_EQ(at_4.step, at_2.step + 10);  // two macro steps of five DEM steps later
  ASSERT_EQ(at_4.x.size(), s.model->state().x.size());
  for (std::size_t i = 0; i < at_4.x.size(); ++i) {
    ASSERT_EQ(at_4.x[i].x, s.model->state().x[i].x);
    ASSERT_EQ(at_4.v[i].z, s.model->state().v[i].z);
  }
}

TEST(DemService, BadConfigsAreRefusedAtStartWithTheKeyNamed) {
  auto refused = [](const std::string& key_value, const std::string& expect) {
    YAML::Node root = cosim::config::load_file(scene_path());
    cosim::config::apply_override(root, key_value);
    try {
      dem::ServiceModel m(root, harness::source("tests/dem_service"));
      ADD_FAILURE() << key_value << " was accepted";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << key_value << ": " << e.what();
    }
  };
  refused("service.snapshots=true", "service.snapshots: unknown key");
  refused("settle.max_time=1", "settle with dem_run");
  refused("scene.dt=1.00000001e-5", "whole number of nanoseconds");
  refused("tools=[]", "no tool");
  refused("scene.dt=1e-4", "scene.dt");  // above the largest safe dt
  refused("service.checkpoint_every=0.01", "service.checkpoint");
}

// Over LCM: dem_service + prescribed + cosim_master against dem_run on the same scene and
// trajectory, over the first 15 ms of blade contact. The reply's wrench is the force of the
// last DEM step of the macro step (evaluated at t_end - dt, docs/dem_service.md), so the
// co-simulation's wrench at macro time t_i+1 is compared with dem_run's at t_i+1 - dt.
namespace {

constexpr double kEnd = 0.015;

struct Series {
  std::vector<double> fx, fy, fz;  // per sample
};

Series dem_run_wrenches() {
  static const Series s = [] {
    const std::string h5 = harness::temp_path("_dem_run.h5");
    harness::Process p = harness::spawn({harness::bin("dem_run"), scene_path(), "--output", h5,
                                         "--set", "run.duration=" + std::to_string(kEnd)},
                                        h5 + ".log");
    EXPECT_EQ(harness::wait_for(p, 120), 0) << harness::read_text(h5 + ".log");
    const auto rows = harness::read_dataset(h5, "tools/blade/samples");  // 14 columns
    Series out;
    for (std::size_t i = 0; i + 14 <= rows.size(); i += 14) {
      out.fx.push_back(rows[i + 1]);
      out.fy.push_back(rows[i + 2]);
      out.fz.push_back(rows[i + 3]);
    }
    return out;
  }();
  return s;
}

// Largest difference of the co-simulation's wrench from dem_run's at the same force times,
// relative to dem_run's largest force; macro step = `inner` DEM steps.
double cosim_error(int inner) {
  const Series ref = dem_run_wrenches();
  const std::string h5 = harness::temp_path("_H" + std::to_string(inner) + ".h5");
  const int code = harness::run_master(
      {"time.end=" + std::to_string(kEnd), "time.macro_step=" + std::to_string(inner * 1e-5)}, h5,
      300, "tests/dem_service/cosim.yaml");
  EXPECT_EQ(code, 0) << harness::read_text(h5 + ".log");
  const auto w = harness::read_dataset(h5, "participants/dem/outputs/blade");  // 9 columns
  double peak = 0, diff = 0;
  for (std::size_t k = 0; k < ref.fx.size(); ++k)
    peak = std::max({peak, std::abs(ref.fx[k]), std::abs(ref.fy[k]), std::abs(ref.fz[k])});
  const std::size_t rows = w.size() / 9;
  EXPECT_EQ(rows, ref.fx.size() / inner + 1);
  for (std::size_t i = 1; i < rows; ++i) {
    const std::size_t k = i * inner - 1;  // dem_run's sample at t_i - dt
    diff = std::max({diff, std::abs(w[9 * i] - ref.fx[k]), std::abs(w[9 * i + 1] - ref.fy[k]),
                     std::abs(w[9 * i + 2] - ref.fz[k])});
  }
  EXPECT_GT(peak, 100.0) << "the blade must meet the bed";
  return diff / peak;
}

}  // namespace

TEST(DemServiceOverLcm, MacroStepEqualToTheDemStepReproducesDemRun) {
  const double e = cosim_error(1);
  std::printf("macro step = dt: largest wrench difference from dem_run %.3g of the peak\n", e);
  // Only rounding differs (the predictor's polynomial fit of the poses),
  // grown by the bed's chaotic dynamics: 2e-13 measured; a real mismatch (one step of lag,
  // a wrong pose) gives 1e-3 and more.
  EXPECT_LT(e, 1e-9);
}

TEST(DemServiceOverLcm, WrenchConvergesToDemRunAsTheMacroStepShrinks) {
  std::vector<double> errors;
  for (int inner : {2, 5, 10, 20}) {
    errors.push_back(cosim_error(inner));
    std::printf("macro step = %2d dt: largest wrench difference from dem_run %.3g of the peak\n",
                inner, errors.back());
  }
  for (std::size_t i = 1; i < errors.size(); ++i) EXPECT_LT(errors[i - 1], errors[i]);
  EXPECT_LT(errors.front(), 1e-3);
  // Linear kinematic prediction: the pose error per step goes as H^2; over a decade of H the
  // measured error falls by more than a decade.
  EXPECT_GT(errors.back() / errors.front(), 10.0);
}

// The defaults of the `service` section in docs/dem_service.md are the code's: setting a key to
// its documented default gives the same options as leaving the key out ("none" = leave it out).
namespace {

std::string describe(const dem::ServiceOptions& o) {
  std::ostringstream out;
  out.precision(17);
  out << o.snapshot << ' ' << o.checkpoint_every << " '" << o.checkpoint << "' " << o.report_every;
  return out.str();
}

std::string read_with(const std::string& set) {
  YAML::Node root = YAML::Load("service: {}");
  if (!set.empty()) cosim::config::apply_override(root, set);
  return describe(dem::read_service_options(root));
}

}  // namespace

TEST(DemService, DocumentedServiceDefaultsAreTheCodes) {
  std::ifstream in(harness::source("docs/dem_service.md"));
  ASSERT_TRUE(in) << "cannot read docs/dem_service.md";
  const std::regex row(R"(^\| `(service\.[a-z_]+)` \|.*\| (`([^`]*)`|none) \|$)");
  const std::string base = read_with("");
  int rows = 0;
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (!std::regex_match(line, m, row)) continue;
    ++rows;
    if (m[2] == "none") continue;  // no value to set: the key is optional without a default
    EXPECT_EQ(read_with(m[1].str() + "=" + m[3].str()), base)
        << "docs/dem_service.md documents `" << m[1] << "` = `" << m[3]
        << "`, but the code's default differs";
  }
  EXPECT_EQ(rows, 4) << "the table of the `service` section in docs/dem_service.md changed";
  // The comparison can fail: a value other than the default changes the options.
  EXPECT_NE(read_with("service.report_every=11"), base);
  EXPECT_NE(read_with("service.snapshot=false"), base);
}
