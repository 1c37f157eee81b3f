// State: everything the step advances (MuJoCo's mjData). A snapshot, a rollback and a
// checkpoint are a copy of this struct and nothing more. The candidate lists live here too:
// they fix the summation order and carry the tangential history, so a restored run continues
// bit for bit.
#pragma once

#include <cstdint>
#include <vector>

#include "dem/vec3.hpp"

namespace dem {

// Pose of a tool: world position of its reference point, orientation of the mesh frame, and
// the velocities used for contact damping and friction. The engine's form of a
// cosim::Kinematics (dem/coupling.hpp converts), in the hot-loop Vec3/Quat.
struct ToolPose {
  Vec3 position;
  Quat orientation;
  Vec3 velocity;          // of the reference point
  Vec3 angular_velocity;  // world frame
};

// Boundary (wall or mesh feature) contacts per particle keep their tangential history in
// fixed slots; more simultaneous boundary contacts than this stop the run with a message.
inline constexpr int kBoundarySlots = 8;

struct State {
  std::int64_t step = 0;

  // Per particle (sorted by grid cell at every broad phase for cache locality).
  std::vector<Vec3> x, v;
  // Velocity estimated at the force time t_n, u = v_n + dt/2 a_(n-1): damping and friction
  // use it (second-order dashpot, docs/physics.md). Set u = v when you set v by hand.
  std::vector<Vec3> u;
  std::vector<double> radius, mass;
  std::vector<std::int32_t> species;
  std::vector<std::int64_t> id;  // stable identity across sorting, used in output

  std::vector<ToolPose> tool_pose;

  // Broad-phase products.
  bool lists_valid = false;
  std::int64_t steps_since_rebuild = 0;
  std::int64_t rebuilds = 0;
  std::int64_t early_rebuilds = 0;
  double max_displacement = 0;  // largest particle displacement since the last broad phase
  std::vector<Vec3> x_at_rebuild;
  std::vector<ToolPose> tool_pose_at_rebuild;
  // Half list of particle pairs (i < j) in CSR form, with the tangential spring of each pair
  // (the spring acts on i; j feels the opposite).
  std::vector<std::int32_t> pair_offset, pair_j;
  std::vector<Vec3> pair_spring;
  // Particle-triangle candidates in CSR form: tool index and triangle index.
  std::vector<std::int32_t> tri_offset, tri_tool, tri_index;
  // Walls within r + skin at the last broad phase, one bit per wall (all bits if > 32 walls).
  std::vector<std::uint32_t> wall_mask;
  // Boundary contact history: kBoundarySlots per particle.
  std::vector<std::uint64_t> slot_key;
  std::vector<Vec3> slot_spring;
  std::vector<std::uint8_t> slot_count;

  std::size_t size() const { return x.size(); }
};

// Every array of State, listed once, in checkpoint order: f(name, array, per_particle) for each,
// where per_particle says the array has one entry per particle. The checkpoint writes and reads
// State through this list, so a new array added here is saved and restored with the rest.
template <class S, class F>
void for_each_array(S& s, F&& f) {
  f("x", s.x, true);
  f("v", s.v, true);
  f("u", s.u, true);
  f("radius", s.radius, true);
  f("mass", s.mass, true);
  f("species", s.species, true);
  f("id", s.id, true);
  f("tool_pose", s.tool_pose, false);
  f("tool_pose_at_rebuild", s.tool_pose_at_rebuild, false);
  f("x_at_rebuild", s.x_at_rebuild, false);
  f("pair_offset", s.pair_offset, false);
  f("pair_j", s.pair_j, false);
  f("pair_spring", s.pair_spring, false);
  f("tri_offset", s.tri_offset, false);
  f("tri_tool", s.tri_tool, false);
  f("tri_index", s.tri_index, false);
  f("wall_mask", s.wall_mask, false);
  f("slot_key", s.slot_key, false);
  f("slot_spring", s.slot_spring, false);
  f("slot_count", s.slot_count, false);
}

// Appends one particle; radius and mass must already be validated.
void add_particle(State& s, Vec3 x, Vec3 v, double radius, double mass, int species,
                  std::int64_t id);

}  // namespace dem
