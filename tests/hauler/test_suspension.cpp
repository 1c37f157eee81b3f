// The hydro-pneumatic strut alone on a rig (a sprung mass on one strut, the hauler's strut
// law): a step load gives the stroke and pressure of the gas law, the end stops hold, and the
// level control restores ride height at its set oil rate.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "hauler.hpp"

using namespace hauler;

namespace {

const double g = 9.81;
const double kMass = 21000;  // kg: the loaded front axle's sprung share
const double kStep = 5e-4;   // s: the rig's inner step (the law is under test, not the step)

// What the gas law says: pressure carries the load, p V^n = p_pre V_acc^n gives the gas volume,
// and the oil the circuit holds puts the stroke where V_gas = V_acc - oil + A s.
struct GasLaw {
  double pressure, gas_volume, stroke;
};
GasLaw gas_law(const Circuit& c, double force, double oil) {
  GasLaw r;
  r.pressure = force / c.piston_area;
  r.gas_volume = c.accumulator_volume * std::pow(c.precharge / r.pressure, 1 / c.polytropic);
  r.stroke = (r.gas_volume - c.accumulator_volume + oil) / c.piston_area;
  return r;
}

Suspension no_level() {
  Suspension s;
  s.level_control = false;
  return s;
}

}  // namespace

TEST(hauler_suspension, StepLoadGivesTheGasLawsStrokeAndPressure) {
  const Suspension s = no_level();
  const Circuit& c = s.front;
  const double oil = StrutRig::oil_for(c, kMass * g, s.ride_stroke);
  StrutRig rig(s, c, kMass, g, oil, kStep);
  const RigState r0 = rig.state();
  EXPECT_NEAR(r0.stroke, s.ride_stroke, 1e-9);
  EXPECT_NEAR(r0.pressure, kMass * g / c.piston_area, 1e-6 * r0.pressure);
  for (double step : {+40e3, -40e3}) {
    StrutRig r(s, c, kMass, g, oil, kStep);
    r.set_load([step](double t) { return t >= 0.1 ? step : 0.0; });
    r.advance(3.0);
    const RigState e = r.state();
    const GasLaw law = gas_law(c, kMass * g + step, oil);
    // the linear spring of the small-stroke stiffness n p A^2 / V would miss by several %
    const double k_lin = c.polytropic * r0.pressure * c.piston_area * c.piston_area /
                         gas_law(c, kMass * g, oil).gas_volume;
    const double linear = s.ride_stroke - step / k_lin;
    std::printf("step %+.0f N: stroke %.5f m (gas law %.5f, linear spring %.5f), pressure %.4f MPa "
                "(gas law %.4f)\n",
                step, e.stroke, law.stroke, linear, e.pressure / 1e6, law.pressure / 1e6);
    EXPECT_NEAR(e.stroke / law.stroke, 1.0, 0.01) << step;
    EXPECT_NEAR(e.pressure / law.pressure, 1.0, 0.01) << step;
    EXPECT_NEAR((e.stroke - s.ride_stroke) / (law.stroke - s.ride_stroke), 1.0, 0.01) << step;
    EXPECT_GT(std::abs(linear - law.stroke), 0.02 * std::abs(law.stroke - s.ride_stroke)) << step;
    EXPECT_NEAR(e.stroke_rate, 0.0, 1e-4);  // at rest
    EXPECT_EQ(e.end_stop, 0.0);
  }
}

// Pushed beyond the stroke both ways: the stops carry the difference with little
// penetration, equal to the stop force over the stop stiffness.
TEST(hauler_suspension, StrokeLimitsHold) {
  const Suspension s = no_level();
  const Circuit& c = s.front;
  const double oil = StrutRig::oil_for(c, kMass * g, s.ride_stroke);
  const double tolerance = 3e-3;  // m
  {  // unloaded: the gas pushes the strut to full extension (the rear after the discharge)
    StrutRig r(s, c, kMass, g, oil, kStep);
    r.set_load([](double t) { return t >= 0.1 ? -0.7 * kMass * g : 0.0; });
    r.advance(3.0);
    const RigState e = r.state();
    std::printf("extension stop: stroke %.5f m (limit %.3f), stop force %.0f N, pressure %.3f MPa\n",
                e.stroke, s.stroke, e.end_stop, e.pressure / 1e6);
    EXPECT_GT(e.stroke, s.stroke);
    EXPECT_LT(e.stroke, s.stroke + tolerance);
    EXPECT_LT(e.end_stop, 0);
    EXPECT_NEAR(e.stroke - s.stroke, -e.end_stop / s.end_stop_stiffness, 1e-6);
  }
  {  // overloaded: to full compression
    StrutRig r(s, c, kMass, g, oil, kStep);
    r.set_load([](double t) { return t >= 0.1 ? 2.5 * kMass * g : 0.0; });
    r.advance(3.0);
    const RigState e = r.state();
    std::printf("compression stop: stroke %.5f m, stop force %.0f N, pressure %.3f MPa\n", e.stroke,
                e.end_stop, e.pressure / 1e6);
    EXPECT_LT(e.stroke, 0);
    EXPECT_GT(e.stroke, -tolerance);
    EXPECT_GT(e.end_stop, 0);
    EXPECT_NEAR(-e.stroke, e.end_stop / s.end_stop_stiffness, 1e-6);
  }
}

// Oil missing (or in excess) for 6 cm of stroke: the level control fills (drains) at its set
// rate, so the stroke moves at level_rate / piston_area until the low-passed ride height is
// back inside the dead band.
TEST(hauler_suspension, LevelControlRestoresRideHeightAtItsRate) {
  const Suspension s;  // level control on
  const Circuit& c = s.front;
  const double expected = c.level_rate / c.piston_area;  // m/s
  for (double offset : {-0.06, +0.06}) {
    const double oil = StrutRig::oil_for(c, kMass * g, s.ride_stroke + offset);
    StrutRig r(s, c, kMass, g, oil, kStep);
    EXPECT_NEAR(r.state().stroke, s.ride_stroke + offset, 1e-9);
    r.advance(0.5);
    const RigState a = r.state();
    r.advance(2.5);
    const RigState b = r.state();
    const double rate = (b.stroke - a.stroke) / 2.0;
    std::printf("offset %+.2f m: stroke %.4f -> %.4f m, rate %.3f mm/s (set %.3f mm/s), flow %.2e m3/s\n",
                offset, a.stroke, b.stroke, 1e3 * rate, -1e3 * expected * (offset > 0 ? 1 : -1),
                b.flow);
    EXPECT_NEAR(rate / (offset < 0 ? expected : -expected), 1.0, 0.05) << offset;
    EXPECT_EQ(b.flow, offset < 0 ? c.level_rate : -c.level_rate);
    r.advance(9.0);
    const RigState e = r.state();
    std::printf("  at 9 s: stroke %.4f m, filtered %.4f m, flow %.1e\n", e.stroke, e.ride_filtered, e.flow);
    EXPECT_EQ(e.flow, 0.0);
    EXPECT_LE(std::abs(e.stroke - s.ride_stroke), s.dead_band);
    // the oil moved is what brought the stroke back (gas volume unchanged at the same load)
    EXPECT_NEAR((e.oil - oil) / c.piston_area, e.stroke - (s.ride_stroke + offset), 1e-4);
  }
}
