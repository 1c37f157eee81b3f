#include "dem/engine.hpp"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <mutex>
#include <sstream>
#include <thread>

#include "dem/contact_law.hpp"
#include "dem/mesh_contact.hpp"
#include "dem/pair_kernel.hpp"
#include "dem/stability.hpp"

namespace dem {
namespace {

// One wall or mesh contact of a particle, before forces.
struct BoundaryContact {
  std::uint64_t key;
  Vec3 point;   // contact point on the body
  Vec3 normal;  // from the body towards the particle centre
  double overlap;
  Vec3 body_velocity;  // body velocity at the contact point
};

constexpr int kMaxHits = 256;  // triangles touching one sphere at once, per tool

// Wall and mesh contacts of particle i after feature selection. Returns the count, or -1 if
// more than kBoundarySlots contacts (or kMaxHits triangle hits) exist.
// dt > 0 widens the test by the distance the contact window can reach (see contact_force);
// dt = 0 gives the geometric contacts.
int gather_boundary(const Scene& scene, const State& s, std::size_t i,
                    const std::vector<std::vector<Vec3>>& tool_vertices, BoundaryContact* out,
                    TriangleHit* hits, double dt) {
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

std::atomic<bool> sleeper_row_skip{true};
std::atomic<bool> sleeper_blocks{true};
// The pair forces' kernel: the AVX-512 one where the processor has it, unless the environment
// asks for the scalar loop (DEM_PAIR_KERNEL=scalar, for timing one against the other; both give
// the same bits). Read once; a value other than vector or scalar is refused.
bool vector_pairs_from_environment() {
  const char* v = std::getenv("DEM_PAIR_KERNEL");
  if (v == nullptr || std::strcmp(v, "vector") == 0) return true;
  if (std::strcmp(v, "scalar") == 0) return false;
  throw std::invalid_argument(std::string("environment DEM_PAIR_KERNEL=") + v +
                              ": use vector (the default) or scalar, or unset it");
}
std::atomic<bool> vector_pairs{true};
std::once_flag vector_pairs_read;
// DEM_PAIR_CHUNKS=branch-free or branching overrides the processor's default for the stream
// kernel (detail::use_branch_free_chunks; the same bits), for timing one against the other.
void chunk_branches_from_environment() {
  const char* v = std::getenv("DEM_PAIR_CHUNKS");
  if (v == nullptr) return;
  if (std::strcmp(v, "branch-free") == 0)
    detail::use_branch_free_chunks(true);
  else if (std::strcmp(v, "branching") == 0)
    detail::use_branch_free_chunks(false);
  else
    throw std::invalid_argument(std::string("environment DEM_PAIR_CHUNKS=") + v +
                                ": use branch-free or branching, or unset it (the processor "
                                "picks)");
}

// One step of semi-implicit Euler: the new velocity moves the particle (symplectic, one force
// evaluation per step; docs/physics.md); u is the velocity at the next force time. Returns |v|^2.
inline double advance(double dt, double m, const Vec3& f, Vec3& v, Vec3& u, Vec3& x) {
  // Component by component (the same arithmetic as with Vec3 temporaries): through a Vec3
  // the compiler built vn on the stack and copied it with a 16-byte load of two 8-byte stores,
  // a store-forwarding stall per particle.
  const double c = dt / m;
  const double dvx = c * f.x, dvy = c * f.y, dvz = c * f.z;
  const double vx = v.x + dvx, vy = v.y + dvy, vz = v.z + dvz;
  v.x = vx;
  v.y = vy;
  v.z = vz;
  u.x = vx + 0.5 * dvx;
  u.y = vy + 0.5 * dvy;
  u.z = vz + 0.5 * dvz;
  x.x = x.x + dt * vx;
  x.y = x.y + dt * vy;
  x.z = x.z + dt * vz;
  return vx * vx + vy * vy + vz * vz;
}

// True for the first thread to claim task k in this pass (pair blocks, boundary chunks): a
// relaxed look first, so a task already taken costs no exchange.
inline bool claim_first(std::int64_t* claim, std::size_t k, std::int64_t pass) {
  return __atomic_load_n(&claim[k], __ATOMIC_RELAXED) != pass &&
         __atomic_exchange_n(&claim[k], pass, __ATOMIC_ACQ_REL) != pass;
}

// Keeps the two largest of the squared displacements seen so far (first >= second), each of
// another particle: what the guard adds up.
inline void keep_two_largest(double& first, double& second, double d2) {
  if (d2 > second) {
    second = std::min(d2, first);
    first = std::max(d2, first);
  }
}

}  // namespace

void detail::use_sleeper_row_skip(bool skip) { sleeper_row_skip = skip; }
void detail::use_sleeper_blocks(bool blocks) { sleeper_blocks = blocks; }
void read_pair_kernel_environment() {
  std::call_once(vector_pairs_read, [] {
    vector_pairs = vector_pairs_from_environment();
    chunk_branches_from_environment();
  });
}

void detail::use_vector_pairs(bool vector) {
  read_pair_kernel_environment();
  vector_pairs = vector;
}

Timing make_timing() {
  return Timing({"broad_phase", "pair_forces", "mesh_contacts", "integration", "output"});
}

Engine::Engine(const Scene& scene) : scene_(scene) {
  read_pair_kernel_environment();
  max_threads_ = threads_ = std::max(1, scene.threads);
  remote_.resize(max_threads_);
  remote_wake_.resize(max_threads_);
  thread_stats_.assign(max_threads_, ContactStats{});
  boundary_stats_.assign(max_threads_, ContactStats{});
  reset_thread_busy();
  tool_wrench_.resize(scene.tools.size());
  wall_force_.resize(scene.walls.size());
  tool_vertices_.resize(scene.tools.size());
  tool_rotation_.resize(scene.tools.size());
  for (const auto& tool : scene.tools) {
    Vec3 lo{0, 0, 0}, hi{0, 0, 0};
    if (!tool.mesh.vertices.empty()) lo = hi = tool.mesh.vertices[0];
    for (const Vec3& v : tool.mesh.vertices) {
      lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
      hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
    }
    tool_box_min_.push_back(lo);
    tool_box_max_.push_back(hi);
    // The box's farthest corner from the reference point (the mesh frame's origin).
    const Vec3 far{std::max(std::abs(lo.x), std::abs(hi.x)), std::max(std::abs(lo.y), std::abs(hi.y)),
                   std::max(std::abs(lo.z), std::abs(hi.z))};
    tool_box_radius_.push_back(norm(far));
  }
}

double Engine::thread_busy(std::size_t sec, int t) const {
  if (sec < section::pair_forces || sec > section::integration || t < 0 || t >= max_threads_)
    return 0;
  return busy_[sec * static_cast<std::size_t>(max_threads_) + static_cast<std::size_t>(t)];
}

void Engine::reset_thread_busy() {
  busy_.assign((section::integration + 1) * static_cast<std::size_t>(max_threads_), 0.0);
}

void Engine::update_tool_geometry(const State& s) {
  if (s.tool_pose.size() != scene_.tools.size())
    throw SimulationError("state has " + std::to_string(s.tool_pose.size()) +
                          " tool poses but the scene has " +
                          std::to_string(scene_.tools.size()) + " tools");
  for (std::size_t m = 0; m < scene_.tools.size(); ++m) {
    const Mesh& mesh = scene_.tools[m].mesh;
    const ToolPose& pose = s.tool_pose[m];
    const Mat3 R = to_matrix(pose.orientation);
    tool_rotation_[m] = R;
    auto& wv = tool_vertices_[m];
    wv.resize(mesh.vertices.size());
    for (std::size_t v = 0; v < wv.size(); ++v) wv[v] = pose.position + R * mesh.vertices[v];
  }
}

bool Engine::guard_fires(const State& s, double* moved) {
  // A pair not in the list was more than `skin` apart at the last broad phase; it can touch
  // only after the two bodies together moved more than that.
  // The two largest displacements belong to two different particles, so their sum bounds what
  // any pair moved together (twice the largest, the usual bound, waits for half the skin when
  // one grain flies); one particle alone reaches a wall or mesh triangle not among its
  // candidates only after moving the whole skin, which the sum covers too.
  // The contact law acts from a gap below dt/2 |v_n| on (the step's window, docs/physics.md),
  // so the window is added: dt/2 (|u_a| + |u_b|) <= dt u_max for a pair, dt/2 (|u| + the
  // fastest point of the tool) for a tool.
  if (far_step_ != s.step || far_state_ != &s || far_size_ != s.size()) find_far_movers(s);
  const double window = scene_.dt * u_max_;
  double worst = s.max_displacement + s.second_displacement + window;
  for (std::size_t m = 0; m < scene_.tools.size(); ++m)
    worst = std::max(worst, s.max_displacement + tool_move(s, m) + 0.5 * window +
                                tool_window(s, m));
  *moved = worst;
  return worst > scene_.skin_distance();
}

// Half a step of the fastest point of tool m: its part of the contact window.
double Engine::tool_window(const State& s, std::size_t m) const {
  const ToolPose& tp = s.tool_pose[m];
  return 0.5 * scene_.dt *
         (norm(tp.velocity) + norm(tp.angular_velocity) * scene_.tools[m].mesh.bounding_radius);
}

// How far any point of tool m moved since the last broad phase (at most).
double Engine::tool_move(const State& s, std::size_t m) const {
  const ToolPose& now = s.tool_pose[m];
  const ToolPose& then = s.tool_pose_at_rebuild[m];
  const double angle = angle_between(now.orientation, then.orientation);
  return norm(now.position - then.position) +
         2 * std::sin(std::min(angle, M_PI) / 2) * scene_.tools[m].mesh.bounding_radius;
}

// One particle's share of the far movers' bookkeeping (the integration per thread, and
// find_far_movers): far if it moved more than 0.9 of half the skin or its half step dt/2 |u|
// (its part of the contact window) exceeds 0.1 of it (NaN counts as far); so every other
// particle has d + dt/2 |u| <= skin / 2, and no pair of two of them is inside its window yet.
// Listed up to one past the cap so that finish_far_movers sees an overflow.
Engine::FarLimits Engine::far_limits() const {
  const double half = 0.5 * scene_.skin_distance();
  const double d = 0.9 * half, u = 0.1 * half / (0.5 * scene_.dt);
  return {d * d, u * u};
}

void Engine::note_far_mover(std::vector<std::int32_t>& far, FarTally& tally, std::size_t i,
                            double d2, double ui2, const FarLimits& limits) {
  tally.u2 = std::max(tally.u2, ui2);
  if (!(d2 <= limits.d2 && ui2 <= limits.u2)) {
    if (far.size() <= kMaxFarMovers) far.push_back(static_cast<std::int32_t>(i));
  } else {
    tally.near2 = std::max(tally.near2, d2);
    tally.near_u2 = std::max(tally.near_u2, ui2);
  }
}

void Engine::SleeperTally::clear() {
  d1 = d2 = 0;
  tally = FarTally{};
  far.clear();
}

void Engine::FarTally::merge(const FarTally& o) {
  near2 = std::max(near2, o.near2);
  near_u2 = std::max(near_u2, o.near_u2);
  u2 = std::max(u2, o.u2);
}

// The far movers of state s from the first `lists` per-thread lists (ascending ranges).
void Engine::finish_far_movers(const State& s, int lists, const FarTally& tally) {
  far_.clear();
  far_overflow_ = false;
  for (int t = 0; t < lists; ++t)
    for (std::int32_t i : thread_far_[static_cast<std::size_t>(t)]) {
      if (far_.size() < kMaxFarMovers)
        far_.push_back(i);
      else
        far_overflow_ = true;
    }
  near_max_ = std::sqrt(tally.near2);
  near_u_max_ = std::sqrt(tally.near_u2);
  u_max_ = std::sqrt(tally.u2);
  far_step_ = s.step;
  far_state_ = &s;
  far_size_ = s.size();
}

void Engine::find_far_movers(const State& s) {
  const FarLimits limits = far_limits();
  if (thread_far_.empty()) thread_far_.resize(1);
  thread_far_[0].clear();
  FarTally tally;
  for (std::size_t i = 0; i < s.size(); ++i)
    note_far_mover(thread_far_[0], tally, i, norm2(s.x[i] - s.x_at_rebuild[i]), norm2(s.u[i]),
                   limits);
  finish_far_movers(s, 1, tally);
}

void Engine::build_mesh_grids() {
  mesh_grid_.assign(scene_.tools.size(), MeshGrid{});
  for (std::size_t m = 0; m < scene_.tools.size(); ++m) {
    const Mesh& mesh = scene_.tools[m].mesh;
    MeshGrid& g = mesh_grid_[m];
    if (mesh.vertices.empty()) continue;
    Vec3 lo = mesh.vertices[0], hi = lo;
    for (const Vec3& v : mesh.vertices) {
      lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
      hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
    }
    // Cells a candidate distance wide, at most about 4 per triangle.
    double h = 2 * scene_.r_max() + scene_.skin_distance();
    detail::grid_cells(lo, hi, std::max(64.0, 4.0 * static_cast<double>(mesh.triangles.size())),
                       h, g.nx, g.ny, g.nz);
    g.lo = lo;
    g.inv_h = 1.0 / h;
    auto cell = [&](double v, double l, long nmax) {
      return std::clamp(static_cast<long>((v - l) * g.inv_h), 0L, nmax - 1);
    };
    std::vector<std::array<long, 6>> box(mesh.triangles.size());
    g.start.assign(static_cast<std::size_t>(g.nx * g.ny * g.nz) + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<std::int32_t> fill(g.start.begin(), g.start.end() - 1);
      for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        auto& b = box[t];
        if (pass == 0) {
          const auto& T = mesh.triangles[t];
          const Vec3 a = mesh.vertices[T[0]], c = mesh.vertices[T[1]], d = mesh.vertices[T[2]];
          b = {cell(std::min({a.x, c.x, d.x}), lo.x, g.nx), cell(std::max({a.x, c.x, d.x}), lo.x, g.nx),
               cell(std::min({a.y, c.y, d.y}), lo.y, g.ny), cell(std::max({a.y, c.y, d.y}), lo.y, g.ny),
               cell(std::min({a.z, c.z, d.z}), lo.z, g.nz), cell(std::max({a.z, c.z, d.z}), lo.z, g.nz)};
        }
        for (long z = b[4]; z <= b[5]; ++z)
          for (long y = b[2]; y <= b[3]; ++y)
            for (long x = b[0]; x <= b[1]; ++x) {
              const long c = (z * g.ny + y) * g.nx + x;
              if (pass == 0)
                ++g.start[c + 1];
              else
                g.tri[fill[c]++] = static_cast<std::int32_t>(t);
            }
      }
      if (pass == 0) {
        for (std::size_t c = 0; c + 1 < g.start.size(); ++c) g.start[c + 1] += g.start[c];
        g.tri.resize(static_cast<std::size_t>(g.start.back()));
      }
    }
  }
}

// Is a triangle of tool m within `reach` of particle e that is not among e's candidates?
bool Engine::unlisted_triangle_near(const State& s, std::size_t e, std::size_t m,
                                    double reach) const {
  const MeshGrid& g = mesh_grid_[m];
  if (g.start.empty()) return false;  // a mesh without vertices
  const Mesh& mesh = scene_.tools[m].mesh;
  const Mat3& R = tool_rotation_[m];
  const Vec3 d = s.x[e] - s.tool_pose[m].position;
  const Vec3 q{R.m[0][0] * d.x + R.m[1][0] * d.y + R.m[2][0] * d.z,
               R.m[0][1] * d.x + R.m[1][1] * d.y + R.m[2][1] * d.z,
               R.m[0][2] * d.x + R.m[1][2] * d.y + R.m[2][2] * d.z};  // R^T d: the mesh frame
  const double grow = reach * (1 + 1e-9) + 1e-12;
  auto range = [&](double v, double l, long nmax, long& c0, long& c1) {
    const double a = (v - grow - l) * g.inv_h, b = (v + grow - l) * g.inv_h;
    c0 = a > 0 ? (a < static_cast<double>(nmax) ? static_cast<long>(a) : nmax) : 0;
    c1 = b >= 0 ? (b < static_cast<double>(nmax) ? static_cast<long>(b) : nmax - 1) : -1;
  };
  long x0, x1, y0, y1, z0, z1;
  range(q.x, g.lo.x, g.nx, x0, x1);
  range(q.y, g.lo.y, g.ny, y0, y1);
  range(q.z, g.lo.z, g.nz, z0, z1);
  const Vec3* wv = tool_vertices_[m].data();
  const std::int32_t k0 = s.tri_offset[e], k1 = s.tri_offset[e + 1];
  for (long z = z0; z <= z1; ++z)
    for (long y = y0; y <= y1; ++y)
      for (long x = x0; x <= x1; ++x) {
        const long c = (z * g.ny + y) * g.nx + x;
        for (std::int32_t k = g.start[c]; k < g.start[c + 1]; ++k) {
          const std::int32_t t = g.tri[k];
          if (closest_on_triangle(mesh, wv, t, s.x[e]).dist2 >= reach * reach * (1 + 1e-9)) continue;
          bool listed = false;
          for (std::int32_t j = k0; j < k1 && !listed; ++j)
            listed = s.tri_tool[j] == static_cast<std::int32_t>(m) && s.tri_index[j] == t;
          if (!listed) return true;
        }
      }
  return false;
}

// Why the bound can be refined (docs/dem.md "The guard"): a pair not in the lists was more than
// the skin apart at the last broad phase. Every particle but the far movers moved at most half
// the skin, so no pair of two of them can touch yet, nor can one of them reach a tool that moved
// less than the skin minus its displacement. What is left are the pairs, walls and tools of the
// few far movers, and those are looked at where the far movers are now: a pair of which one is a
// far mover can be active this step only within r_a + r_b + dt/2 (|u_a| + |u_b|) of each other
// (contact_force's window), and every particle within that reach of a far mover lay, at the last
// broad phase, in the cells around it widened by half the skin.
bool Engine::far_movers_clear(const State& s) {
  if (far_step_ != s.step || far_state_ != &s || far_size_ != s.size()) find_far_movers(s);
  if (far_overflow_ || s.x_at_rebuild.size() != s.size() || s.wall_mask.size() != s.size())
    return false;
  if (!broad_.grid_matches(s) && !broad_.restore_grid(scene_, s)) return false;
  const double skin = scene_.skin_distance();
  const std::size_t ntools = scene_.tools.size();
  std::vector<double>& moves = tool_moves_;
  moves.resize(ntools);
  const double dt = scene_.dt, rmax = scene_.r_max();
  // Pairs of the others, and the others against walls, are within the bound with the window
  // (note_far_mover); against a tool they are if d + dt/2 |u| + d_t + the tool's part is.
  for (std::size_t m = 0; m < ntools; ++m) {
    moves[m] = tool_move(s, m) + tool_window(s, m);  // with the tool's part of the window
    if (near_max_ + 0.5 * dt * near_u_max_ + moves[m] > skin) return false;
  }
  const auto listed = [&](std::size_t a, std::size_t b) {
    const std::size_t i = std::min(a, b), j = std::max(a, b);
    for (std::int32_t k = s.pair_offset[i]; k < s.pair_offset[i + 1]; ++k)
      if (static_cast<std::size_t>(s.pair_j[k]) == j) return true;
    return false;
  };
  // May a and b be active this step without being in the lists? (1e-9: rounding of the bound)
  const auto unlisted_near = [&](std::size_t a, std::size_t b, double ua) {
    const double reach = (s.radius[a] + s.radius[b] + 0.5 * dt * (ua + norm(s.u[b]))) * (1 + 1e-9);
    return norm2(s.x[a] - s.x[b]) < reach * reach && !listed(a, b);
  };
  // The far movers flagged (for the grid search below; cleared on every way out).
  far_flag_.resize(s.size());
  for (const std::int32_t e : far_) far_flag_[static_cast<std::size_t>(e)] = 1;
  struct Unflag {
    std::vector<std::uint8_t>& flag;
    const std::vector<std::int32_t>& far;
    ~Unflag() {
      for (const std::int32_t e : far) flag[static_cast<std::size_t>(e)] = 0;
    }
  } unflag{far_flag_, far_};
  const RegionOptions& region = scene_.region;
  for (std::size_t k = 0; k < far_.size(); ++k) {
    const std::size_t e = static_cast<std::size_t>(far_[k]);
    const Vec3 xe = s.x[e];
    const double re = s.radius[e], ue = norm(s.u[e]);
    if (!(ue <= u_max_)) return false;  // NaN: the blow-up check names it
    // Left the region of interest: a broad phase removes it now, as it would have before.
    if (region.enabled && (xe.x < region.min.x || xe.y < region.min.y || xe.z < region.min.z ||
                           xe.x > region.max.x || xe.y > region.max.y || xe.z > region.max.z))
      return false;
    // Walls not among its candidates, within the reach of boundary_contacts this step.
    const double wall_reach = (re + 0.5 * dt * ue) * (1 + 1e-9);
    for (std::size_t w = 0; w < scene_.walls.size() && w < 32; ++w) {
      if ((s.wall_mask[e] >> w) & 1u) continue;
      const Wall& wall = scene_.walls[w];
      if (dot(xe - wall.point, wall.normal) < wall_reach) return false;
    }
    // Tools that may have come within reach of a triangle not among its candidates: the
    // triangles within the reach of boundary_contacts this step must all be candidates (a
    // particle without a boundary slot block has none).
    const double disp = norm(xe - s.x_at_rebuild[e]) + 0.5 * dt * ue;
    for (std::size_t m = 0; m < ntools; ++m) {
      if (disp + moves[m] <= skin) continue;
      const Mesh& mesh = scene_.tools[m].mesh;
      const ToolPose& tp = s.tool_pose[m];
      const double reach = re + 0.5 * dt * (ue + norm(tp.velocity) +
                                            norm(tp.angular_velocity) * mesh.bounding_radius);
      const double far = mesh.bounding_radius + reach * (1 + 1e-9);
      if (norm2(xe - tp.position) >= far * far) continue;  // beyond every vertex
      if (mesh_grid_.size() != ntools) build_mesh_grids();
      if (unlisted_triangle_near(s, e, m, reach)) return false;
    }
    // Particles: those that moved at most half the skin, found through the grid ... (first
    // against the reach with the fastest speed of all, u_max_ >= |u_b|: what it rules out,
    // unlisted_near would too)
    bool clear = true;
    const double reach = (re + rmax + 0.5 * dt * (ue + u_max_) + 0.5 * skin) * (1 + 1e-9);
    const double pre = re + 0.5 * dt * (ue + u_max_);
    broad_.for_each_near(xe, reach, [&](std::int32_t b) {
      const std::size_t bb = static_cast<std::size_t>(b);
      if (!clear || bb == e) return;
      const double bound = (pre + s.radius[bb]) * (1 + 1e-9);
      if (!(norm2(s.x[bb] - xe) < bound * bound) || far_flag_[bb]) return;
      if (unlisted_near(e, bb, ue)) clear = false;
    });
    if (!clear) return false;
    // ... and the other far movers, wherever they are (the same first test).
    for (std::size_t l = k + 1; l < far_.size(); ++l) {
      const std::size_t b = static_cast<std::size_t>(far_[l]);
      const double bound = (pre + s.radius[b]) * (1 + 1e-9);
      if (!(norm2(s.x[b] - xe) < bound * bound)) continue;
      if (unlisted_near(e, b, ue)) return false;
    }
  }
  return true;
}

void Engine::size_sleep_arrays(State& s) {
  // rest_steps is a sorted field: the broad phase permutes it, so it must have one entry per
  // particle before every build, with sleeping enabled or not (then it stays all zero).
  if (s.rest_steps.size() != s.size()) s.rest_steps.resize(s.size(), 0);
}

void Engine::remove_outside(State& s) {
  removed_last_ = 0;
  if (!scene_.region.enabled) return;
  const std::size_t n = s.size();
  const Vec3 lo = scene_.region.min, hi = scene_.region.max;
  remove_.assign(n, 0);
  bool any = false;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 p = s.x[i];
    // NaN compares false: a NaN particle is left for the blow-up check to name.
    const bool out = p.x < lo.x || p.y < lo.y || p.z < lo.z || p.x > hi.x || p.y > hi.y ||
                     p.z > hi.z;
    remove_[i] = out;
    any = any || out;
  }
  if (any) removed_last_ = static_cast<std::int64_t>(remove_particles(s, remove_));
}

