// State: everything the step advances (MuJoCo's mjData). A snapshot, a rollback and a
// checkpoint are a copy of this struct and nothing more. The candidate lists live here too:
// they fix the summation order and carry the tangential history, so a restored run continues
// bit for bit.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>
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
  // The largest displacement of any particle but the one that moved farthest: the guard rebuilds
  // when the two together may have closed the skin (a pair moved at most their sum).
  double second_displacement = 0;
  std::vector<Vec3> x_at_rebuild;
  std::vector<ToolPose> tool_pose_at_rebuild;
  // Half list of particle pairs (i < j) in CSR form, with the tangential spring of each pair
  // (the spring acts on i; j feels the opposite).
  std::vector<std::int32_t> pair_offset, pair_j;
  std::vector<Vec3> pair_spring;
  // Work of the pair rows before each particle (candidates, plus 4 per pair touching at the
  // broad phase, plus 1 per particle), n + 1 entries: threads split the pair forces by it.
  std::vector<std::int64_t> pair_work;
  // The half list read by partner, for sleeping (Scene::sleep): pair_row[pair_row_offset[j] ..
  // pair_row_offset[j + 1]) are the rows i < j that hold j, ascending. Empty until a step with
  // sleeping needs it (build_pair_rows); every change of the lists empties it.
  std::vector<std::int32_t> pair_row_offset, pair_row;
  // Particle-triangle candidates in CSR form: tool index and triangle index.
  std::vector<std::int32_t> tri_offset, tri_tool, tri_index;
  // Walls within r + skin at the last broad phase, one bit per wall (all bits if > 32 walls).
  std::vector<std::uint32_t> wall_mask;
  // Boundary contact history. Only particles near a wall or a tool at the last broad phase (or
  // still touching one) have a block of kBoundarySlots slots, about a tenth of a bed: slot_block
  // is the block's index in the pool slot_key/slot_spring, or -1. The broad phase hands out
  // the blocks, so between broad phases a particle without one cannot gain a boundary contact.
  std::vector<std::uint8_t> slot_count;  // per particle: boundary contacts in its block
  std::vector<std::int32_t> slot_block;  // per particle
  std::vector<std::uint64_t> slot_key;   // pool: kBoundarySlots per block
  std::vector<Vec3> slot_spring;
  std::vector<std::int32_t> slot_particle;  // pool: the particle of each block, ascending

  // Sleeping (Scene::sleep): consecutive steps each particle has been at rest; it is asleep
  // when this reached scene.sleep.steps. Sized with the particles at every step while sleep
  // is enabled (all zero otherwise); empty in checkpoints written before sleeping existed.
  std::vector<std::int32_t> rest_steps;
  // The rotating particle model (Scene::rotation, dem/rotation.hpp); all empty with the
  // translating model. Per particle: angular velocity w and its estimate at the force time wu
  // (as u for v). Per pair of the half list: the rolling spring torque on i (pair_roll, j feels
  // the opposite); per boundary slot: the rolling spring torque on the particle (slot_roll).
  std::vector<Vec3> w, wu;
  std::vector<Vec3> pair_roll, slot_roll;
  // Particles removed because they left the region of interest (Scene::region) and their mass.
  std::int64_t removed_count = 0;
  double removed_mass = 0;

  std::size_t size() const { return x.size(); }
};

// What an array of State holds, for the code that walks them all (for_each_array).
enum class Field {
  particle,  // one entry per particle, always: validated on load, moved by the broad phase sort
  sorted,    // one entry per particle once a broad phase ran (empty before): moved by the sort
  derived,   // anything else: lists, pools, tool poses; rebuilt or indexed, never permuted
  model,     // one entry per particle when the particle model has it (the rotating model's w,
             // wu), else empty: when not empty validated, moved and compacted like `sorted`
};

// Every array of State, listed once, in checkpoint order: f(name, array, field) for each. The
// checkpoint writes, reads and validates State through this list and the broad phase permutes
// through it, so a new array added here is saved, restored and kept in particle order with the
// rest.
template <class S, class F>
void for_each_array(S& s, F&& f) {
  f("x", s.x, Field::particle);
  f("v", s.v, Field::particle);
  f("u", s.u, Field::particle);
  f("radius", s.radius, Field::particle);
  f("mass", s.mass, Field::particle);
  f("species", s.species, Field::particle);
  f("id", s.id, Field::particle);
  f("tool_pose", s.tool_pose, Field::derived);
  f("tool_pose_at_rebuild", s.tool_pose_at_rebuild, Field::derived);
  f("x_at_rebuild", s.x_at_rebuild, Field::derived);  // rewritten by every broad phase
  f("pair_offset", s.pair_offset, Field::derived);
  f("pair_j", s.pair_j, Field::derived);
  f("pair_spring", s.pair_spring, Field::derived);
  f("pair_work", s.pair_work, Field::derived);
  f("pair_row_offset", s.pair_row_offset, Field::derived);
  f("pair_row", s.pair_row, Field::derived);
  f("tri_offset", s.tri_offset, Field::derived);
  f("tri_tool", s.tri_tool, Field::derived);
  f("tri_index", s.tri_index, Field::derived);
  f("wall_mask", s.wall_mask, Field::derived);  // rewritten by every broad phase
  f("slot_key", s.slot_key, Field::derived);
  f("slot_spring", s.slot_spring, Field::derived);
  f("slot_count", s.slot_count, Field::sorted);
  f("slot_block", s.slot_block, Field::sorted);
  f("slot_particle", s.slot_particle, Field::derived);
  f("rest_steps", s.rest_steps, Field::sorted);
  f("w", s.w, Field::model);  // rotating model only (empty otherwise)
  f("wu", s.wu, Field::model);
  f("pair_roll", s.pair_roll, Field::derived);
  f("slot_roll", s.slot_roll, Field::derived);
}

// Bytes the arrays of State hold (capacity, not size): the memory of a scene.
inline std::size_t bytes(const State& s) {
  std::size_t b = 0;
  for_each_array(s, [&](const char*, const auto& a, Field) {
    b += a.capacity() * sizeof(typename std::decay_t<decltype(a)>::value_type);
  });
  return b;
}

// The names of the arrays of State whose sizes or bytes differ between a and b, each after a
// space; empty when every array is the same, bit for bit (the checks of runs that must agree).
std::string differing_arrays(const State& a, const State& b);

// Fills pair_row_offset and pair_row from pair_offset and pair_j.
void build_pair_rows(State& s);

// Appends one particle; radius and mass must already be validated.
void add_particle(State& s, Vec3 x, Vec3 v, double radius, double mass, int species,
                  std::int64_t id);

// Removes the particles with remove[i] != 0 from every array of State (field list), keeping
// the order of the rest; the pair and triangle lists drop their rows and entries and are
// renumbered, so the lists stay valid and the tangential history of the others survives.
// Adds the count and mass to removed_count / removed_mass. Returns the number removed.
std::size_t remove_particles(State& s, const std::vector<std::uint8_t>& remove);

}  // namespace dem
