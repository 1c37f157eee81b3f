// The oscillator halves' FMU interfaces: inputs and outputs as the native participants
// exchange them (mbs_adapters/oscillator), parameters with the native defaults
// (oscillator::Parameters, docs/config.md). OSCILLATOR_FMU_SIDE is 1 or 2 (one FMU each).
#include "../common/description.hpp"

#include "oscillator.hpp"

namespace fmu_export {

namespace {
using C = Causality;
using V = Variability;

Variable real(const std::string& name, fmi2ValueReference vr, C c, double start,
              const std::string& unit, const std::string& description,
              std::vector<std::string> depends_on = {}) {
  return Variable{name, Type::Real, vr, c, c == C::Parameter ? V::Fixed : V::Continuous, start, "", unit,
                  description, std::move(depends_on)};
}

Description make() {
  const oscillator::Parameters p;  // the native defaults
  Description d;
  d.can_get_and_set_state = true;
  d.can_interpolate_inputs = true;
  d.default_start = 0;
  d.default_stop = 1;
  d.default_step = 5e-4;
  const std::string inner = "inner step of the exact integrator; the communication step must be a multiple of it";
#if OSCILLATOR_FMU_SIDE == 1
  d.model_identifier = "oscillator_mass1";
  d.model_name = "oscillator_mass1";
  d.description =
      "Dual-mass oscillator, half 1: m1 x1'' = -c1 x1 - d1 x1' + force; input force, outputs x, v "
      "(soilcosim, mbs_adapters/oscillator)";
  d.variables = {
      real("force", 0, C::Input, 0, "N", "coupling force on mass 1"),
      real("x", 1, C::Output, 0, "m", "position of mass 1"),
      real("v", 2, C::Output, 0, "m/s", "velocity of mass 1"),
      real("mass", 10, C::Parameter, p.m1, "kg", "m1"),
      real("stiffness", 11, C::Parameter, p.c1, "N/m", "c1"),
      real("damping", 12, C::Parameter, p.d1, "N.s/m", "d1"),
      real("position", 13, C::Parameter, p.x1, "m", "x1 at the start time"),
      real("velocity", 14, C::Parameter, p.v1, "m/s", "v1 at the start time"),
      real("inner_step", 15, C::Parameter, 5e-6, "s", inner),
  };
#else
  d.model_identifier = "oscillator_mass2";
  d.model_name = "oscillator_mass2";
  d.description =
      "Dual-mass oscillator, half 2 with the coupling spring-damper: m2 x2'' = -c2 x2 - d2 x2' + Fc, "
      "Fc = cc (x - x2) + dc (v - v2); inputs x, v of mass 1, output force = -Fc on mass 1 "
      "(soilcosim, mbs_adapters/oscillator)";
  d.variables = {
      real("x", 0, C::Input, p.x1, "m", "position of mass 1 (start: the native coupled_position)"),
      real("v", 1, C::Input, p.v1, "m/s", "velocity of mass 1 (start: the native coupled_velocity)"),
      real("force", 2, C::Output, 0, "N", "coupling force on mass 1, -Fc", {"x", "v"}),
      real("mass", 10, C::Parameter, p.m2, "kg", "m2"),
      real("stiffness", 11, C::Parameter, p.c2, "N/m", "c2"),
      real("damping", 12, C::Parameter, p.d2, "N.s/m", "d2"),
      real("coupling_stiffness", 13, C::Parameter, p.cc, "N/m", "cc"),
      real("coupling_damping", 14, C::Parameter, p.dc, "N.s/m", "dc"),
      real("position", 15, C::Parameter, p.x2, "m", "x2 at the start time"),
      real("velocity", 16, C::Parameter, p.v2, "m/s", "v2 at the start time"),
      real("inner_step", 17, C::Parameter, 5e-6, "s", inner),
  };
#endif
  return d;
}
}  // namespace

const Description& description() {
  static const Description d = make();
  return d;
}

}  // namespace fmu_export