void Engine::rebuild(State& s) {
  choose_threads(s);
  cosim::Stopwatch watch;
  update_tool_geometry(s);
  size_sleep_arrays(s);
  remove_outside(s);
  choose_threads(s);
  broad_.build(scene_, s, tool_vertices_, threads_);
  timing_.lap(section::broad_phase, watch);
}

void Engine::choose_threads(const State& s) {
  const long per = std::max(1, scene_.min_particles_per_thread);
  const long cap = std::max(1L, static_cast<long>(s.size()) / per);
  threads_ = static_cast<int>(std::min<long>(max_threads_, cap));
}

void Engine::prepare(State& s) {
  choose_threads(s);
  cosim::Stopwatch watch;
  update_tool_geometry(s);
  timing_.lap(section::mesh_contacts, watch);
  size_sleep_arrays(s);
  removed_last_ = 0;

  const bool due = !s.lists_valid || s.steps_since_rebuild >= scene_.broad_phase_interval ||
                   s.pair_offset.size() != s.size() + 1 || s.slot_block.size() != s.size() ||
                   s.slot_particle.size() * kBoundarySlots != s.slot_key.size() ||
                   s.pair_work.size() != s.size() + 1;
  double moved = 0;
  if (due) {
    remove_outside(s);
    choose_threads(s);
    broad_.build(scene_, s, tool_vertices_, threads_);
  } else if (guard_fires(s, &moved)) {
    if (scene_.guard == GuardMode::rebuild && far_movers_clear(s)) {
      if (cleared_at_ != s.step) ++guard_cleared_;  // prepare() may be called twice a step
      cleared_at_ = s.step;
      timing_.lap(section::broad_phase, watch);
      return;
    }
    if (scene_.guard == GuardMode::strict) {
      std::ostringstream msg;
      msg << "broad phase guard at step " << s.step << " (t = " << s.step * scene_.dt
          << " s): bodies moved " << moved << " m since the last broad phase (with this step's "
          << "contact window), more than the skin "
          << scene_.skin_distance() << " m; contacts could be missed. Lower "
          << "scene.broad_phase_interval (now " << scene_.broad_phase_interval
          << ") or raise scene.skin (now " << scene_.skin
          << "), or set scene.guard: rebuild to rebuild early automatically";
      throw SimulationError(msg.str());
    }
    ++s.early_rebuilds;
    remove_outside(s);
    choose_threads(s);
    broad_.build(scene_, s, tool_vertices_, threads_);
  }
  timing_.lap(section::broad_phase, watch);
}

