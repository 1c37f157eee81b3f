#include "dem/broad_phase.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>


#include "dem/mesh_contact.hpp"

namespace dem {

template <class T>
void BroadPhase::permute(std::vector<T>& a, std::vector<T>& scratch, std::size_t width) {
  const std::size_t n = order_.size();
  scratch.resize(a.size());
#pragma omp parallel for schedule(static) num_threads(threads_)
  for (std::size_t p = 0; p < n; ++p) {
    const std::size_t o = static_cast<std::size_t>(order_[p]);
    for (std::size_t k = 0; k < width; ++k) scratch[p * width + k] = a[o * width + k];
  }
  a.swap(scratch);
}

void BroadPhase::build(const Scene& scene, State& s,
                       const std::vector<std::vector<Vec3>>& tool_vertices, int threads) {
  const std::size_t n = s.size();
  threads_ = std::max(1, threads);
  const double skin = scene.skin_distance();
  const double rmax = scene.r_max();

  // Grid over the particles' bounding box; cells at least one candidate distance wide, so
  // the 27 surrounding cells hold every candidate.
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const Vec3& p : s.x) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  if (n == 0) lo = hi = Vec3{};
  double h = 2 * rmax + skin;
  long nx, ny, nz;
  // A particle far from the rest would blow the cell count up: coarsen the grid instead.
  const double max_cells = std::max<double>(4.0 * static_cast<double>(n), 64.0);
  while (true) {
    nx = static_cast<long>((hi.x - lo.x) / h) + 1;
    ny = static_cast<long>((hi.y - lo.y) / h) + 1;
    nz = static_cast<long>((hi.z - lo.z) / h) + 1;
    if (static_cast<double>(nx) * ny * nz <= max_cells) break;
    h *= 1.25;
  }
  const long ncells = nx * ny * nz;
  const double inv_h = 1.0 / h;
  auto cell_coord = [&](double v, double l, long nmax) {
    long c = static_cast<long>((v - l) * inv_h);
    return std::clamp(c, 0L, nmax - 1);
  };

  // Stable counting sort of particles by cell.
  cell_of_.resize(n);
  cell_start_.assign(static_cast<std::size_t>(ncells) + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 p = s.x[i];
    const long c = (cell_coord(p.z, lo.z, nz) * ny + cell_coord(p.y, lo.y, ny)) * nx +
                   cell_coord(p.x, lo.x, nx);
    cell_of_[i] = static_cast<std::int32_t>(c);
    ++cell_start_[c + 1];
  }
  for (long c = 0; c < ncells; ++c) cell_start_[c + 1] += cell_start_[c];
  order_.resize(n);
  {
    std::vector<std::int32_t>& fill = scratch_i32_;
    fill.assign(cell_start_.begin(), cell_start_.end() - 1);
    for (std::size_t i = 0; i < n; ++i) order_[fill[cell_of_[i]]++] = static_cast<std::int32_t>(i);
  }

  // Keep the old list (old particle indices) to carry tangential history over.
  const bool had_list = s.lists_valid && s.pair_offset.size() == n + 1;
  old_offset_.swap(s.pair_offset);
  old_j_.swap(s.pair_j);
  old_spring_.swap(s.pair_spring);

  permute(s.x, scratch_vec_, 1);
  permute(s.v, scratch_vec_, 1);
  permute(s.u, scratch_vec_, 1);
  permute(s.radius, scratch_d_, 1);
  permute(s.mass, scratch_d_, 1);
  permute(s.species, scratch_i32_, 1);
  permute(s.id, scratch_i64_, 1);
  s.slot_count.resize(n, 0);
  s.slot_key.resize(n * kBoundarySlots, 0);
  s.slot_spring.resize(n * kBoundarySlots);
  permute(s.slot_count, scratch_u8_, 1);
  permute(s.slot_key, scratch_key_, kBoundarySlots);
  permute(s.slot_spring, scratch_vec_, kBoundarySlots);
  // cell_of_ in the new order, for the neighbour stencil.
  for (std::size_t p = 0; p < n; ++p) scratch_i32_[p] = cell_of_[order_[p]];
  scratch_i32_.resize(n);
  cell_of_.swap(scratch_i32_);

