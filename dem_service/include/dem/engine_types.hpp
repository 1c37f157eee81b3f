// What the engine's parts share: the error that stops a run, the soil's wrench on a tool, the
// contact statistics of a step, and the timing table's sections.
#pragma once

#include <cstdint>
#include <stdexcept>

#include "cosim/timer.hpp"
#include "dem/vec3.hpp"

namespace dem {

// The run cannot continue: NaN, runaway speed, guard violation in strict mode, too many
// boundary contacts. The message names the step, time, particle and the fix.
struct SimulationError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The soil's wrench on a tool as the contact loops sum it, in the hot-loop Vec3. It stays inside
// the engine: outside it is a cosim::Wrench (dem/coupling.hpp converts, with the point).
struct Wrench {
  Vec3 force;   // on the tool, ground frame
  Vec3 torque;  // about the tool's reference point, ground frame
};

// What the last step's force evaluation saw: contacts that carried a force and the deepest
// overlap, absolute and as a fraction of the smaller radius (a stiffness/dt sanity check).
struct ContactStats {
  std::int64_t particle_contacts = 0;
  std::int64_t boundary_contacts = 0;  // walls and tool features
  double max_overlap = 0;              // m
  double max_overlap_ratio = 0;        // overlap / smaller radius
};

// Wall-clock seconds per stage, LAMMPS style: the rows of the timing table, the `/timing`
// attributes of the output file and dem_service's `seconds_<section>` diagnostics.
using Timing = cosim::Timer;
namespace section {
enum : std::size_t {
  broad_phase,    // tool geometry for the lists and the broad phase
  pair_forces,    // narrow phase + contact forces between particles
  mesh_contacts,  // walls and tool meshes (and the tools' world geometry)
  integration,
  output,         // filled by the caller that writes files
};
}  // namespace section
Timing make_timing();  // the sections above, named as in the output

}  // namespace dem