void Engine::step(State& s) {
  prepare(s);
  cosim::Stopwatch watch;
  pair_forces(s);
  timing_.lap(section::pair_forces, watch);
  boundary_forces(s);
  timing_.lap(section::mesh_contacts, watch);

  stats_ = ContactStats{};
  for (int t = 0; t < threads_; ++t)
    for (const ContactStats* c : {&thread_stats_[t], &boundary_stats_[t]}) {
      stats_.particle_contacts += c->particle_contacts;
      stats_.boundary_contacts += c->boundary_contacts;
      stats_.max_overlap = std::max(stats_.max_overlap, c->max_overlap);
      stats_.max_overlap_ratio = std::max(stats_.max_overlap_ratio, c->max_overlap_ratio);
    }

  watch.restart();
  integrate(s);
  timing_.lap(section::integration, watch);
}

// A particle is fast, and keeps all its candidates listed, above the speed that would close
// the margin within kCloseSteps steps together with another (2 v dt kCloseSteps = margin).
// In the paper's pile (margin 4 mm, dt 1e-4 s: 0.05 m/s) 25 steps listed every 17 steps and
// kept 68 % of the candidates; 400 lists about every 40 steps, keeping 71 %.
constexpr double kCloseSteps = 400;
// The margin the check allows: a little below the listed one (the rounding of the distances).
constexpr double kCloseSlack = 0.999;
// Above this share of the candidates kept (a gas, or most particles fast), the half list is
// read: the copies cost more than the few pairs they spare.
constexpr double kCloseMaxShare = 0.9;

bool Engine::close_pairs_hold(const State& s) const {
  const ClosePairs& c = close_;
  if (c.state != &s || c.size != s.size() || c.candidates != s.pair_j.size() ||
      c.rebuilds != s.rebuilds || c.built_at != s.step - s.steps_since_rebuild ||
      c.step != s.step)
    return false;  // new lists, another state, or a state put back (a repeated macro step)
  if (!c.use) return true;  // the half list is read until its next build
  return std::sqrt(c.d1) + std::sqrt(c.d2) + scene_.dt * std::sqrt(c.u2) <=
         kCloseSlack * scene_.close_distance();
}