  // Half list (j > i), built per thread over contiguous ranges and joined in thread order.
  const int T = std::max(1, threads);
  thread_j_.resize(T);
  thread_used_.assign(T, 0);
  s.pair_offset.assign(n + 1, 0);
#pragma omp parallel num_threads(T)
  {
    const int t = omp_get_thread_num();
    const std::size_t a0 = n * t / T, a1 = n * (t + 1) / T;
    // Work on local vectors: the vector headers of neighbouring threads share a cache line,
    // and push_back on them directly would bounce it between cores.
    // J is used as a raw buffer: its first `used` entries are this thread's list.
    std::vector<std::int32_t> J;
    J.swap(thread_j_[t]);
    std::size_t used = 0;
    const Vec3* const X = s.x.data();
    const double* const R = s.radius.data();
    for (std::size_t a = a0; a < a1; ++a) {
      const long c = cell_of_[a];
      const long cx = c % nx, cy = (c / nx) % ny, cz = c / (nx * ny);
      const Vec3 xa = s.x[a];
      const double ra = s.radius[a];
      std::int32_t count = 0;
      // Cells are numbered x fastest, so the three cells x-1..x+1 of a row are one
      // contiguous index range: 9 ranges instead of 27 cells.
      const long x0 = std::max(cx - 1, 0L), x1 = std::min(cx + 1, nx - 1);
      for (long dz = -1; dz <= 1; ++dz) {
        const long z = cz + dz;
        if (z < 0 || z >= nz) continue;
        for (long dy = -1; dy <= 1; ++dy) {
          const long y = cy + dy;
          if (y < 0 || y >= ny) continue;
          const long row = (z * ny + y) * nx;
          const std::int32_t b0 = std::max<std::int32_t>(cell_start_[row + x0], a + 1);
          const std::int32_t b1 = cell_start_[row + x1 + 1];
          if (b1 <= b0) continue;
          // Branch-free append: write every candidate, advance only on a hit (a hit is
          // rare enough that a branch would mispredict often).
          const std::size_t need = used + static_cast<std::size_t>(b1 - b0);
          if (need > J.size()) J.resize(std::max(need, 2 * J.size()));  // rare: grows once
          std::int32_t* out = J.data() + used;
          std::int32_t hits = 0;
          for (std::int32_t b = b0; b < b1; ++b) {
            const double cut = ra + R[b] + skin;
            const Vec3 d = xa - X[b];
            out[hits] = b;
            hits += norm2(d) < cut * cut;
          }
          used += static_cast<std::size_t>(hits);
          count += hits;
        }
      }
      s.pair_offset[a + 1] = count;
    }
    thread_used_[t] = used;
    J.swap(thread_j_[t]);
  }
  for (std::size_t a = 0; a < n; ++a) s.pair_offset[a + 1] += s.pair_offset[a];
  s.pair_j.resize(s.pair_offset[n]);
  s.pair_spring.assign(s.pair_offset[n], Vec3{});  // filled from the old list below
  {
    std::size_t pos = 0;
    for (int t = 0; t < T; ++t) {
      std::copy(thread_j_[t].begin(), thread_j_[t].begin() + thread_used_[t],
                s.pair_j.begin() + pos);
      pos += thread_used_[t];
    }
  }

  // Carry the tangential springs of pairs in contact over to the new list. Only non-zero
  // springs are looked up: most candidates are not touching. Each old pair maps to at most
  // one new entry, so the parallel writes never collide.
  if (had_list) {
    new_index_.resize(n);
    for (std::size_t p = 0; p < n; ++p) new_index_[order_[p]] = static_cast<std::int32_t>(p);
#pragma omp parallel for schedule(static) num_threads(T)
    for (std::size_t oa = 0; oa < n; ++oa) {
      for (std::int32_t k = old_offset_[oa]; k < old_offset_[oa + 1]; ++k) {
        const Vec3 sp = old_spring_[k];
        if (sp.x == 0 && sp.y == 0 && sp.z == 0) continue;
        const std::int32_t na = new_index_[oa], nb = new_index_[old_j_[k]];
        const bool swap = na > nb;  // the spring is stored on the lower index of the pair
        const std::int32_t row = swap ? nb : na, col = swap ? na : nb;
        for (std::int32_t q = s.pair_offset[row]; q < s.pair_offset[row + 1]; ++q)
          if (s.pair_j[q] == col) {
            s.pair_spring[q] = swap ? -sp : sp;
            break;
          }
      }
    }
  }

