// Checks made before the first step: dt against the stiffest contact, and the initial
// particles (radius, mass, overlaps) against the scene.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

// One grain size that bounds a contact's period: a species' smallest, largest and listed radii.
struct SizeProbe {
  std::string name;  // the species
  double r, m;       // radius and mass
};
std::vector<SizeProbe> size_probes(const Scene& scene);

// Shortest contact period over the scene's species extremes (smallest and largest radius of
// each species, against each other and against walls/tools). `which` describes that contact.
double stiffest_contact_period(const Scene& scene, std::string* which = nullptr);

// The largest dt that leaves scene.stability.min_steps_per_contact steps per contact.
double largest_safe_dt(const Scene& scene);

// Refuses (std::invalid_argument) or warns (to `warn`) when dt is above largest_safe_dt,
// according to scene.stability.on_violation. The message names scene.dt and the safe dt.
void check_dt(const Scene& scene, std::ostream& warn);

// Refuses (std::invalid_argument) a state whose particles have a non-positive or non-finite
// radius, mass or position, an unknown species, a radius above the species' maximum, or that
// overlap each other or a wall by more than scene.stability.overlap_tolerance of the smaller
// radius. check_overlaps = false skips the overlap tests: for a run continued from its own
// checkpoint (RunConfig::continues), whose overlaps are the run's, not a bed's set-up error.
void validate_state(const Scene& scene, const State& s, bool check_overlaps = true);

}  // namespace dem