void Engine::list_close_pairs(State& s) {
  ClosePairs& c = close_;
  const std::size_t n = s.size();
  const int T = threads_;
  const double margin = scene_.close_distance();
  const double fast = margin / (2 * kCloseSteps * scene_.dt);
  const double fast2 = fast * fast;
  c.offset.resize(n + 1);
  c.fast.resize(n);
  c.x_at.resize(n);
  c.keep.resize(s.pair_j.size());
  c.thread_base.assign(T + 1, 0);
  double slow_u2 = 0;
  const Vec3* const X = s.x.data();
  const Vec3* const U = s.u.data();
  const double* const R = s.radius.data();
  const std::int32_t* const off = s.pair_offset.data();
  const std::int32_t* const J = s.pair_j.data();
  Vec3* const spring = s.pair_spring.data();
  // Sleeping: two sleepers keep their spring while both sleep (the pair loop skips them), so a
  // pair of two sleepers that holds one stays listed (they do not move: it cannot have come
  // apart beyond the margin, but nothing here relies on that).
  const bool sleep = scene_.sleep.enabled && s.rest_steps.size() == n;
  const std::int32_t* const REST = sleep ? s.rest_steps.data() : nullptr;
  const std::int32_t S = scene_.sleep.steps;
#pragma omp parallel num_threads(T) reduction(max : slow_u2)
  {
    const int t = omp_get_thread_num();
    const std::size_t a0 = bounds_[t], a1 = bounds_[t + 1];
    for (std::size_t i = a0; i < a1; ++i) {
      const double u2 = norm2(U[i]);
      c.fast[i] = u2 > fast2;
      if (!c.fast[i]) slow_u2 = std::max(slow_u2, u2);
      c.x_at[i] = X[i];
    }
#pragma omp barrier
    std::int64_t kept = 0;
    for (std::size_t i = a0; i < a1; ++i) {
      const Vec3 xi = X[i];
      const double ri = R[i];
      const bool fi = c.fast[i];
      for (std::int32_t k = off[i]; k < off[i + 1]; ++k) {
        const std::int32_t j = J[k];
        const double reach = ri + R[j] + margin;
        const bool keep = fi || c.fast[j] || norm2(xi - X[j]) < reach * reach ||
                          (sleep && REST[i] >= S && REST[j] >= S && nonzero(spring[k]));
        c.keep[k] = keep;
        kept += keep;
        // Farther apart than the margin: out of contact this step, so the pair loop would
        // clear its history now; it is cleared here.
        if (!keep && nonzero(spring[k])) spring[k] = Vec3{};
      }
    }
    c.thread_base[t + 1] = kept;
#pragma omp barrier
#pragma omp single
    for (int q = 0; q < T; ++q) c.thread_base[q + 1] += c.thread_base[q];
    // (the single's barrier)
#pragma omp single nowait
    {
      c.partner.resize(static_cast<std::size_t>(c.thread_base[T]));
      c.index.resize(static_cast<std::size_t>(c.thread_base[T]));
      c.spring.resize(static_cast<std::size_t>(c.thread_base[T]));
    }
#pragma omp barrier
    std::int32_t q = static_cast<std::int32_t>(c.thread_base[t]);
    for (std::size_t i = a0; i < a1; ++i) {
      c.offset[i] = q;
      for (std::int32_t k = off[i]; k < off[i + 1]; ++k)
        if (c.keep[k]) {
          c.partner[q] = J[k];
          c.index[q] = k;
          c.spring[q] = spring[k];
          ++q;
        }
    }
  }
  c.offset[n] = static_cast<std::int32_t>(c.thread_base[T]);
  c.state = &s;
  c.size = n;
  c.candidates = s.pair_j.size();
  c.rebuilds = s.rebuilds;
  c.built_at = s.step - s.steps_since_rebuild;
  c.step = s.step;
  c.d1 = c.d2 = 0;
  c.u2 = slow_u2;
  close_share_ = c.candidates ? static_cast<double>(c.thread_base[T]) / c.candidates : 0;
  c.use = close_share_ <= kCloseMaxShare;
  ++close_builds_;
}

// Pair blocks: about kPairBlocks of them, none shorter than kPairBlockMin rows (a function of
// the lists alone, never of the thread count, so the sums are the same on any number of
// threads). Block k + 2 starts after the last partner of block k, so block k's partners lie
// in blocks k and k + 1.
constexpr std::size_t kPairBlocks = 64;
constexpr std::size_t kBoundaryChunks = 64;  // see boundary_forces
constexpr std::size_t kPairBlockMin = 512;

void Engine::make_pair_blocks(const State& s) {
  PairBlocks& b = blocks_;
  const std::size_t n = s.size();
  if (b.state == &s && b.size == n && b.candidates == s.pair_j.size() &&
      b.rebuilds == s.rebuilds && b.built_at == s.step - s.steps_since_rebuild)
    return;
  const std::int32_t* const off = s.pair_offset.data();
  const std::int32_t* const J = s.pair_j.data();
  const std::size_t target = std::max(kPairBlockMin, n / kPairBlocks);
  b.start.assign(1, 0);
  if (n > 0) b.start.push_back(std::min(n, target));
  while (b.start.back() < n) {
    const std::size_t k0 = b.start[b.start.size() - 2], k1 = b.start.back();
    std::size_t reach = k1;  // one past the last partner of block [k0, k1)
    for (std::int32_t q = off[k0]; q < off[k1]; ++q)
      reach = std::max(reach, static_cast<std::size_t>(J[q]) + 1);
    b.start.push_back(std::min(n, std::max(k1 + target, reach)));
  }
  const std::size_t K = b.start.size() - 1;
  b.done.assign(K, 0);
  b.claim.assign(K, 0);
  b.owner.assign(K, 0);
  b.pass = 0;
  b.state = &s;
  b.size = n;
  b.candidates = s.pair_j.size();
  b.rebuilds = s.rebuilds;
  b.built_at = s.step - s.steps_since_rebuild;
}

namespace detail {

std::vector<std::int32_t> pair_block_walk(std::int32_t K, int t, int T) {
  std::vector<std::int32_t> w;
  if (K <= 0) return w;
  w.reserve(K);
  if (T >= 2 && t == T - 1) {
    // Backward from the top: E_L (L the last even), O_{K-1} if K - 1 is odd, then each even
    // followed by the odd block above it.
    const std::int32_t L = (K - 1) / 2 * 2;
    w.push_back(L);
    if (L + 1 < K) w.push_back(L + 1);
    for (std::int32_t e = L - 2; e >= 0; e -= 2) {
      w.push_back(e);
      w.push_back(e + 1);
    }
    return w;
  }
  // Forward over [a, b) (a even): each even, then the odd block below it; the odd block below
  // b last (its upper neighbour, b, was walked first or does not exist).
  auto forward = [&w](std::int32_t a, std::int32_t b) {
    for (std::int32_t e = a; e < b; e += 2) {
      w.push_back(e);
      if (e > a) w.push_back(e - 1);
    }
    const std::int32_t last_even = a + (b - 1 - a) / 2 * 2;
    if (last_even + 1 < b) w.push_back(last_even + 1);
  };
  const std::int32_t s = static_cast<std::int32_t>(static_cast<std::int64_t>(K) * t / T) / 2 * 2;
  forward(s, K);
  if (s > 0) forward(0, s);
  return w;
}

}  // namespace detail

bool Engine::AwakePartners::holds(const State& s, std::int64_t at_step) const {
  return state == &s && size == s.size() && pairs == s.pair_j.size() && rebuilds == s.rebuilds &&
         step == at_step && count.size() == s.size() && s.pair_row_offset.size() == s.size() + 1;
}

// The rows that hold particle j (State::pair_row) gain `delta` awake partners.
void Engine::AwakePartners::add(const State& s, std::int32_t j, std::int32_t delta) {
  const std::int32_t* const ro = s.pair_row_offset.data();
  const std::int32_t* const rr = s.pair_row.data();
  for (std::int32_t q = ro[j]; q < ro[j + 1]; ++q) count[static_cast<std::size_t>(rr[q])] += delta;
}

// Sleeping: for each row of the half list, the number of its partners that are awake
// (State::pair_row lists the rows that hold each particle). A sleeper's row is read by the pair
// loop only when it holds one.
void Engine::count_awake_partners(const State& s) {
  AwakePartners& a = awake_partners_;
  const std::size_t n = s.size();
  const std::int32_t S = scene_.sleep.steps;
  a.count.assign(n, 0);
  for (std::size_t j = 0; j < n; ++j)
    if (s.rest_steps[j] < S) a.add(s, static_cast<std::int32_t>(j), 1);
  a.state = &s;
  a.size = n;
  a.pairs = s.pair_j.size();
  a.rebuilds = s.rebuilds;
  a.step = s.step;
}

// After the integration of a step (s.step already the next one): the rows that hold a particle
// that woke gain an awake partner, those that hold one that fell asleep lose one. Only if the
// counts were those of the step just made; else they are counted again when next needed.
void Engine::update_awake_partners(const State& s) {
  AwakePartners& a = awake_partners_;
  if (!a.holds(s, s.step - 1)) {
    a.state = nullptr;
    return;
  }
  for (const std::int32_t j : a.woke) a.add(s, j, 1);
  for (const std::int32_t j : a.fell) a.add(s, j, -1);
  a.step = s.step;
}

