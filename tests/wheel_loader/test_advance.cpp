// The machine layer's advance (mbs_adapters/common/machine.cpp): the state moved into the
// integrator and back instead of copied, and a warm restart instead of Integrator::initialize
// at every macro step, must give the same bits as the plain path kept beside it
// (Machine::advance_reference: copy in, Integrator::initialize, copy out). Two machines built
// alike are driven with the same changing wrench, one by each path, through what the adapter
// and the FMU do between steps (a snapshot and a redo, saved states, a checkpoint loaded into a
// fresh machine, interval averages from every inner step); every output is compared bit for
// bit after every macro step. The hauler shares the layer and is held to the same.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "hauler.hpp"
#include "wheel_loader.hpp"

namespace {

constexpr double kH = 1e-3;  // the main job's macro step

// The doubles of a kinematics, a report, ... appended to one vector for a bitwise compare.
void put(std::vector<double>& out, const cosim::Kinematics& k) {
  const cosim::Value v = k.to_value();
  out.insert(out.end(), v.begin(), v.end());
}
void put(std::vector<double>& out, const mbs::V3& v) { out.insert(out.end(), v.begin(), v.end()); }

std::vector<double> outputs(const wheel_loader::WheelLoader& m) {
  std::vector<double> o;
  put(o, m.bucket());
  const wheel_loader::Reports r = m.reports();
  for (double x : {r.a_long, r.a_vert, r.j_long, r.j_vert, r.lift_force, r.tilt_force, r.lift_length,
                   r.tilt_length, r.speed, r.x_machine, r.drive_force, r.normal_load, r.normal_front,
                   r.normal_rear, r.boom_angle, r.bucket_pitch, r.pitch, r.heave})
    o.push_back(x);
  put(o, m.cutting_edge());
  const wheel_loader::Dynamics d = m.dynamics();
  for (const auto* b : {&d.frame, &d.boom, &d.crank, &d.link, &d.bucket}) {
    put(o, b->com_acceleration);
    put(o, b->angular_acceleration);
  }
  for (const auto* p : {&d.a_pin, &d.j_pin, &d.boom_pivot, &d.crank_pivot, &d.link_pin}) {
    put(o, p->force);
    put(o, p->moment);
  }
  o.push_back(m.max_acceleration());
  o.push_back(m.time());
  return o;
}

std::vector<double> outputs(const hauler::Hauler& m) {
  std::vector<double> o;
  put(o, m.body());
  const hauler::Reports r = m.reports();
  for (double x : {r.hoist_force, r.hoist_length, r.body_angle, r.pitch, r.heave, r.x_machine, r.speed,
                   r.kinetic_energy, r.front.pressure, r.rear.pressure, r.front.oil, r.rear.oil,
                   r.front.ride_filtered, r.rear.ride_filtered})
    o.push_back(x);
  o.push_back(m.max_acceleration());
  o.push_back(m.time());
  return o;
}

// Bitwise equality of two output vectors (a NaN equals itself); names the first that differs.
::testing::AssertionResult same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size()) return ::testing::AssertionFailure() << a.size() << " vs " << b.size() << " outputs";
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::memcmp(&a[i], &b[i], sizeof(double)) != 0)
      return ::testing::AssertionFailure() << "output " << i << ": " << a[i] << " vs " << b[i] << " (differ by "
                                           << a[i] - b[i] << ")";
  return ::testing::AssertionSuccess();
}

// A soil-like wrench for macro step k on a machine whose coupled body is at `at`: a resisting
// force that grows and wobbles, linear in time within the step (like an order-1 predictor), a
// torque, and the reference point at the body (as the DEM reports it).
mbs::WrenchInput wrench_for(double t0, int k, const mbs::V3& at, double scale) {
  const double a = scale * (0.2 + 0.8 * std::sin(0.7 * k * kH * 10)), b = scale * 0.3 * std::cos(0.013 * k);
  return [=](double t) {
    const double s = (t - t0) / kH;
    mbs::Wrench w;
    w.force = {-a * (1 + 0.1 * s), 0.02 * b, 0.4 * a + b * s};
    w.torque = {0.01 * b, 0.3 * a * (1 - 0.2 * s), 0};
    w.point = at;
    return w;
  };
}

