#include "dem/boundary_contacts.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>

#include "cosim/stopwatch.hpp"
#include "dem/contact_law.hpp"
#include "dem/pair_blocks.hpp"
#include "dem/rotation.hpp"

namespace dem {
namespace {

// One wall or mesh contact of a particle, before forces.
struct Contact {
  std::uint64_t key;
  Vec3 point;   // contact point on the body
  Vec3 normal;  // from the body towards the particle centre
  double overlap;
  Vec3 body_velocity;  // body velocity at the contact point
};

constexpr int kMaxHits = 256;  // triangles touching one sphere at once, per tool
constexpr std::size_t kBoundaryChunks = 64;  // chunks of slot blocks (see the header)
constexpr std::size_t kPrefetch = 8;         // particles fetched ahead (BoundaryContacts::run)

// Asks for the lines of particle i that the boundary contacts read or write (the first line
// of each; a second line of a Vec3 that straddles two was not worth its instruction). Always
// inlined: GCC 12 takes a function that only prefetches for one without effects and drops its
// calls.
[[gnu::always_inline]] inline void prefetch_particle(const State& s, const Vec3* force,
                                                     const Vec3* torque, const std::uint8_t* ghost,
                                                     bool sleep_on, std::size_t i) {
  __builtin_prefetch(&s.wall_mask[i]);
  __builtin_prefetch(&s.slot_count[i]);
  __builtin_prefetch(&s.tri_offset[i]);
  __builtin_prefetch(&s.x[i]);
  __builtin_prefetch(&s.u[i]);
  __builtin_prefetch(&s.radius[i]);
  __builtin_prefetch(&s.mass[i]);
  __builtin_prefetch(&force[i]);
  if (sleep_on) __builtin_prefetch(&s.rest_steps[i]);
  if (ghost) __builtin_prefetch(&ghost[i]);
  if (torque) {
    __builtin_prefetch(&s.wu[i]);
    __builtin_prefetch(&torque[i]);
  }
}

// Wall and mesh contacts of particle i after feature selection. Returns the count, or -1 if
// more than kBoundarySlots contacts (or kMaxHits triangle hits) exist.
// dt > 0 widens the test by the distance the contact window can reach (see contact_force);
// dt = 0 gives the geometric contacts.
// lanes: the candidate triangles tested 4 at a time (triangles_within), the closest point taken
// only for those within reach; the same hits in the same order.
int gather(const Scene& scene, const State& s, std::size_t i,
           const std::vector<std::vector<Vec3>>& tool_vertices, Contact* out, TriangleHit* hits,
           double dt, bool lanes = false) {
  const Vec3 xi = s.x[i];
  const double r = s.radius[i];
  const double speed = norm(s.u[i]);
  int nc = 0;
  const std::uint32_t mask = s.wall_mask[i];
  for (std::size_t w = 0; w < scene.walls.size(); ++w) {
    if (w < 32 && !(mask & (1u << w))) continue;
    const Wall& wall = scene.walls[w];
    const double gap = dot(xi - wall.point, wall.normal);
    if (gap < r + 0.5 * dt * speed) {
      if (nc == kBoundarySlots) return -1;
      out[nc++] = {contact_key(FeatureKind::wall, static_cast<std::uint32_t>(w), 0),
                   xi - gap * wall.normal, wall.normal, r - gap, Vec3{}};
    }
  }
  const std::int32_t k0 = s.tri_offset[i], k1 = s.tri_offset[i + 1];
  for (std::int32_t k = k0; k < k1;) {
    const std::int32_t m = s.tri_tool[k];
    const Mesh& mesh = scene.tools[m].mesh;
    const Vec3* wv = tool_vertices[m].data();
    const ToolPose& tp = s.tool_pose[m];
    const double reach = r + 0.5 * dt * (speed + norm(tp.velocity) +
                                         norm(tp.angular_velocity) * mesh.bounding_radius);
    int nh = 0;
    if (lanes) {
      std::int32_t k2 = k;  // this tool's candidates: [k, k2)
      while (k2 < k1 && s.tri_tool[k2] == m) ++k2;
      for (; k < k2; k += 4) {
        const std::int32_t* const tri = &s.tri_index[static_cast<std::size_t>(k)];
        int within = triangles_within(mesh, wv, tri, std::min(4, k2 - k), xi, reach * reach);
        while (within) {
          const int l = __builtin_ctz(static_cast<unsigned>(within));
          within &= within - 1;
          if (nh == kMaxHits) return -1;
          hits[nh++] = closest_on_triangle(mesh, wv, tri[l], xi);
        }
      }
      k = k2;
    }
    for (; k < k1 && s.tri_tool[k] == m; ++k) {
      const TriangleHit h = closest_on_triangle(mesh, wv, s.tri_index[k], xi);
      if (h.dist2 < reach * reach) {
        if (nh == kMaxHits) return -1;
        hits[nh++] = h;
      }
    }
    nh = select_mesh_contacts(mesh, hits, nh);
    const ToolPose& pose = s.tool_pose[m];
    for (int h = 0; h < nh; ++h) {
      if (nc == kBoundarySlots) return -1;
      const double d = std::sqrt(hits[h].dist2);
      Vec3 n;
      if (d > 1e-12 * r) {
        n = (1.0 / d) * (xi - hits[h].point);
      } else {  // centre on the surface: fall back to the face normal
        const auto& T = mesh.triangles[hits[h].triangle];
        const Vec3 fn = cross(wv[T[1]] - wv[T[0]], wv[T[2]] - wv[T[0]]);
        n = (1.0 / norm(fn)) * fn;
      }
      const Vec3 arm = hits[h].point - pose.position;
      out[nc++] = {contact_key(hits[h].kind, static_cast<std::uint32_t>(m),
                               static_cast<std::uint32_t>(hits[h].feature)),
                   hits[h].point, n, r - d, pose.velocity + cross(pose.angular_velocity, arm)};
    }
  }
  return nc;
}

bool shares_vertex(const Scene& scene, std::uint64_t a, std::uint64_t b) {
  if (key_kind(a) == FeatureKind::wall || key_kind(b) == FeatureKind::wall) return false;
  if (key_body(a) != key_body(b)) return false;
  const Mesh& mesh = scene.tools[key_body(a)].mesh;
  std::int32_t va[3], vb[3];
  const int na = feature_vertices(mesh, key_kind(a), key_feature(a), va);
  const int nb = feature_vertices(mesh, key_kind(b), key_feature(b), vb);
  for (int p = 0; p < na; ++p)
    for (int q = 0; q < nb; ++q)
      if (va[p] == vb[q]) return true;
  return false;
}

// The springs of particle i's nc new contacts from its nold old ones (slot block at `base`): the
// same feature keeps its spring; a sphere sliding from a face onto an edge or vertex (or on to
// the next face) keeps its tangential spring: the new feature inherits from an adjacent one that
// just ended.
// roll (the rotating model's rolling springs, else nullptr) goes with its spring.
// Fast: when the new keys are the old ones in the same order (a resting contact, the usual
// case), each contact keeps the spring of its own slot, which is what the matching below gives
// (contact c finds every slot before c taken and slot c its first free match, equal keys or
// not).
template <bool Fast>
void carry_springs(const Scene& scene, const State& s, std::size_t base, const Contact* cs,
                   int nc, int nold, Vec3* spring, Vec3* roll) {
  if (Fast && nc == nold) {
    int c = 0;
    while (c < nc && s.slot_key[base + c] == cs[c].key) ++c;
    if (c == nc) {
      // The whole block, a fixed size (a copy of nc entries becomes a rep movs, slow to start).
      std::memcpy(spring, &s.slot_spring[base], kBoundarySlots * sizeof(Vec3));
      if (roll) std::memcpy(roll, &s.slot_roll[base], kBoundarySlots * sizeof(Vec3));
      return;
    }
  }
  std::uint64_t old_key[kBoundarySlots];
  Vec3 old_spring[kBoundarySlots];
  bool used[kBoundarySlots] = {}, matched[kBoundarySlots] = {};
  // The whole block, a fixed size: a copy of nold entries became a rep movs, slow to start.
  std::memcpy(old_key, &s.slot_key[base], sizeof old_key);
  std::memcpy(old_spring, &s.slot_spring[base], sizeof old_spring);
  for (int c = 0; c < nc; ++c)
    for (int o = 0; o < nold; ++o)
      if (!used[o] && old_key[o] == cs[c].key) {
        spring[c] = old_spring[o];
        if (roll) roll[c] = s.slot_roll[base + o];
        used[o] = matched[c] = true;
        break;
      }
  for (int c = 0; c < nc; ++c) {
    if (matched[c]) continue;
    spring[c] = Vec3{};
    if (roll) roll[c] = Vec3{};
    for (int o = 0; o < nold; ++o)
      if (!used[o] && shares_vertex(scene, old_key[o], cs[c].key)) {
        spring[c] = old_spring[o];
        if (roll) roll[c] = s.slot_roll[base + o];
        used[o] = true;
        break;
      }
  }
}

}  // namespace

BoundaryContacts::BoundaryContacts(const Scene& scene, int max_threads) : scene_(scene) {
  thread_stats_.assign(static_cast<std::size_t>(max_threads), ContactStats{});
  tool_wrench_.resize(scene.tools.size());
  wall_force_.resize(scene.walls.size());
}

void BoundaryContacts::forces(State& s, const ToolGeometry& tools, Vec3* force, int T,
                              double* busy, Vec3* torque, const std::uint8_t* ghost) {
  if (!begin(s, torque)) return;
#pragma omp parallel num_threads(T)
  run(s, tools, force, omp_get_thread_num(), T, busy, torque, ghost);
  end(s);
}

bool BoundaryContacts::begin(State& s, const Vec3* torque) {
  const std::size_t ntools = scene_.tools.size(), nwalls = scene_.walls.size();
  std::fill(thread_stats_.begin(), thread_stats_.end(), ContactStats{});
  overflow_ = -1;
  chunks_ = 0;
  if (ntools == 0 && nwalls == 0) return false;
  // Only particles with a slot block can touch a wall or a tool; they are cut into chunks.
  const std::size_t nb = s.slot_particle.size();
  // The rotating model (torque != nullptr, dem/rotation.hpp): spins, torques, rolling springs.
  if (torque != nullptr && s.slot_roll.size() != s.slot_key.size())
    s.slot_roll.assign(s.slot_key.size(), Vec3{});
  chunks_ = std::max<std::size_t>(1, std::min(kBoundaryChunks, nb));
  chunk_tool_wrench_.assign(chunks_ * ntools, Wrench{});
  chunk_wall_force_.assign(chunks_ * nwalls, Vec3{});
  if (chunk_claim_.size() < chunks_) chunk_claim_.resize(chunks_, 0);
  ++chunk_pass_;
  return true;
}

void BoundaryContacts::run(State& s, const ToolGeometry& tools, Vec3* force, int t, int T,
                           double* busy, Vec3* torque, const std::uint8_t* ghost,
                           const ChunkWait* wait) {
  if (chunks_ == 0) return;  // begin() found no wall and no tool
  if (fast_)
    run_chunks<true>(s, tools, force, t, T, busy, torque, ghost, wait);
  else
    run_chunks<false>(s, tools, force, t, T, busy, torque, ghost, wait);
}

template <bool Fast>
void BoundaryContacts::run_chunks(State& s, const ToolGeometry& tools, Vec3* force, int t, int T,
                                  double* busy, Vec3* torque, const std::uint8_t* ghost,
                                  const ChunkWait* wait) {
  const ContactLaw& law = scene_.particle_wall;
  const bool per_body_laws = !scene_.boundary_laws.empty();
  const double dt = scene_.dt;
  const std::size_t ntools = scene_.tools.size(), nwalls = scene_.walls.size();
  const std::size_t nb = s.slot_particle.size();
  const bool spin = torque != nullptr;
  const RollingResistance& rolling = scene_.rotation.rolling;
  const std::size_t C = chunks_;
  const std::int64_t pass = chunk_pass_;
  {
    const cosim::Stopwatch watch;
    double waited = 0;
    Contact cs[kBoundarySlots];
    TriangleHit hits[kMaxHits];
    // Fast: the springs of a particle's contacts, set by carry_springs before they are read
    // (here and not in the loop: zeroing them for every particle was a tenth of the stage).
    Vec3 spring_all[kBoundarySlots], roll_all[kBoundarySlots];
    std::int64_t my_overflow = -1;
    ContactStats my_stats;
    const bool sleep_on = scene_.sleep.enabled;
    const std::int32_t S = scene_.sleep.steps;
    // Each thread walks the chunks as it walks the pair blocks (on two threads one up from the
    // first, one down from the last) and runs those it claims first: a thread keeps its part of
    // the particles from step to step.
    std::int64_t* const CLAIM = chunk_claim_.data();
    for (const std::int32_t walked : detail::pair_block_walk(static_cast<std::int32_t>(C), t, T)) {
      const std::size_t chunk = static_cast<std::size_t>(walked);
      if (!claim_first(CLAIM, chunk, pass)) continue;
      Wrench* const tw = chunk_tool_wrench_.data() + chunk * ntools;
      Vec3* const wf = chunk_wall_force_.data() + chunk * nwalls;
      const std::size_t k0 = nb * chunk / C, k1 = nb * (chunk + 1) / C;
      if (wait && k1 > k0) {
        std::size_t lo = static_cast<std::size_t>(s.slot_particle[k0]), hi = lo;
        for (std::size_t k = k0 + 1; k < k1; ++k) {
          const std::size_t i = static_cast<std::size_t>(s.slot_particle[k]);
          lo = std::min(lo, i);
          hi = std::max(hi, i);
        }
        waited += wait->fn(wait->ctx, lo, hi);
      }
      // Fast: the particles of a chunk lie apart in memory (a wall's layer of a bed sorted by
      // cell), and the work on one is too long for the processor to reach the next one's loads
      // by itself: they are fetched kPrefetch particles ahead.
      if (Fast)
        for (std::size_t k = k0; k < std::min(k1, k0 + kPrefetch); ++k)
          prefetch_particle(s, force, torque, ghost, sleep_on,
                            static_cast<std::size_t>(s.slot_particle[k]));
      for (std::size_t k = k0; k < k1; ++k) {
        const std::size_t i = static_cast<std::size_t>(s.slot_particle[k]);
        if (Fast && k + kPrefetch < k1)
          prefetch_particle(s, force, torque, ghost, sleep_on,
                            static_cast<std::size_t>(s.slot_particle[k + kPrefetch]));
        // A sleeper has no wall or mesh forces; its boundary history stays as it was.
        if (sleep_on && s.rest_steps[i] >= S) continue;
        // Another rank's particle (dem/mpi/): its owner computes its boundary contacts.
        if (ghost && ghost[i]) continue;
        // Nothing near and nothing remembered.
        if (s.wall_mask[i] == 0 && s.tri_offset[i] == s.tri_offset[i + 1] && s.slot_count[i] == 0)
          continue;
        const int nc =
            gather(scene_, s, i, tools.vertices, cs, hits, dt, Fast && triangle_lanes_);
        if (nc < 0) {
          if (my_overflow < 0) my_overflow = static_cast<std::int64_t>(i);
          continue;
        }
        const int nold = s.slot_count[i];
        if (nc == 0 && nold == 0) continue;
        const std::size_t base = k * kBoundarySlots;  // this particle's block
        Vec3 spring_one[Fast ? 1 : kBoundarySlots], roll_one[Fast ? 1 : kBoundarySlots];
        Vec3* const spring = Fast ? spring_all : spring_one;
        Vec3* const roll = Fast ? roll_all : roll_one;
        carry_springs<Fast>(scene_, s, base, cs, nc, nold, spring, spin ? roll : nullptr);
        const double ri = s.radius[i], mi = s.mass[i];
        const ContactCoefficients coef = coefficients(law, ri, mi);
        Vec3 fi{}, ti{};
        int active = 0;
        for (int c = 0; c < nc; ++c) {
          Vec3 f;
          // A wall or tool with a law of its own (Scene::boundary_laws; none: particle_wall).
          const ContactLaw* lw = &law;
          ContactCoefficients cw = coef;
          if (per_body_laws) {
            const std::uint32_t b = key_body(cs[c].key);
            lw = key_kind(cs[c].key) == FeatureKind::wall ? &scene_.wall_law(b) : &scene_.tool_law(b);
            if (lw != &law) cw = coefficients(*lw, ri, mi);
          }
          Vec3 couple{};  // rotating model: the rolling torque on the particle
          if (spin) {
            const bool wall = key_kind(cs[c].key) == FeatureKind::wall;
            const Vec3 body_w = wall ? Vec3{} : s.tool_pose[key_body(cs[c].key)].angular_velocity;
            const BoundarySpin b{lw, cw,
                                 rolling_coefficients(rolling, cw.k, ri,
                                                      1.4 * mi * ri * ri)};  // I + m r^2
            Vec3 tq;
            if (!rotating_boundary_contact(b, cs[c].overlap, cs[c].normal, cs[c].point, s.x[i],
                                           s.u[i], s.wu[i], cs[c].body_velocity, body_w,
                                           spring[c], roll[c], dt, f, tq, couple))
              continue;
            ti += tq;
          } else if (!contact_force(*lw, cw, cs[c].overlap, cs[c].normal,
                                    s.u[i] - cs[c].body_velocity, spring[c], dt, f)) {
            continue;
          }
          ++my_stats.boundary_contacts;
          my_stats.max_overlap = std::max(my_stats.max_overlap, cs[c].overlap);
          my_stats.max_overlap_ratio = std::max(my_stats.max_overlap_ratio, cs[c].overlap / ri);
          fi += f;
          const std::uint32_t body = key_body(cs[c].key);
          if (key_kind(cs[c].key) == FeatureKind::wall) {
            wf[body] -= f;
          } else {
            tw[body].force -= f;
            tw[body].torque -= cross(cs[c].point - s.tool_pose[body].position, f);
            if (spin) tw[body].torque -= couple;
          }
          s.slot_key[base + active] = cs[c].key;
          s.slot_spring[base + active] = spring[c];
          if (spin) s.slot_roll[base + active] = roll[c];
          ++active;
        }
        s.slot_count[i] = static_cast<std::uint8_t>(active);
        force[i] += fi;
        if (spin) torque[i] += ti;
      }
    }
    thread_stats_[t] = my_stats;
    busy[t] += watch.seconds() - waited;
    if (my_overflow >= 0) {
#pragma omp critical(dem_overflow)
      if (overflow_ < 0 || my_overflow < overflow_) overflow_ = my_overflow;
    }
  }
}

void BoundaryContacts::end(State& s) {
  if (chunks_ == 0) return;
  if (overflow_ >= 0) {
    const std::size_t i = static_cast<std::size_t>(overflow_);
    std::ostringstream msg;
    msg << "step " << s.step << " (t = " << s.step * scene_.dt << " s): particle id " << s.id[i]
        << " at (" << s.x[i].x << ", " << s.x[i].y << ", " << s.x[i].z << ") touches more than "
        << kBoundarySlots << " walls and mesh features at once; the tool mesh is probably finer "
        << "than the particles (coarsen it) or the particle was pushed through it (lower dt)";
    throw SimulationError(msg.str());
  }
  sum_chunks(chunks_);
}

// The chunks' sums in chunk order.
void BoundaryContacts::sum_chunks(std::size_t C) {
  const std::size_t ntools = scene_.tools.size(), nwalls = scene_.walls.size();
  for (std::size_t m = 0; m < ntools; ++m) {
    Wrench w{};
    for (std::size_t c = 0; c < C; ++c) {
      w.force += chunk_tool_wrench_[c * ntools + m].force;
      w.torque += chunk_tool_wrench_[c * ntools + m].torque;
    }
    tool_wrench_[m] = w;
  }
  for (std::size_t w = 0; w < nwalls; ++w) {
    Vec3 f{};
    for (std::size_t c = 0; c < C; ++c) f += chunk_wall_force_[c * nwalls + w];
    wall_force_[w] = f;
  }
}

std::vector<BoundaryContacts::MeshContact> BoundaryContacts::mesh_contacts(
    const State& s, const ToolGeometry& tools) const {
  std::vector<MeshContact> out;
  Contact cs[kBoundarySlots];
  std::vector<TriangleHit> hits(kMaxHits);
  for (std::size_t i = 0; i + 1 < s.tri_offset.size(); ++i) {
    const int nc = gather(scene_, s, i, tools.vertices, cs, hits.data(), 0.0);
    for (int c = 0; c < nc; ++c)
      if (key_kind(cs[c].key) != FeatureKind::wall)
        out.push_back({s.id[i], static_cast<int>(key_body(cs[c].key)), cs[c].key, cs[c].point});
  }
  return out;
}

std::size_t BoundaryContacts::bytes() const {
  return chunk_claim_.capacity() * sizeof(std::int64_t) +
         chunk_tool_wrench_.capacity() * sizeof(Wrench) + chunk_wall_force_.capacity() * sizeof(Vec3);
}

}  // namespace dem