// The forces on particles [i0, i1) start from gravity, and with sleeping no one has woken them
// yet. A sleeper's force is not written: nothing reads it (the integration passes sleepers, one
// woken in this step is integrated from the next on, with the forces of that step; the pair
// loop adds nothing to it), and its store was most of this loop's memory traffic.
template <bool Sleep>
void Engine::start_forces(const State& s, std::size_t i0, std::size_t i1) {
  const Vec3 g = scene_.gravity;
  if (Sleep) {
    const std::int32_t S = scene_.sleep.steps;
    const std::int32_t* __restrict const REST = s.rest_steps.data();
    const double* __restrict const M = s.mass.data();
    Vec3* __restrict const F = force_.data();
    std::uint8_t* __restrict const WAKE = wake_.data();
    if (i1 > i0) std::memset(WAKE + i0, 0, i1 - i0);
    for (std::size_t i = i0; i < i1; ++i)
      if (REST[i] < S) F[i] = M[i] * g;
  } else {
    for (std::size_t i = i0; i < i1; ++i) force_[i] = s.mass[i] * g;
  }
}

void Engine::pair_forces(State& s) {
  if (scene_.sleep.enabled)
    pair_forces_impl<true>(s);
  else
    pair_forces_impl<false>(s);
}

// Sleep = false is the all-active loop (detail::pair_rows: the AVX-512 kernel or the scalar
// loop, the same bits); Sleep = true adds the sleeper rules (Scene::sleep, detail::pair_rows_sleep)
// and computes every force that the all-active loop computes between awake particles in the
// same order, so the awake part of the bed sees the same sums.
template <bool Sleep>
void Engine::pair_forces_impl(State& s) {
  const std::size_t n = s.size();
  if (Sleep) wake_.resize(n);
  const std::int32_t S = scene_.sleep.steps;
  const double wake_speed2 = scene_.sleep.wake() * scene_.sleep.wake();
  const std::int32_t* const REST = s.rest_steps.data();
  std::uint8_t* const WAKE = wake_.data();
  force_.resize(n);
  const int T = threads_;
  const ContactLaw law = scene_.particle_particle;  // a local copy: no reloads after stores
  const double dt = scene_.dt;
  // Threads take contiguous particle ranges of equal work (State::pair_work), not of equal
  // length: the bottom of a bed has about twice the contacts of its top half.
  bounds_.resize(T + 1);
  {
    const std::int64_t* const work = s.pair_work.data();
    bounds_[0] = 0;
    bounds_[T] = n;
    for (int t = 1; t < T; ++t) {
      const std::int64_t target = work[n] * t / T;
      bounds_[t] = static_cast<std::size_t>(
          std::lower_bound(work + bounds_[t - 1], work + n, target) - work);
    }
  }
  // Sleeping: a sleeper's row is scanned only if an awake particle is among its partners (the
  // rows of two sleepers compute nothing): AwakePartners counts them per row. Without sleepers
  // in the last step (sleeping_) every row is read and nothing is counted or built; the pairs
  // computed are the same either way.
  const bool skip_rows = Sleep && sleeping_ > 0 && sleeper_row_skip.load(std::memory_order_relaxed);
  if (skip_rows) {
    // Built by the first step with sleeping after a broad phase (and again if a loaded
    // checkpoint's copy does not fit the lists).
    if (s.pair_row_offset.size() != n + 1 || s.pair_row.size() != s.pair_j.size() ||
        static_cast<std::size_t>(s.pair_row_offset[n]) != s.pair_row.size()) {
      build_pair_rows(s);
      awake_partners_.state = nullptr;
    }
    if (!awake_partners_.holds(s, s.step)) count_awake_partners(s);
  }
  // What every thread's rows read and write (raw pointers, see dem/pair_kernel.hpp).
  detail::PairRows rows;
  rows.x = s.x.data();
  rows.u = s.u.data();
  rows.radius = s.radius.data();
  rows.mass = s.mass.data();
  rows.offset = s.pair_offset.data();
  rows.partner = s.pair_j.data();
  rows.spring = s.pair_spring.data();
  rows.force = force_.data();
  rows.law = law;
  rows.dt = dt;
  detail::PairSleep sleep_rules;  // each thread adds its queue of remote wakes
  if (Sleep) {
    sleep_rules.rest = REST;
    sleep_rules.steps = S;
    sleep_rules.wake_speed2 = wake_speed2;
    sleep_rules.awake_partners = skip_rows ? awake_partners_.count.data() : nullptr;
    sleep_rules.wake = WAKE;
  }
  if (scene_.close_pairs_on()) {
    if (!close_pairs_hold(s)) list_close_pairs(s);
    if (close_.use) {
      rows.offset = close_.offset.data();
      rows.partner = close_.partner.data();
      rows.spring = close_.spring.data();
      rows.spring_index = close_.index.data();
      rows.spring_home = s.pair_spring.data();
    }
  }
  const bool vector = vector_pairs.load(std::memory_order_relaxed);
  if (scene_.pair_schedule == PairSchedule::blocks) {
    make_pair_blocks(s);
    PairBlocks& b = blocks_;
    const std::int64_t K = static_cast<std::int64_t>(b.start.size()) - 1;
    const std::int64_t pass = ++b.pass;
    const std::size_t* const B = b.start.data();
    std::int64_t* const DONE = b.done.data();
    std::int64_t* const CLAIM = b.claim.data();
    rows.direct_end = n;  // a block's partners: in it or in the next block (made so)
#pragma omp parallel num_threads(T)
    {
      const int t = omp_get_thread_num();
      cosim::Stopwatch busy;
      double waited = 0;  // for the even blocks beside an odd one
      std::vector<detail::PairRemote> remote;  // stays empty: every partner is direct
      std::vector<std::int32_t> remote_wake;
      detail::PairSleep sl = sleep_rules;
      sl.remote_wake = &remote_wake;
      detail::PairRowStats st;
      // This thread's walk: it runs each block that no one has claimed before it. Before an odd
      // block the walk has passed both evens beside it, so they are claimed and, as an even
      // block never waits, done or being done.
      for (const std::int32_t kk : detail::pair_block_walk(static_cast<std::int32_t>(K), t, T)) {
        const std::int64_t k = kk;
        if (!claim_first(CLAIM, k, pass)) continue;
        b.owner[k] = t;
        if (k % 2 == 0) {
          // This block's and the next block's particles start from gravity (no one else
          // writes the next block before this block is done).
          start_forces<Sleep>(s, B[k], B[std::min(k + 2, K)]);
        } else {
          // The even blocks beside it: the one before has set up this block and written into
          // it, the one after is written into by this one.
          const auto ready = [&] {
            return __atomic_load_n(&DONE[k - 1], __ATOMIC_ACQUIRE) == pass &&
                   (k + 1 >= K || __atomic_load_n(&DONE[k + 1], __ATOMIC_ACQUIRE) == pass);
          };
          if (!ready()) {
            const cosim::Stopwatch wait;
            int spins = 0;
            while (!ready()) {
              if (++spins < 4000) {
#if defined(__x86_64__) || defined(__i386__)
                __builtin_ia32_pause();
#endif
              } else {
                std::this_thread::yield();
              }
            }
            waited += wait.seconds();
          }
        }
        if (Sleep)
          detail::pair_rows_sleep(rows, sl, B[k], B[k + 1], remote, st, vector);
        else
          detail::pair_rows(rows, B[k], B[k + 1], remote, st, vector);
        __atomic_store_n(&DONE[k], pass, __ATOMIC_RELEASE);
      }
      thread_stats_[t] = ContactStats{st.contacts, 0, st.max_overlap, st.max_overlap_ratio};
      add_busy(section::pair_forces, t, busy.seconds() - waited);
    }
    // The integration's ranges follow the blocks' owners: thread t starts at the first block
    // that a thread t or above ran (a split of the particles only, never of a sum).
    split_.assign(T + 1, n);
    split_[0] = 0;
    for (int t = 1; t < T; ++t) {
      std::int64_t k = 0;
      while (k < K && b.owner[k] < t) ++k;
      split_[t] = std::max(split_[t - 1], B[k]);
    }
    return;
  }
  split_.assign(bounds_.begin(), bounds_.end());
#pragma omp parallel num_threads(T)
  {
    const int t = omp_get_thread_num();
    const std::size_t a0 = bounds_[t], a1 = bounds_[t + 1];
    const cosim::Stopwatch busy;
    std::vector<detail::PairRemote> remote;  // local for the loop (no false sharing), capacity kept
    remote.swap(remote_[t]);
    remote.clear();
    std::vector<std::int32_t> remote_wake;
    if (Sleep) {
      remote_wake.swap(remote_wake_[t]);
      remote_wake.clear();
    }
    start_forces<Sleep>(s, a0, a1);
    detail::PairRowStats st;
    if (Sleep) {
      detail::PairSleep sl = sleep_rules;
      sl.remote_wake = &remote_wake;
      detail::pair_rows_sleep(rows, sl, a0, a1, remote, st, vector);
    } else {
      detail::pair_rows(rows, a0, a1, remote, st, vector);
    }
    remote.swap(remote_[t]);
    if (Sleep) remote_wake.swap(remote_wake_[t]);
    thread_stats_[t] = ContactStats{st.contacts, 0, st.max_overlap, st.max_overlap_ratio};
    add_busy(section::pair_forces, t, busy.seconds());
  }
  for (int t = 0; t < T; ++t)
    for (const detail::PairRemote& r : remote_[t]) force_[r.j] -= r.f;
  if (Sleep)
    for (int t = 0; t < T; ++t)
      for (const std::int32_t p : remote_wake_[t]) wake_[p] = 1;
}