// Drives `fast` (advance) and `ref` (advance_reference) alike through `steps` macro steps from
// their common start, comparing every output after every step; between steps both go through
// a snapshot and a redo (every 7th step), a saved state set back (every 11th), the interval
// averages' per-inner-step callback (every 5th), and at `checkpoint_at` each is saved to a
// checkpoint file and continued by a fresh machine loaded from it (make()).
template <class M>
void drive_alike(const std::function<std::unique_ptr<M>()>& make, int steps, double scale, int checkpoint_at,
                 const std::string& tag) {
  std::unique_ptr<M> fast = make(), ref = make();
  ASSERT_TRUE(same_bits(outputs(*fast), outputs(*ref))) << "the two machines are built alike";
  const double t0 = fast->time();
  int compared = 0, sampled_steps = 0;
  long inner_samples = 0;
  for (int k = 0; k < steps; ++k) {
    const double t_end = t0 + (k + 1) * kH;
    const double t_start = t_end - kH;
    auto set = [&](M& m) { m.set_wrench(wrench_for(t_start, k, m.coupled_body().position, scale)); };
    if (k % 7 == 3) {  // a step that is redone from its snapshot with another input, then the same
      for (M* m : {fast.get(), ref.get()}) {
        m->save_snapshot();
        m->set_wrench(wrench_for(t_start, k + 50, m->coupled_body().position, 2 * scale));
      }
      fast->advance(t_end);
      ref->advance_reference(t_end);
      ASSERT_TRUE(same_bits(outputs(*fast), outputs(*ref))) << tag << ": the redone step " << k;
      fast->restore_snapshot();
      ref->restore_snapshot();
    }
    std::shared_ptr<const void> saved_fast, saved_ref;
    if (k % 11 == 5) {  // a saved state set back after a step it is not part of (an FMU's state)
      saved_fast = fast->copy_state();
      saved_ref = ref->copy_state();
      set(*fast);
      set(*ref);
      fast->advance(t_end);
      ref->advance_reference(t_end);
      fast->set_state(saved_fast);
      ref->set_state(saved_ref);
    }
    set(*fast);
    set(*ref);
    if (k % 5 == 2) {  // interval averages: a sample after every inner step
      std::vector<double> a, b;
      fast->advance(t_end, [&] { put(a, fast->coupled_body()); });
      ref->advance_reference(t_end, [&] { put(b, ref->coupled_body()); });
      ASSERT_TRUE(same_bits(a, b)) << tag << ": the inner steps of step " << k;
      inner_samples += static_cast<long>(a.size() / 13);
      ++sampled_steps;
    } else {
      fast->advance(t_end);
      ref->advance_reference(t_end);
    }
    ASSERT_TRUE(same_bits(outputs(*fast), outputs(*ref))) << tag << ": after step " << k << ", t = " << t_end;
    ++compared;
    if (k == checkpoint_at) {  // a checkpoint resumed by a fresh process: a machine never advanced
      const std::string pf = std::string(TEST_TMP_DIR) + "/" + tag + "_fast.state",
                        pr = std::string(TEST_TMP_DIR) + "/" + tag + "_ref.state";
      fast->save_state(pf);
      ref->save_state(pr);
      fast = make();
      ref = make();
      fast->load_state(pf);
      ref->load_state(pr);
      std::remove(pf.c_str());
      std::remove(pr.c_str());
    }
  }
  EXPECT_EQ(compared, steps);
  // the callback ran once after every inner step of the sampled steps
  EXPECT_EQ(inner_samples, sampled_steps * std::lround(kH / fast->inner_step()));
  EXPECT_GT(sampled_steps, 0);
}

}  // namespace

// The linkage moves (the tilt cylinder's first pulse starts at 2 s), the bucket is pushed by a
// wrench of a digging bucket's size (up to about 250 kN): the closed Z-bar loop is projected at
// every restart and every inner step.
TEST(WheelLoaderAdvance, TheWarmRestartWithoutCopiesIsTheReferenceAdvanceBitForBit) {
  wheel_loader::Parameters p;
  auto make = [&] { return std::make_unique<wheel_loader::WheelLoader>(p, 1.95); };
  drive_alike<wheel_loader::WheelLoader>(make, 150, 2.5e5, 90, "wheel_loader");
  // the path did move the machine: the bucket turned and the machine drove on
  wheel_loader::WheelLoader a(p, 1.95), b(p, 1.95);
  const double pitch0 = a.reports().bucket_pitch, x0 = a.reports().x_machine;
  for (int k = 0; k < 150; ++k) {
    a.set_wrench(wrench_for(1.95 + k * kH, k, a.bucket().position, 2.5e5));
    a.advance(1.95 + (k + 1) * kH);
  }
  EXPECT_GT(std::abs(a.reports().bucket_pitch - pitch0), 1e-3);
  EXPECT_GT(a.reports().x_machine - x0, 0.1);  // about 1 m/s, slowed by the push
  EXPECT_LT(a.reports().x_machine - x0, 0.2);
}

// A machine with its own state variables (the struts' oil and filtered ride height, z) and no
// closed loop.
TEST(WheelLoaderAdvance, TheHaulerOnTheSameLayerIsTheReferenceAdvanceBitForBit) {
  hauler::Parameters p;
  auto make = [&] { return std::make_unique<hauler::Hauler>(p, 0.0); };
  drive_alike<hauler::Hauler>(make, 60, 1e5, 40, "hauler");
}

// An advance that is not a whole number of inner steps is refused before anything moves: the
// state is the one it was, and the next advance is the reference's.
TEST(WheelLoaderAdvance, ARefusedAdvanceLeavesTheStateAndTheNextStepIsTheReferences) {
  wheel_loader::Parameters p;
  wheel_loader::WheelLoader fast(p, 0.0), ref(p, 0.0);
  fast.advance(kH);
  ref.advance_reference(kH);
  const std::vector<double> before = outputs(fast);
  EXPECT_THROW(fast.advance(kH + 0.5 * p.inner_step), std::invalid_argument);
  EXPECT_TRUE(same_bits(outputs(fast), before));
  fast.advance(2 * kH);
  ref.advance_reference(2 * kH);
  EXPECT_TRUE(same_bits(outputs(fast), outputs(ref)));
}
