#include "dem/far_movers.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

#include "dem/mesh_contact.hpp"

namespace dem {

bool FarMoverGuard::fires(const Scene& scene, const State& s, double* moved) {
  // A pair not in the list was more than `skin` apart at the last broad phase; it can touch
  // only after the two bodies together moved more than that.
  // The two largest displacements belong to two different particles, so their sum bounds what
  // any pair moved together (twice the largest, the usual bound, waits for half the skin when
  // one grain flies); one particle alone reaches a wall or mesh triangle not among its
  // candidates only after moving the whole skin, which the sum covers too.
  // The contact law acts from a gap below dt/2 |v_n| on (the step's window, docs/physics.md),
  // so the window is added: dt/2 (|u_a| + |u_b|) <= dt u_max for a pair, dt/2 (|u| + the
  // fastest point of the tool) for a tool.
  if (!stamp_.matches(s, kStampFields)) find(scene, s);
  const double worst = bound(scene, s, u_max_);
  *moved = worst;
  return worst > scene.skin_distance();
}

double FarMoverGuard::bound(const Scene& scene, const State& s, double u_max) {
  const double window = scene.dt * u_max;
  double worst = s.max_displacement + s.second_displacement + window;
  for (std::size_t m = 0; m < scene.tools.size(); ++m)
    worst = std::max(worst, s.max_displacement + tool_move(scene, s, m) + 0.5 * window +
                                tool_window(scene, s, m));
  return worst;
}

std::string FarMoverGuard::strict_message(const Scene& scene, const State& s, double moved) {
  std::ostringstream msg;
  msg << "broad phase guard at step " << s.step << " (t = " << s.step * scene.dt
      << " s): bodies moved " << moved << " m since the last broad phase (with this step's "
      << "contact window), more than the skin " << scene.skin_distance() << " m; contacts could "
      << "be missed. Lower scene.broad_phase_interval (now " << scene.broad_phase_interval
      << ") or raise scene.skin (now " << scene.skin
      << "), or set scene.guard: rebuild to rebuild early automatically";
  return msg.str();
}

double FarMoverGuard::tool_window(const Scene& scene, const State& s, std::size_t m) {
  const ToolPose& tp = s.tool_pose[m];
  return 0.5 * scene.dt *
         (norm(tp.velocity) + norm(tp.angular_velocity) * scene.tools[m].mesh.bounding_radius);
}

double FarMoverGuard::tool_move(const Scene& scene, const State& s, std::size_t m) {
  const ToolPose& now = s.tool_pose[m];
  const ToolPose& then = s.tool_pose_at_rebuild[m];
  const double angle = angle_between(now.orientation, then.orientation);
  return norm(now.position - then.position) +
         2 * std::sin(std::min(angle, M_PI) / 2) * scene.tools[m].mesh.bounding_radius;
}

FarMoverGuard::Limits FarMoverGuard::limits(const Scene& scene) {
  const double half = 0.5 * scene.skin_distance();
  const double d = 0.9 * half, u = 0.1 * half / (0.5 * scene.dt);
  return {d * d, u * u};
}

void FarMoverGuard::finish(const State& s, int lists, const Tally& tally, bool merge_sorted) {
  far_.clear();
  overflow_ = false;
  for (int t = 0; t < lists; ++t)
    for (std::int32_t i : thread_far_[static_cast<std::size_t>(t)]) {
      if (far_.size() < kMaxFarMovers)
        far_.push_back(i);
      else
        overflow_ = true;
    }
  near_max_ = std::sqrt(tally.near2);
  near_u_max_ = std::sqrt(tally.near_u2);
  u_max_ = std::sqrt(tally.u2);
  stamp_.take(s);
  if (merge_sorted) {
    std::sort(far_.begin(), far_.end());
    far_.erase(std::unique(far_.begin(), far_.end()), far_.end());
  }
}

void FarMoverGuard::find(const Scene& scene, const State& s) {
  const Limits lim = limits(scene);
  if (thread_far_.empty()) thread_far_.resize(1);
  thread_far_[0].clear();
  Tally tally;
  for (std::size_t i = 0; i < s.size(); ++i)
    note(thread_far_[0], tally, i, norm2(s.x[i] - s.x_at_rebuild[i]), norm2(s.u[i]), lim);
  finish(s, 1, tally);
}

void FarMoverGuard::build_mesh_grids(const Scene& scene) {
  mesh_grid_.assign(scene.tools.size(), MeshGrid{});
  for (std::size_t m = 0; m < scene.tools.size(); ++m) {
    const Mesh& mesh = scene.tools[m].mesh;
    MeshGrid& g = mesh_grid_[m];
    if (mesh.vertices.empty()) continue;
    Vec3 lo = mesh.vertices[0], hi = lo;
    for (const Vec3& v : mesh.vertices) {
      lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
      hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
    }
    // Cells a candidate distance wide, at most about 4 per triangle.
    double h = 2 * scene.r_max() + scene.skin_distance();
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

bool FarMoverGuard::unlisted_triangle_near(const Scene& scene, const State& s,
                                           const ToolGeometry& tools, std::size_t e,
                                           std::size_t m, double reach) const {
  const MeshGrid& g = mesh_grid_[m];
  if (g.start.empty()) return false;  // a mesh without vertices
  const Mesh& mesh = scene.tools[m].mesh;
  const Vec3 q = to_frame(tools.rotation[m], s.x[e] - s.tool_pose[m].position);  // mesh frame
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
  const Vec3* wv = tools.vertices[m].data();
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
bool FarMoverGuard::clear(const Scene& scene, const State& s, BroadPhase& broad,
                          const ToolGeometry& tools) {
  if (!stamp_.matches(s, kStampFields)) find(scene, s);
  if (overflow_ || s.x_at_rebuild.size() != s.size() || s.wall_mask.size() != s.size())
    return false;
  if (!broad.grid_matches(s) && !broad.restore_grid(scene, s)) return false;
  const double skin = scene.skin_distance();
  const std::size_t ntools = scene.tools.size();
  std::vector<double>& moves = tool_moves_;
  moves.resize(ntools);
  const double dt = scene.dt, rmax = scene.r_max();
  // Pairs of the others, and the others against walls, are within the bound with the window
  // (note()); against a tool they are if d + dt/2 |u| + d_t + the tool's part is.
  for (std::size_t m = 0; m < ntools; ++m) {
    moves[m] = tool_move(scene, s, m) + tool_window(scene, s, m);  // with the tool's window
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
  const RegionOptions& region = scene.region;
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
    for (std::size_t w = 0; w < scene.walls.size() && w < 32; ++w) {
      if ((s.wall_mask[e] >> w) & 1u) continue;
      const Wall& wall = scene.walls[w];
      if (dot(xe - wall.point, wall.normal) < wall_reach) return false;
    }
    // Tools that may have come within reach of a triangle not among its candidates: the
    // triangles within the reach of boundary_contacts this step must all be candidates (a
    // particle without a boundary slot block has none).
    const double disp = norm(xe - s.x_at_rebuild[e]) + 0.5 * dt * ue;
    for (std::size_t m = 0; m < ntools; ++m) {
      if (disp + moves[m] <= skin) continue;
      const Mesh& mesh = scene.tools[m].mesh;
      const ToolPose& tp = s.tool_pose[m];
      const double reach = re + 0.5 * dt * (ue + norm(tp.velocity) +
                                            norm(tp.angular_velocity) * mesh.bounding_radius);
      const double far = mesh.bounding_radius + reach * (1 + 1e-9);
      if (norm2(xe - tp.position) >= far * far) continue;  // beyond every vertex
      if (mesh_grid_.size() != ntools) build_mesh_grids(scene);
      if (unlisted_triangle_near(scene, s, tools, e, m, reach)) return false;
    }
    // Particles: those that moved at most half the skin, found through the grid ... (first
    // against the reach with the fastest speed of all, u_max_ >= |u_b|: what it rules out,
    // unlisted_near would too)
    bool clear = true;
    const double reach = (re + rmax + 0.5 * dt * (ue + u_max_) + 0.5 * skin) * (1 + 1e-9);
    const double pre = re + 0.5 * dt * (ue + u_max_);
    broad.for_each_near(xe, reach, [&](std::int32_t b) {
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

}  // namespace dem