  // Particle-triangle candidates: each triangle visits the cells its box (grown by the
  // largest radius and the skin) overlaps. Threads take contiguous triangle ranges and their
  // lists are joined in thread order: the same list as one thread makes.
  tri_candidates_.clear();
  const double margin = rmax + skin;
  thread_tri_.resize(T);
  for (std::size_t m = 0; m < scene.tools.size(); ++m) {
    const Mesh& mesh = scene.tools[m].mesh;
    const Vec3* wv = tool_vertices[m].data();
    const std::size_t ntri = mesh.triangles.size();
    const int TT = ntri >= 256 ? T : 1;  // a handful of triangles is not worth a fork
#pragma omp parallel num_threads(TT)
    {
      const int th = omp_get_thread_num();
      std::vector<TriCandidate>& out = thread_tri_[th];
      out.clear();
      const std::size_t t0 = ntri * th / TT, t1 = ntri * (th + 1) / TT;
      for (std::size_t tt = t0; tt < t1; ++tt) {
        const std::int32_t t = static_cast<std::int32_t>(tt);
        const auto& T3 = mesh.triangles[tt];
        const Vec3 a = wv[T3[0]], b = wv[T3[1]], c = wv[T3[2]];
        const Vec3 bmin{std::min({a.x, b.x, c.x}) - margin, std::min({a.y, b.y, c.y}) - margin,
                        std::min({a.z, b.z, c.z}) - margin};
        const Vec3 bmax{std::max({a.x, b.x, c.x}) + margin, std::max({a.y, b.y, c.y}) + margin,
                        std::max({a.z, b.z, c.z}) + margin};
        if (n == 0 || bmax.x < lo.x || bmax.y < lo.y || bmax.z < lo.z || bmin.x > hi.x ||
            bmin.y > hi.y || bmin.z > hi.z)
          continue;
        const long x0 = cell_coord(bmin.x, lo.x, nx), x1 = cell_coord(bmax.x, lo.x, nx);
        const long y0 = cell_coord(bmin.y, lo.y, ny), y1 = cell_coord(bmax.y, lo.y, ny);
        const long z0 = cell_coord(bmin.z, lo.z, nz), z1 = cell_coord(bmax.z, lo.z, nz);
        for (long z = z0; z <= z1; ++z)
          for (long y = y0; y <= y1; ++y)
            for (long x = x0; x <= x1; ++x) {
              const long cc = (z * ny + y) * nx + x;
              for (std::int32_t p = cell_start_[cc]; p < cell_start_[cc + 1]; ++p) {
                const double cut = s.radius[p] + skin;
                if (closest_on_triangle(mesh, wv, t, s.x[p]).dist2 < cut * cut)
                  out.push_back({p, static_cast<std::int32_t>(m), t});
              }
            }
      }
    }
    for (int th = 0; th < TT; ++th)
      tri_candidates_.insert(tri_candidates_.end(), thread_tri_[th].begin(), thread_tri_[th].end());
  }
  s.tri_offset.assign(n + 1, 0);
  for (const auto& c : tri_candidates_) ++s.tri_offset[c.particle + 1];
  for (std::size_t a = 0; a < n; ++a) s.tri_offset[a + 1] += s.tri_offset[a];
  s.tri_tool.resize(tri_candidates_.size());
  s.tri_index.resize(tri_candidates_.size());
  tri_count_.assign(s.tri_offset.begin(), s.tri_offset.end() - 1);
  for (const auto& c : tri_candidates_) {  // stable: per particle ordered by (tool, triangle)
    const std::int32_t k = tri_count_[c.particle]++;
    s.tri_tool[k] = c.tool;
    s.tri_index[k] = c.tri;
  }

  // Wall candidates: most particles are far from every wall and skip the wall loop.
  s.wall_mask.resize(n);
  const std::size_t nw = scene.walls.size();
#pragma omp parallel for schedule(static) num_threads(threads_)
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t mask = 0;
    if (nw > 32) {
      mask = ~0u;
    } else {
      for (std::size_t w = 0; w < nw; ++w)
        if (dot(s.x[i] - scene.walls[w].point, scene.walls[w].normal) < s.radius[i] + skin)
          mask |= 1u << w;
    }
    s.wall_mask[i] = mask;
  }
  s.x_at_rebuild.resize(n);
#pragma omp parallel for schedule(static) num_threads(threads_)
  for (std::size_t i = 0; i < n; ++i) s.x_at_rebuild[i] = s.x[i];
  s.tool_pose_at_rebuild = s.tool_pose;
  s.max_displacement = 0;
  s.steps_since_rebuild = 0;
  s.lists_valid = true;
  ++s.rebuilds;
}

}  // namespace dem