void Engine::boundary_forces(State& s) {
  const int T = threads_;
  const ContactLaw& law = scene_.particle_wall;
  const bool per_body_laws = !scene_.boundary_laws.empty();
  const double dt = scene_.dt;
  const std::size_t ntools = scene_.tools.size(), nwalls = scene_.walls.size();
  std::fill(boundary_stats_.begin(), boundary_stats_.end(), ContactStats{});
  if (ntools == 0 && nwalls == 0) return;
  std::int64_t overflow = -1;
  // Only particles with a slot block can touch a wall or a tool (the broad phase handed the
  // blocks out). They are cut into chunks, a number that depends on the blocks alone; each chunk
  // sums its tools' and walls' forces on its own, each chunk is run by the thread that claims it
  // first, and the chunks' sums are added in chunk order: the same bits on any thread count.
  const std::size_t nb = s.slot_particle.size();
  const std::size_t C = std::max<std::size_t>(1, std::min(kBoundaryChunks, nb));
  chunk_tool_wrench_.assign(C * ntools, Wrench{});
  chunk_wall_force_.assign(C * nwalls, Vec3{});
  if (chunk_claim_.size() < C) chunk_claim_.resize(C, 0);
  const std::int64_t pass = ++chunk_pass_;
#pragma omp parallel num_threads(T)
  {
    const int t = omp_get_thread_num();
    const cosim::Stopwatch busy;
    BoundaryContact cs[kBoundarySlots];
    TriangleHit hits[kMaxHits];
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
      for (std::size_t k = k0; k < k1; ++k) {
        const std::size_t i = static_cast<std::size_t>(s.slot_particle[k]);
        // A sleeper has no wall or mesh forces; its boundary history stays as it was.
        if (sleep_on && s.rest_steps[i] >= S) continue;
        // Nothing near and nothing remembered.
        if (s.wall_mask[i] == 0 && s.tri_offset[i] == s.tri_offset[i + 1] && s.slot_count[i] == 0)
          continue;
        const int nc = gather_boundary(scene_, s, i, tool_vertices_, cs, hits, dt);
        if (nc < 0) {
          if (my_overflow < 0) my_overflow = static_cast<std::int64_t>(i);
          continue;
        }
        const int nold = s.slot_count[i];
        if (nc == 0 && nold == 0) continue;
        const std::size_t base = k * kBoundarySlots;  // this particle's block
        std::uint64_t old_key[kBoundarySlots];
        Vec3 old_spring[kBoundarySlots], spring[kBoundarySlots];
        bool used[kBoundarySlots] = {}, matched[kBoundarySlots] = {};
        // The whole block, a fixed size: a copy of nold entries became a rep movs, slow to start.
        std::memcpy(old_key, &s.slot_key[base], sizeof old_key);
        std::memcpy(old_spring, &s.slot_spring[base], sizeof old_spring);
        for (int c = 0; c < nc; ++c)
          for (int o = 0; o < nold; ++o)
            if (!used[o] && old_key[o] == cs[c].key) {
              spring[c] = old_spring[o];
              used[o] = matched[c] = true;
              break;
            }
        // A sphere sliding from a face onto an edge or vertex (or on to the next face) keeps its
        // tangential spring: the new feature inherits from an adjacent one that just ended.
        for (int c = 0; c < nc; ++c) {
          if (matched[c]) continue;
          spring[c] = Vec3{};
          for (int o = 0; o < nold; ++o)
            if (!used[o] && shares_vertex(scene_, old_key[o], cs[c].key)) {
              spring[c] = old_spring[o];
              used[o] = true;
              break;
            }
        }
        const double ri = s.radius[i], mi = s.mass[i];
        const ContactCoefficients coef = coefficients(law, ri, mi);
        Vec3 fi{};
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
          if (!contact_force(*lw, cw, cs[c].overlap, cs[c].normal, s.u[i] - cs[c].body_velocity,
                             spring[c], dt, f))
            continue;
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
          }
          s.slot_key[base + active] = cs[c].key;
          s.slot_spring[base + active] = spring[c];
          ++active;
        }
        s.slot_count[i] = static_cast<std::uint8_t>(active);
        force_[i] += fi;
      }
    }
    boundary_stats_[t] = my_stats;
    add_busy(section::mesh_contacts, t, busy.seconds());
#pragma omp critical(dem_overflow)
    if (my_overflow >= 0 && (overflow < 0 || my_overflow < overflow)) overflow = my_overflow;
  }
  if (overflow >= 0) {
    const std::size_t i = static_cast<std::size_t>(overflow);
    std::ostringstream msg;
    msg << "step " << s.step << " (t = " << s.step * scene_.dt << " s): particle id " << s.id[i]
        << " at (" << s.x[i].x << ", " << s.x[i].y << ", " << s.x[i].z << ") touches more than "
        << kBoundarySlots << " walls and mesh features at once; the tool mesh is probably finer "
        << "than the particles (coarsen it) or the particle was pushed through it (lower dt)";
    throw SimulationError(msg.str());
  }
  // The chunks' sums in chunk order.
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

void Engine::integrate(State& s) {
  if (scene_.sleep.enabled)
    integrate_impl<true>(s);
  else
    integrate_impl<false>(s);
}

