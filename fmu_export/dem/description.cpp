// dem_fmu's interface: the tool's pose and twist in, the soil's wrench on it out, and where
// to find the running dem_service (docs/fmi.md, "Driving the DEM from another FMI master").
#include "../common/description.hpp"

namespace fmu_export {

namespace {
using C = Causality;
using V = Variability;

Description make() {
  Description d;
  d.model_identifier = "dem_fmu";
  d.model_name = "dem_fmu";
  d.description =
      "Client of a running dem_service (soilcosim): each doStep sends the tool's pose and twist "
      "over LCM and returns the wrench of the soil on the tool (docs/fmi.md)";
  d.can_get_and_set_state = true;  // back to the start of the last step only (docs/fmi.md)
  d.can_interpolate_inputs = true;
  d.default_start = 0;
  d.default_stop = 1;
  d.default_step = 1e-3;
  auto in = [&](const std::string& name, fmi2ValueReference vr, double start, const std::string& unit,
                const std::string& what) {
    d.variables.push_back({name, Type::Real, vr, C::Input, V::Continuous, start, "", unit, what, {}});
  };
  auto out = [&](const std::string& name, fmi2ValueReference vr, const std::string& unit, const std::string& what) {
    d.variables.push_back({name, Type::Real, vr, C::Output, V::Continuous, 0, "", unit, what, {}});
  };
  const char* axes[] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a)
    in(std::string("position_") + axes[a], a, 0, "m", "tool reference point, ground frame");
  const char* q[] = {"w", "x", "y", "z"};
  for (int a = 0; a < 4; ++a)
    in(std::string("quaternion_") + q[a], 3 + a, a == 0 ? 1 : 0, "",
       "unit quaternion (w, x, y, z) of the tool's mesh frame, body -> ground");
  for (int a = 0; a < 3; ++a)
    in(std::string("velocity_") + axes[a], 7 + a, 0, "m/s", "velocity of the tool reference point, ground frame");
  for (int a = 0; a < 3; ++a)
    in(std::string("angular_velocity_") + axes[a], 10 + a, 0, "rad/s", "angular velocity of the tool, ground frame");
  for (int a = 0; a < 3; ++a)
    out(std::string("force_") + axes[a], 20 + a, "N", "force of the soil on the tool, ground frame");
  for (int a = 0; a < 3; ++a)
    out(std::string("torque_") + axes[a], 23 + a, "N.m", "torque of the soil on the tool about reference_point, ground frame");
  for (int a = 0; a < 3; ++a)
    out(std::string("reference_point_") + axes[a], 26 + a, "m",
        "point the torque is about: the tool reference point at the last DEM step of the communication step");
  auto str = [&](const std::string& name, fmi2ValueReference vr, const std::string& start, const std::string& what) {
    d.variables.push_back({name, Type::String, vr, C::Parameter, V::Fixed, 0, start, "", what, {}});
  };
  str("bus_url", 0, "", "LCM URL of the bus dem_service is on; empty: $LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0");
  str("session", 1, "",
      "session id in hex if dem_service was started with --session; empty: a new session with any free dem_service of that name");
  str("participant", 2, "dem", "the DEM participant's name (dem_service --name)");
  str("tool", 3, "", "the scene's tool this FMU moves; empty: the scene's only tool");
  str("dem_parameters", 4, "",
      "YAML map of dotted keys that amend dem_service's config, e.g. {output.file: dem.h5} (docs/dem_service.md)");
  d.variables.push_back({"connect_timeout", Type::Real, 40, C::Parameter, V::Fixed, 10, "", "s",
                         "seconds to wait at initialization for dem_service to answer", {}});
  d.variables.push_back({"timeout", Type::Real, 41, C::Parameter, V::Fixed, 2, "", "s",
                         "liveness: seconds of silence (no heartbeat, no reply) after which dem_service counts as gone", {}});
  d.variables.push_back({"retries", Type::Integer, 0, C::Parameter, V::Fixed, 3, "", "",
                         "give up after (retries + 1) x timeout without an answer from a live dem_service", {}});
  return d;
}
}  // namespace

const Description& description() {
  static const Description d = make();
  return d;
}

}  // namespace fmu_export