template <bool Sleep>
void Engine::integrate_impl(State& s) {
  const std::size_t n = s.size();
  // Sleeping: a tool's neighbourhood is, with neighbourhood: sphere, the sphere around its
  // reference point with the mesh's bounding radius plus scene.sleep.tool_distance (plus the
  // particle radius below); with neighbourhood: box, the points within tool_distance (plus the
  // particle radius) of the mesh's box in the tool frame.
  const std::size_t ntools = scene_.tools.size();
  const bool box = scene_.sleep.neighbourhood == SleepNeighbourhood::box;
  std::vector<Vec3> tool_centre(Sleep ? ntools : 0);
  std::vector<double> tool_reach(Sleep ? ntools : 0);
  if (Sleep)
    for (std::size_t m = 0; m < ntools; ++m) {
      tool_centre[m] = s.tool_pose[m].position;
      tool_reach[m] = (box ? 0.0 : scene_.tools[m].mesh.bounding_radius) + scene_.sleep.tool_distance;
    }
  const std::int32_t S = scene_.sleep.steps;
  const double rest_speed2 = scene_.sleep.speed * scene_.sleep.speed;
  std::int64_t sleeping = 0;
  if (Sleep) {
    awake_partners_.woke.clear();
    awake_partners_.fell.clear();
  }
  const int T = threads_;
  const double dt = scene_.dt;
  const double vmax2 = scene_.stability.max_speed * scene_.stability.max_speed;
  double max_d2 = 0, second_d2 = 0;  // the two largest squared displacements (two particles)
  const FarLimits limits = far_limits();
  FarTally tally;
  thread_far_.resize(static_cast<std::size_t>(T));
  std::int64_t bad = -1;
  // Close pairs in use: the slow particles' displacements since they were listed, and speeds.
  const bool close = close_.use && close_.state == &s && close_.size == n;
  const std::uint8_t* const FAST = close ? close_.fast.data() : nullptr;
  const Vec3* const X_CLOSE = close ? close_.x_at.data() : nullptr;
  double close_d1 = 0, close_d2 = 0, close_u2 = 0;
  // Sleeping without close pairs: the sleepers' share of the guard's tallies is kept between
  // steps (SleeperTally); a particle adds its displacement when it falls asleep. Right after a
  // broad phase every sleeper's displacement is 0, so the tally starts empty; in any other
  // step it does not belong to, every sleeper is noted again (`renote`).
  const bool keep_sleepers = Sleep && !close;
  bool renote = false;
  if (keep_sleepers) {
    SleeperTally& k = sleepers_;
    const bool same = k.state == &s && k.size == n && k.step == s.step;
    bool rebox = true;
    if (same && k.rebuilds + 1 == s.rebuilds && s.steps_since_rebuild == 0) {
      k.clear();
    } else if (!(same && k.rebuilds == s.rebuilds)) {
      k.clear();
      renote = true;
    } else {
      rebox = false;
    }
    if (rebox) {  // the sleepers' boxes per block, from every sleeper
      const std::size_t nb = (n + kSleepBlock - 1) / kSleepBlock;
      k.box_lo.resize(nb);
      k.box_hi.resize(nb);
      const std::int32_t* const REST = s.rest_steps.data();
      const Vec3* const X = s.x.data();
      constexpr double inf = std::numeric_limits<double>::infinity();
#pragma omp parallel for num_threads(T) schedule(static)
      for (std::size_t b = 0; b < nb; ++b) {
        Vec3 lo{inf, inf, inf}, hi{-inf, -inf, -inf};
        const std::size_t i1 = std::min(n, (b + 1) * kSleepBlock);
        for (std::size_t i = b * kSleepBlock; i < i1; ++i)
          if (REST[i] >= S) {
            lo = {std::min(lo.x, X[i].x), std::min(lo.y, X[i].y), std::min(lo.z, X[i].z)};
            hi = {std::max(hi.x, X[i].x), std::max(hi.y, X[i].y), std::max(hi.z, X[i].z)};
          }
        k.box_lo[b] = lo;
        k.box_hi[b] = hi;
      }
    }
    k.fell_asleep.clear();
  }
  // With neighbourhood: box, the world frame's box around each tool's box (its frame's box
  // turned into the world), widened by the reach and a margin for rounding: a point outside
  // it is not within the reach of the tool's box, so near_tool skips the rotation for it.
  std::vector<Vec3> aabb_lo(Sleep && box ? ntools : 0), aabb_hi(aabb_lo.size());
  for (std::size_t m = 0; m < aabb_lo.size(); ++m) {
    const Mat3& R = tool_rotation_[m];
    const Vec3 c = 0.5 * (tool_box_min_[m] + tool_box_max_[m]), h = 0.5 * (tool_box_max_[m] - tool_box_min_[m]);
    const Vec3 cw = tool_centre[m] + Vec3{R.m[0][0] * c.x + R.m[0][1] * c.y + R.m[0][2] * c.z,
                                          R.m[1][0] * c.x + R.m[1][1] * c.y + R.m[1][2] * c.z,
                                          R.m[2][0] * c.x + R.m[2][1] * c.y + R.m[2][2] * c.z};
    const Vec3 hw{std::abs(R.m[0][0]) * h.x + std::abs(R.m[0][1]) * h.y + std::abs(R.m[0][2]) * h.z,
                  std::abs(R.m[1][0]) * h.x + std::abs(R.m[1][1]) * h.y + std::abs(R.m[1][2]) * h.z,
                  std::abs(R.m[2][0]) * h.x + std::abs(R.m[2][1]) * h.y + std::abs(R.m[2][2]) * h.z};
    const double margin = 1e-9 * (norm(cw) + norm(hw) + tool_reach[m] + 1.0);
    const Vec3 w = hw + Vec3{margin, margin, margin};
    aabb_lo[m] = cw - w;
    aabb_hi[m] = cw + w;
  }
  // Whole blocks of sleepers (any radius up to r_max) against each tool's neighbourhood: the
  // sphere about its reference point, or the world box above.
  const double block_pad = scene_.r_max() * (1 + 1e-6);
  const bool use_blocks = sleeper_blocks.load(std::memory_order_relaxed);
  const auto block_far = [&](std::size_t b) {
    if (!use_blocks) return false;
    const Vec3 lo = sleepers_.box_lo[b], hi = sleepers_.box_hi[b];
    if (!(lo.x <= hi.x)) return true;  // no sleeper in it
    for (std::size_t m = 0; m < ntools; ++m) {
      const double reach = (tool_reach[m] + block_pad) * (1 + 1e-6);
      if (box) {
        const Vec3 a = aabb_lo[m], z = aabb_hi[m];
        if (lo.x > z.x + reach || hi.x < a.x - reach || lo.y > z.y + reach || hi.y < a.y - reach ||
            lo.z > z.z + reach || hi.z < a.z - reach)
          continue;
        return false;
      }
      const Vec3 c = tool_centre[m];
      const Vec3 out{std::max({lo.x - c.x, 0.0, c.x - hi.x}), std::max({lo.y - c.y, 0.0, c.y - hi.y}),
                     std::max({lo.z - c.z, 0.0, c.z - hi.z})};
      if (!(norm2(out) > reach * reach)) return false;
    }
    return true;
  };
#pragma omp parallel num_threads(T)
  {
    const int t = omp_get_thread_num();
    const cosim::Stopwatch busy;
    // The particles whose pair forces this thread ran (pair_forces), which are in its cache.
    const bool own = split_.size() == static_cast<std::size_t>(T) + 1 && split_[T] == n;
    const std::size_t a0 = own ? split_[t] : n * t / T, a1 = own ? split_[t + 1] : n * (t + 1) / T;
    double my_d2 = 0, my_second = 0;  // this thread's two largest
    double my_close_d1 = 0, my_close_d2 = 0, my_close_u2 = 0;  // close pairs (slow particles)
    FarTally my_tally;  // far movers: the others' largest displacement and speed, the largest
    std::vector<std::int32_t>& my_far = thread_far_[t];
    my_far.clear();
    // State's arrays as raw pointers that cannot alias: the compiler keeps their addresses and
    // the running maxima in registers (through State's vectors it reloads them after every
    // store). Both loops below use them.
    const double* __restrict const M = s.mass.data();
    const double* __restrict const RAD = s.radius.data();
    const Vec3* __restrict const FORCE = force_.data();
    const Vec3* __restrict const XR = s.x_at_rebuild.data();
    Vec3* __restrict const V = s.v.data();
    Vec3* __restrict const U = s.u.data();
    Vec3* __restrict const X = s.x.data();
    std::int32_t* __restrict const REST = Sleep ? s.rest_steps.data() : nullptr;
    const std::uint8_t* __restrict const WAKE = Sleep ? wake_.data() : nullptr;
    auto moved = [&](std::size_t i, double d2) {
      keep_two_largest(my_d2, my_second, d2);
      note_far_mover(my_far, my_tally, i, d2, norm2(U[i]), limits);
      if (close && !FAST[i]) {  // as in the all-awake loop below
        keep_two_largest(my_close_d1, my_close_d2, norm2(X[i] - X_CLOSE[i]));
        my_close_u2 = std::max(my_close_u2, norm2(U[i]));
      }
    };
    std::int64_t my_bad = -1;
    std::int64_t my_sleeping = 0;
    // The sleepers this thread adds to sleepers_ (fell asleep this step, or all with renote).
    double sl_d1 = 0, sl_d2 = 0;
    FarTally sl_tally;
    std::vector<std::int32_t> sl_far;
    std::vector<std::int32_t> my_woke, my_fell;  // awake_partners_ (and sleepers_' boxes)
    auto note_sleeper = [&](std::size_t i, double d2) {
      keep_two_largest(sl_d1, sl_d2, d2);
      note_far_mover(sl_far, sl_tally, i, d2, norm2(U[i]), limits);
    };
    auto near_tool = [&](std::size_t i) {
      for (std::size_t m = 0; m < tool_centre.size(); ++m) {
        const double reach = tool_reach[m] + RAD[i];
        const Vec3 d = X[i] - tool_centre[m];
        if (!box) {
          if (norm2(d) < reach * reach) return true;
          continue;
        }
        // Outside the world box around the tool's box widened by the reach, or farther from
        // the reference point than the box's farthest corner plus the reach: not near the box
        // (the exact test below would say the same; margins of 1e-9 cover its rounding).
        // Spares the rotation for most of a large bed.
        const Vec3 x = X[i], a = aabb_lo[m], z = aabb_hi[m];
        const double r = reach * (1 + 1e-9);
        if (x.x > z.x + r || x.x < a.x - r || x.y > z.y + r || x.y < a.y - r || x.z > z.z + r ||
            x.z < a.z - r)
          continue;
        const double bound = (tool_box_radius_[m] + reach) * (1 + 1e-9);
        if (norm2(d) > bound * bound) continue;
        // d in the tool frame (R^T d), then its distance to the mesh's box
        const Mat3& R = tool_rotation_[m];
        const Vec3 q{R.m[0][0] * d.x + R.m[1][0] * d.y + R.m[2][0] * d.z,
                     R.m[0][1] * d.x + R.m[1][1] * d.y + R.m[2][1] * d.z,
                     R.m[0][2] * d.x + R.m[1][2] * d.y + R.m[2][2] * d.z};
        const Vec3 lo = tool_box_min_[m], hi = tool_box_max_[m];
        const Vec3 out{std::max({lo.x - q.x, 0.0, q.x - hi.x}), std::max({lo.y - q.y, 0.0, q.y - hi.y}),
                       std::max({lo.z - q.z, 0.0, q.z - hi.z})};
        if (norm2(out) < reach * reach) return true;
      }
      return false;
    };
    if (!Sleep) {
      // All awake (0.88 of the time with the raw pointers than through State's vectors).
      for (std::size_t i = a0; i < a1; ++i) {
        const double v2 = advance(dt, M[i], FORCE[i], V[i], U[i], X[i]);
        if (!(v2 <= vmax2) && my_bad < 0) my_bad = static_cast<std::int64_t>(i);
        const double d2 = norm2(X[i] - XR[i]);
        keep_two_largest(my_d2, my_second, d2);
        note_far_mover(my_far, my_tally, i, d2, norm2(U[i]), limits);
        if (close && !FAST[i]) {
          keep_two_largest(my_close_d1, my_close_d2, norm2(X[i] - X_CLOSE[i]));
          my_close_u2 = std::max(my_close_u2, norm2(U[i]));
        }
      }
    } else {
      bool far_block = false;  // the sleepers of i's block are beyond every tool's reach
      for (std::size_t i = a0; i < a1; ++i) {
        if (keep_sleepers && (i == a0 || i % kSleepBlock == 0)) {
          far_block = block_far(i / kSleepBlock);
          // A whole block asleep, beyond every tool and woken by no one: nothing to do in it
          // (what the loop below would find particle by particle).
          if (far_block && !renote && i % kSleepBlock == 0 && i + kSleepBlock <= a1) {
            int quiet = 1;
            for (std::size_t q = i; q < i + kSleepBlock; ++q) quiet &= (REST[q] >= S) & (WAKE[q] == 0);
            if (quiet) {
              my_sleeping += static_cast<std::int64_t>(kSleepBlock);
              i += kSleepBlock - 1;
              continue;
            }
          }
        }
        if (REST[i] >= S) {
          // Asleep: not integrated. Woken by the pair loop or a tool, it is integrated from
          // the next step on, with all its forces.
          if (WAKE[i] || (!far_block && near_tool(i))) {
            REST[i] = 0;
            my_woke.push_back(static_cast<std::int32_t>(i));
          } else
            ++my_sleeping;
          // It has not moved since it fell asleep (nor this step): already in sleepers_.
          if (!keep_sleepers)
            moved(i, norm2(X[i] - XR[i]));
          else if (renote)
            note_sleeper(i, norm2(X[i] - XR[i]));
          continue;
        }
        const double v2 = advance(dt, M[i], FORCE[i], V[i], U[i], X[i]);
        if (!(v2 <= vmax2) && my_bad < 0) my_bad = static_cast<std::int64_t>(i);
        const double d2 = norm2(X[i] - XR[i]);
        moved(i, d2);
        std::int32_t r = REST[i];
        if (v2 < rest_speed2 && !near_tool(i)) {
          if (++r >= S) {  // falls asleep where it is
            V[i] = U[i] = Vec3{};
            ++my_sleeping;
            my_fell.push_back(static_cast<std::int32_t>(i));
            if (keep_sleepers) note_sleeper(i, d2);
          }
        } else {
          r = 0;
        }
        REST[i] = r;
      }
    }
    add_busy(section::integration, t, busy.seconds());
#pragma omp critical(dem_integrate)
    {
      keep_two_largest(max_d2, second_d2, my_d2);
      keep_two_largest(max_d2, second_d2, my_second);
      tally.merge(my_tally);
      keep_two_largest(close_d1, close_d2, my_close_d1);
      keep_two_largest(close_d1, close_d2, my_close_d2);
      close_u2 = std::max(close_u2, my_close_u2);
      sleeping += my_sleeping;
      if (Sleep) {
        AwakePartners& a = awake_partners_;
        a.woke.insert(a.woke.end(), my_woke.begin(), my_woke.end());
        a.fell.insert(a.fell.end(), my_fell.begin(), my_fell.end());
      }
      if (keep_sleepers) {
        keep_two_largest(sleepers_.d1, sleepers_.d2, sl_d1);
        keep_two_largest(sleepers_.d1, sleepers_.d2, sl_d2);
        sleepers_.tally.merge(sl_tally);
        sleepers_.far.insert(sleepers_.far.end(), sl_far.begin(), sl_far.end());
        sleepers_.fell_asleep.insert(sleepers_.fell_asleep.end(), my_fell.begin(), my_fell.end());
      }
      if (my_bad >= 0 && (bad < 0 || my_bad < bad)) bad = my_bad;
    }
  }
  int lists = T;
  if (keep_sleepers) {
    SleeperTally& k = sleepers_;
    keep_two_largest(max_d2, second_d2, k.d1);
    keep_two_largest(max_d2, second_d2, k.d2);
    tally.merge(k.tally);
    if (k.far.size() > kMaxFarMovers + 1) k.far.resize(kMaxFarMovers + 1);  // overflows anyway
    if (!k.far.empty()) {
      thread_far_.resize(static_cast<std::size_t>(T) + 1);
      thread_far_[T] = k.far;
      lists = T + 1;
    }
    for (const std::int32_t i : k.fell_asleep) {  // their blocks' boxes grow
      const std::size_t b = static_cast<std::size_t>(i) / kSleepBlock;
      const Vec3 x = s.x[static_cast<std::size_t>(i)];
      Vec3& lo = k.box_lo[b];
      Vec3& hi = k.box_hi[b];
      lo = {std::min(lo.x, x.x), std::min(lo.y, x.y), std::min(lo.z, x.z)};
      hi = {std::max(hi.x, x.x), std::max(hi.y, x.y), std::max(hi.z, x.z)};
    }
    k.state = &s;
    k.size = n;
    k.rebuilds = s.rebuilds;
    k.step = s.step + 1;  // the step this integration ends in
  }
  s.max_displacement = std::sqrt(max_d2);
  s.second_displacement = std::sqrt(second_d2);
  if (close) {
    close_.d1 = close_d1;
    close_.d2 = close_d2;
    close_.u2 = close_u2;
  }
  sleeping_ = sleeping;
  ++s.step;
  if (close_.state == &s) close_.step = s.step;  // its copies of the springs are of this state
  if (Sleep) {
    woke_total_ += static_cast<std::int64_t>(awake_partners_.woke.size());
    fell_asleep_total_ += static_cast<std::int64_t>(awake_partners_.fell.size());
    update_awake_partners(s);
  }
  ++s.steps_since_rebuild;
  finish_far_movers(s, lists, tally);  // the far movers of the new state
  if (lists > T) {  // ascending and each once (a woken sleeper may be in both lists)
    std::sort(far_.begin(), far_.end());
    far_.erase(std::unique(far_.begin(), far_.end()), far_.end());
  }
  if (bad >= 0) {
    const std::size_t i = static_cast<std::size_t>(bad);
    std::ostringstream msg;
    msg << "blow-up at step " << s.step << " (t = " << s.step * dt << " s): particle id "
        << s.id[i] << " at (" << s.x[i].x << ", " << s.x[i].y << ", " << s.x[i].z
        << ") has speed " << norm(s.v[i]) << " m/s (limit scene.stability.max_speed = "
        << scene_.stability.max_speed << "); kinetic energy " << kinetic_energy(s)
        << " J. Lower scene.dt (now " << dt << ", largest safe " << largest_safe_dt(scene_)
        << ") or soften contact normal_stiffness";
    throw SimulationError(msg.str());
  }
}

std::vector<std::pair<std::int64_t, std::int64_t>> Engine::particle_contacts(
    const State& s) const {
  std::vector<std::pair<std::int64_t, std::int64_t>> out;
  for (std::size_t i = 0; i + 1 < s.pair_offset.size(); ++i)
    for (std::int32_t k = s.pair_offset[i]; k < s.pair_offset[i + 1]; ++k) {
      const std::int32_t j = s.pair_j[k];
      const double rsum = s.radius[i] + s.radius[j];
      if (norm2(s.x[i] - s.x[j]) < rsum * rsum)
        out.emplace_back(std::min(s.id[i], s.id[j]), std::max(s.id[i], s.id[j]));
    }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Engine::MeshContact> Engine::mesh_contacts(const State& s) {
  update_tool_geometry(s);
  std::vector<MeshContact> out;
  BoundaryContact cs[kBoundarySlots];
  std::vector<TriangleHit> hits(kMaxHits);
  for (std::size_t i = 0; i + 1 < s.tri_offset.size(); ++i) {
    const int nc = gather_boundary(scene_, s, i, tool_vertices_, cs, hits.data(), 0.0);
    for (int c = 0; c < nc; ++c)
      if (key_kind(cs[c].key) != FeatureKind::wall)
        out.push_back({s.id[i], static_cast<int>(key_body(cs[c].key)), cs[c].key, cs[c].point});
  }
  return out;
}

std::size_t Engine::workspace_bytes() const {
  std::size_t b = broad_.workspace_bytes() + force_.capacity() * sizeof(Vec3) +
                  (awake_partners_.count.capacity() + awake_partners_.woke.capacity() +
                   awake_partners_.fell.capacity()) *
                      sizeof(std::int32_t);
  for (const auto& v : tool_vertices_) b += v.capacity() * sizeof(Vec3);
  for (const auto& v : remote_) b += v.capacity() * sizeof(detail::PairRemote);
  const ClosePairs& c = close_;  // close pairs (scene.close_margin)
  b += (c.offset.capacity() + c.partner.capacity() + c.index.capacity()) *
           sizeof(std::int32_t) +
       (c.spring.capacity() + c.x_at.capacity()) * sizeof(Vec3) + c.keep.capacity() +
       c.fast.capacity() + c.thread_base.capacity() * sizeof(std::int64_t);
  b += blocks_.start.capacity() * sizeof(std::size_t) +  // pair blocks, boundary chunks
       blocks_.done.capacity() * sizeof(std::int64_t) +
       (blocks_.claim.capacity() + chunk_claim_.capacity()) * sizeof(std::int64_t) +
       blocks_.owner.capacity() * sizeof(int) + split_.capacity() * sizeof(std::size_t) +
       chunk_tool_wrench_.capacity() * sizeof(Wrench) + chunk_wall_force_.capacity() * sizeof(Vec3);
  return b;
}

std::string close_pairs_summary(const Engine& engine, long long steps) {
  if (!engine.scene().close_pairs_on()) return {};
  char line[200];
  std::snprintf(line, sizeof line,
                "Close pairs: listed %lld times in %lld steps; the last listing kept %.1f %% of "
                "the candidates%s",
                static_cast<long long>(engine.close_builds()), steps, 100 * engine.close_share(),
                engine.close_builds() == 0 || engine.close_used()
                    ? ""
                    : " (over 90 %: every candidate read instead)");
  return line;
}

std::string sleeping_summary(const Engine& engine, double asleep_share, long long steps) {
  if (!engine.scene().sleep.enabled) return {};
  const double per = steps > 0 ? 1.0 / static_cast<double>(steps) : 0.0;
  char line[240];
  std::snprintf(line, sizeof line,
                "Sleeping: %.1f %% of particle-steps asleep, %lld asleep at the end; woke %lld, "
                "fell asleep %lld (%.3g and %.3g per step)",
                100 * asleep_share, static_cast<long long>(engine.sleeping()),
                static_cast<long long>(engine.woke_total()),
                static_cast<long long>(engine.fell_asleep_total()),
                static_cast<double>(engine.woke_total()) * per,
                static_cast<double>(engine.fell_asleep_total()) * per);
  return line;
}

double payload_mass(const State& s, const Mesh& mesh, const ToolPose& pose) {
  if (mesh.vertices.empty()) return 0;
  Vec3 lo = mesh.vertices[0], hi = mesh.vertices[0];
  for (const Vec3& v : mesh.vertices) {
    lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
    hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
  }
  const Mat3 R = to_matrix(pose.orientation);  // tool frame -> ground
  double mass = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Vec3 d = s.x[i] - pose.position;
    // R^T d: the centre in the tool frame.
    const Vec3 l{R.m[0][0] * d.x + R.m[1][0] * d.y + R.m[2][0] * d.z,
                 R.m[0][1] * d.x + R.m[1][1] * d.y + R.m[2][1] * d.z,
                 R.m[0][2] * d.x + R.m[1][2] * d.y + R.m[2][2] * d.z};
    if (l.x >= lo.x && l.x <= hi.x && l.y >= lo.y && l.y <= hi.y && l.z >= lo.z && l.z <= hi.z)
      mass += s.mass[i];
  }
  return mass;
}

double kinetic_energy(const State& s) {
  double e = 0;
  for (std::size_t i = 0; i < s.size(); ++i) e += 0.5 * s.mass[i] * norm2(s.v[i]);
  return e;
}

}  // namespace dem
