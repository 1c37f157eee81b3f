#include "dem/broad_phase.hpp"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#include "dem/mesh_contact.hpp"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace dem {

namespace detail {

std::int32_t row_hits_scalar(const RowData& d, Vec3 xa, double ra, double skin, std::int32_t a,
                             const std::int32_t* row_begin, const std::int32_t* row_end,
                             int rows, std::int32_t* out, std::int32_t& touching) {
  std::int32_t hits = 0, touch = 0;
  for (int q = 0; q < rows; ++q) {
    const std::int32_t b0 = std::max(row_begin[q], a + 1), b1 = row_end[q];
    for (std::int32_t b = b0; b < b1; ++b) {
      const double rsum = ra + d.r[b], cut = rsum + skin;
      const double dx = xa.x - d.x[b], dy = xa.y - d.y[b], dz = xa.z - d.z[b];
      const double d2 = dx * dx + dy * dy + dz * dz;
      out[hits] = b;  // branch-free append: a hit is rare enough that a branch mispredicts
      hits += d2 < cut * cut;
      touch += d2 < rsum * rsum;
    }
  }
  touching += touch;
  return hits;
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx512f,avx512vl"))) static std::int32_t row_hits_avx512(
    const RowData& d, Vec3 xa, double ra, double skin, std::int32_t a,
    const std::int32_t* row_begin, const std::int32_t* row_end, int rows, std::int32_t* out,
    std::int32_t& touching) {
  const __m512d ax = _mm512_set1_pd(xa.x), ay = _mm512_set1_pd(xa.y), az = _mm512_set1_pd(xa.z);
  const __m512d vr = _mm512_set1_pd(ra), vs = _mm512_set1_pd(skin);
  const __m256i iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  std::int32_t hits = 0, touch = 0;
  for (int q = 0; q < rows; ++q) {
    const std::int32_t b0 = std::max(row_begin[q], a + 1), b1 = row_end[q];
    for (std::int32_t b = b0; b < b1; b += 8) {
      const int left = b1 - b;
      const __mmask8 live = left >= 8 ? 0xFF : static_cast<__mmask8>((1u << left) - 1);
      const __m512d bx = _mm512_maskz_loadu_pd(live, d.x + b);
      const __m512d by = _mm512_maskz_loadu_pd(live, d.y + b);
      const __m512d bz = _mm512_maskz_loadu_pd(live, d.z + b);
      const __m512d br = _mm512_maskz_loadu_pd(live, d.r + b);
      const __m512d rsum = _mm512_add_pd(vr, br), cut = _mm512_add_pd(rsum, vs);
      const __m512d dx = _mm512_sub_pd(ax, bx), dy = _mm512_sub_pd(ay, by),
                    dz = _mm512_sub_pd(az, bz);
      const __m512d d2 = _mm512_add_pd(
          _mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)), _mm512_mul_pd(dz, dz));
      const __mmask8 hit =
          _mm512_mask_cmp_pd_mask(live, d2, _mm512_mul_pd(cut, cut), _CMP_LT_OQ);
      const __mmask8 tch =
          _mm512_mask_cmp_pd_mask(live, d2, _mm512_mul_pd(rsum, rsum), _CMP_LT_OQ);
      const __m256i idx = _mm256_add_epi32(_mm256_set1_epi32(b), iota);
      // Compressed in a register and stored whole (8 lanes; the caller leaves kRowHitsSlack
      // entries of room past the candidates): AMD's Zen 4 and 5 run vpcompressd to memory as
      // microcode, about half of this loop's time (perf, 2026-12-06), the register form fast.
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + hits),
                          _mm256_maskz_compress_epi32(hit, idx));
      hits += __builtin_popcount(hit);
      touch += __builtin_popcount(tch);
    }
  }
  touching += touch;
  return hits;
}
#endif

#if defined(__x86_64__) && defined(__GNUC__)
// The same test 4 candidates at a time with AVX2, for processors without AVX-512 (AMD Zen 2 and
// 3, most Intel client parts): the same operations in the same order (no FMA in the target), the
// hits appended in lane order through a table of the 16 masks.
struct Compress4 {
  std::int32_t lanes[16][4];
  constexpr Compress4() : lanes{} {
    for (int m = 0; m < 16; ++m) {
      int n = 0;
      for (int l = 0; l < 4; ++l)
        if ((m >> l) & 1) lanes[m][n++] = l;
    }
  }
};
alignas(64) static constexpr Compress4 kCompress4{};

__attribute__((target("avx2"))) static std::int32_t row_hits_avx2_impl(
    const RowData& d, Vec3 xa, double ra, double skin, std::int32_t a,
    const std::int32_t* row_begin, const std::int32_t* row_end, int rows, std::int32_t* out,
    std::int32_t& touching) {
  const __m256d ax = _mm256_set1_pd(xa.x), ay = _mm256_set1_pd(xa.y), az = _mm256_set1_pd(xa.z);
  const __m256d vr = _mm256_set1_pd(ra), vs = _mm256_set1_pd(skin);
  const __m256i iota = _mm256_setr_epi64x(0, 1, 2, 3);
  std::int32_t hits = 0, touch = 0;
  for (int q = 0; q < rows; ++q) {
    const std::int32_t b0 = std::max(row_begin[q], a + 1), b1 = row_end[q];
    for (std::int32_t b = b0; b < b1; b += 4) {
      // Lanes l < left are live; the others read nothing (masked loads) and never hit.
      const __m256i live = _mm256_cmpgt_epi64(_mm256_set1_epi64x(b1 - b), iota);
      const __m256d bx = _mm256_maskload_pd(d.x + b, live);
      const __m256d by = _mm256_maskload_pd(d.y + b, live);
      const __m256d bz = _mm256_maskload_pd(d.z + b, live);
      const __m256d br = _mm256_maskload_pd(d.r + b, live);
      const __m256d rsum = _mm256_add_pd(vr, br), cut = _mm256_add_pd(rsum, vs);
      const __m256d dx = _mm256_sub_pd(ax, bx), dy = _mm256_sub_pd(ay, by),
                    dz = _mm256_sub_pd(az, bz);
      const __m256d d2 = _mm256_add_pd(
          _mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
      const __m256d lv = _mm256_castsi256_pd(live);
      const int hit = _mm256_movemask_pd(
          _mm256_and_pd(lv, _mm256_cmp_pd(d2, _mm256_mul_pd(cut, cut), _CMP_LT_OQ)));
      const int tch = _mm256_movemask_pd(
          _mm256_and_pd(lv, _mm256_cmp_pd(d2, _mm256_mul_pd(rsum, rsum), _CMP_LT_OQ)));
      // 4 entries stored whole (the caller leaves kRowHitsSlack entries of room).
      const __m128i lanes =
          _mm_load_si128(reinterpret_cast<const __m128i*>(kCompress4.lanes[hit]));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(out + hits),
                       _mm_add_epi32(_mm_set1_epi32(b), lanes));
      hits += __builtin_popcount(static_cast<unsigned>(hit));
      touch += __builtin_popcount(static_cast<unsigned>(tch));
    }
  }
  touching += touch;
  return hits;
}
#endif

static bool has_avx512_row_test() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl");
#else
  return false;
#endif
}

bool row_hits_avx2_available() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2");
#else
  return false;
#endif
}

bool row_hits_vector_available() { return has_avx512_row_test() || row_hits_avx2_available(); }

std::int32_t row_hits_avx2(const RowData& d, Vec3 xa, double ra, double skin, std::int32_t a,
                           const std::int32_t* row_begin, const std::int32_t* row_end, int rows,
                           std::int32_t* out, std::int32_t& touching) {
#if defined(__x86_64__) && defined(__GNUC__)
  if (row_hits_avx2_available())
    return row_hits_avx2_impl(d, xa, ra, skin, a, row_begin, row_end, rows, out, touching);
#endif
  return row_hits_scalar(d, xa, ra, skin, a, row_begin, row_end, rows, out, touching);
}

using RowHits = std::int32_t (*)(const RowData&, Vec3, double, double, std::int32_t,
                                 const std::int32_t*, const std::int32_t*, int, std::int32_t*,
                                 std::int32_t&);

// The one place that picks the test: the vector one when asked for and available (AVX-512, else
// AVX2).
static RowHits choose_row_hits(bool vector) {
#if defined(__x86_64__) && defined(__GNUC__)
  if (vector && has_avx512_row_test()) return row_hits_avx512;
  if (vector && row_hits_avx2_available()) return row_hits_avx2_impl;
#endif
  return row_hits_scalar;
}

std::int32_t row_hits_vector(const RowData& d, Vec3 xa, double ra, double skin, std::int32_t a,
                             const std::int32_t* row_begin, const std::int32_t* row_end,
                             int rows, std::int32_t* out, std::int32_t& touching) {
  return choose_row_hits(true)(d, xa, ra, skin, a, row_begin, row_end, rows, out, touching);
}

}  // namespace detail

namespace {

using detail::RowData;
using detail::RowHits;

}  // namespace

void BroadPhase::use_vector_row_test(bool vector) { vector_row_test_ = vector; }
void BroadPhase::use_history_same_rows(bool same_rows) { history_same_rows_ = same_rows; }


template <class T>
void BroadPhase::permute(std::vector<T>& a, std::size_t p0, std::size_t p1) {
  static_assert(std::is_trivially_copyable_v<T>, "State arrays are flat arrays of plain values");
  const std::size_t w = p1 - p0;
  // One byte buffer for every type: it grows to the largest window once, then stays.
  if (scratch_.size() < w * sizeof(T)) scratch_.resize(w * sizeof(T));
  T* const out = reinterpret_cast<T*>(scratch_.data());  // operator new's alignment suffices
  T* const arr = a.data();
  const std::int32_t* const order = order_.data();
#pragma omp parallel num_threads(threads_)
  {
#pragma omp for schedule(static)
    for (std::size_t p = p0; p < p1; ++p) out[p - p0] = arr[order[p]];
#pragma omp for schedule(static)
    for (std::size_t p = p0; p < p1; ++p) arr[p] = out[p - p0];
  }
}

namespace {
template <class T>
std::size_t held(const std::vector<T>& v) {
  return v.capacity() * sizeof(T);
}
}  // namespace

std::size_t BroadPhase::workspace_bytes() const {
  std::size_t b = held(cell_of_) + held(cell_start_) + held(fill_) + held(order_) +
                  held(new_index_) + held(scratch_) + held(old_offset_) + held(old_j_) +
                  held(old_spring_) + held(pool_key_) + held(pool_spring_) + held(old_roll_) + held(pool_roll_) +
                  held(tri_candidates_) + held(tri_count_) + held(px_) + held(py_) +
                  held(pz_) + held(pr_);
  for (const auto& v : thread_j_) b += held(v);
  for (const auto& v : thread_tri_) b += held(v);
  return b;
}

// Cells at least h wide over the box [lo, hi]; a particle far from the rest would blow the
// cell count up: the grid is coarsened instead.
void BroadPhase::set_grid(Vec3 lo, Vec3 hi, std::size_t n, double h) {
  long nx, ny, nz;
  detail::grid_cells(lo, hi, std::max<double>(4.0 * static_cast<double>(n), 64.0), h, nx, ny, nz);
  lo_ = lo;
  inv_h_ = 1.0 / h;
  nx_ = nx;
  ny_ = ny;
  nz_ = nz;
}

bool BroadPhase::grid_matches(const State& s) const {
  return grid_stamp_.matches(s, kGridFields);
}

// The grid of the last broad phase from the positions it binned (State::x_at_rebuild, which are
// in cell order): after a restart from a checkpoint, when this object has not built the lists.
bool BroadPhase::restore_grid(const Scene& scene, const State& s) {
  const std::size_t n = s.size();
  if (!s.lists_valid || s.x_at_rebuild.size() != n) return false;
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const Vec3& p : s.x_at_rebuild) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  if (n == 0) lo = hi = Vec3{};
  set_grid(lo, hi, n, 2 * scene.r_max() + scene.skin_distance());
  cell_start_.assign(static_cast<std::size_t>(nx_ * ny_ * nz_) + 1, 0);
  long last = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const long c = cell_index(s.x_at_rebuild[i]);
    if (c < last) {  // not in cell order: not a grid this object can rebuild
      cell_start_.clear();
      return false;
    }
    last = c;
    ++cell_start_[c + 1];
  }
  for (std::size_t c = 0; c + 1 < cell_start_.size(); ++c) cell_start_[c + 1] += cell_start_[c];
  grid_stamp_.take(s);
  return true;
}

void BroadPhase::build(const Scene& scene, State& s,
                       const std::vector<std::vector<Vec3>>& tool_vertices, int threads) {
  const int T = std::max(1, threads);
  threads_ = T;
  const double skin = scene.skin_distance();
  cosim::Stopwatch watch;
  make_grid(s, T, scene.r_max(), skin);
  stages_.lap(stage::grid, watch);
  const auto [p0, p1] = sort_by_cell(s, T);
  stages_.lap(stage::sort, watch);
  const bool had_list = permute_state(s, p0, p1);
  stages_.lap(stage::permute, watch);
  list_pairs(s, T, skin);
  stages_.lap(stage::pair_list, watch);
  if (had_list) carry_history(s, T);
  stages_.lap(stage::history, watch);
  list_mesh_candidates(scene, s, tool_vertices, T, skin);
  stages_.lap(stage::mesh_candidates, watch);

  // --- wall masks, reference positions for the guard, boundary history slots.
  boundary_slots(scene, s, skin);
  s.tool_pose_at_rebuild = s.tool_pose;
  stages_.lap(stage::wall_masks, watch);
  s.max_displacement = 0;
  s.second_displacement = 0;
  s.pair_row_offset.clear();  // the lists by partner: built again when sleeping needs them
  s.pair_row.clear();
  s.steps_since_rebuild = 0;
  s.lists_valid = true;
  ++s.rebuilds;
  grid_stamp_.take(s);  // steps_since_rebuild is 0: built at this step
}

void BroadPhase::make_grid(const State& s, int T, double rmax, double skin) {
  const std::size_t n = s.size();
  // --- grid: bounding box of the particles (min and max are exact, so any thread count
  // gives the same box); cells at least one candidate distance wide, so the 27 surrounding
  // cells hold every candidate.
  double lx = 1e300, ly = 1e300, lz = 1e300, hx = -1e300, hy = -1e300, hz = -1e300;
  {
    const Vec3* const X = s.x.data();
#pragma omp parallel for schedule(static) num_threads(T) \
    reduction(min : lx, ly, lz) reduction(max : hx, hy, hz)
    for (std::size_t i = 0; i < n; ++i) {
      lx = std::min(lx, X[i].x), ly = std::min(ly, X[i].y), lz = std::min(lz, X[i].z);
      hx = std::max(hx, X[i].x), hy = std::max(hy, X[i].y), hz = std::max(hz, X[i].z);
    }
  }
  Vec3 lo{lx, ly, lz}, hi{hx, hy, hz};
  if (n == 0) lo = hi = Vec3{};
  set_grid(lo, hi, n, 2 * rmax + skin);
  box_lo_ = lo;
  box_hi_ = hi;
}

std::pair<std::size_t, std::size_t> BroadPhase::sort_by_cell(const State& s, int T) {
  const std::size_t n = s.size();
  // --- sort: stable counting sort of particles by cell (cells numbered x fastest).
  cell_of_.resize(n);
#pragma omp parallel for schedule(static) num_threads(T)
  for (std::size_t i = 0; i < n; ++i) {
    cell_of_[i] = static_cast<std::int32_t>(cell_index(s.x[i]));
  }
  const long ncells = nx_ * ny_ * nz_;
  cell_start_.assign(static_cast<std::size_t>(ncells) + 1, 0);
  for (std::size_t i = 0; i < n; ++i) ++cell_start_[cell_of_[i] + 1];
  for (long c = 0; c < ncells; ++c) cell_start_[c + 1] += cell_start_[c];
  order_.resize(n);
  fill_.assign(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t i = 0; i < n; ++i) order_[fill_[cell_of_[i]]++] = static_cast<std::int32_t>(i);
  // The window of positions whose particle changed: in a bed at rest between two broad
  // phases few particles cross a cell face, and often none does.
  std::size_t p0 = 0, p1 = n;
  while (p0 < n && order_[p0] == static_cast<std::int32_t>(p0)) ++p0;
  while (p1 > p0 && order_[p1 - 1] == static_cast<std::int32_t>(p1 - 1)) --p1;
  return {p0, p1};
}

bool BroadPhase::permute_state(State& s, std::size_t p0, std::size_t p1) {
  const std::size_t n = s.size();
  // --- permute: every per-particle array (State's field list) into the new order, only in
  // the window. The old pair list keeps its old indices, to carry the history over.
  const bool had_list = s.lists_valid && s.pair_offset.size() == n + 1;
  old_offset_.swap(s.pair_offset);
  old_j_.swap(s.pair_j);
  old_spring_.swap(s.pair_spring);
  old_roll_.swap(s.pair_roll);  // the rotating model's rolling springs (empty otherwise)
  s.pair_roll.clear();
  s.slot_count.resize(n, 0);
  s.slot_block.resize(n, -1);
  last_permuted_ = p1 - p0;
  if (p1 > p0) {
    for_each_array(s, [&](const char*, auto& a, Field field) {
      if (field != Field::derived && !a.empty()) permute(a, p0, p1);  // Field::model: maybe empty
    });
    permute(cell_of_, p0, p1);  // cell_of_ in the new order, for the stencil
  }
  return had_list;
}

void BroadPhase::list_pairs(State& s, int T, double skin) {
  const std::size_t n = s.size();
  // --- pair list: half list (j > i), built per thread over contiguous ranges; each thread
  // writes its rows into the shared list at its offset, so the list is the same for any
  // thread count.
  thread_j_.resize(T);
  thread_used_.assign(T, 0);
  thread_base_.assign(T + 1, 0);
  s.pair_offset.resize(n + 1);
  s.pair_offset[0] = 0;
  s.pair_work.resize(n + 1);
  s.pair_work[0] = 0;
  work_base_.assign(T + 1, 0);
  px_.resize(n);
  py_.resize(n);
  pz_.resize(n);
  pr_.resize(n);
  const RowData rd{px_.data(), py_.data(), pz_.data(), pr_.data()};
  const RowHits row_hits = detail::choose_row_hits(vector_row_test_);
  const long nx = nx_, ny = ny_, nz = nz_;
#pragma omp parallel num_threads(T)
  {
    const int t = omp_get_thread_num();
    const std::size_t a0 = n * t / T, a1 = n * (t + 1) / T;
    // Positions and radii as separate arrays in the new order, for the distance test of whole
    // stencil rows at once (row_hits).
    for (std::size_t a = a0; a < a1; ++a) {
      px_[a] = s.x[a].x;
      py_[a] = s.x[a].y;
      pz_[a] = s.x[a].z;
      pr_[a] = s.radius[a];
    }
#pragma omp barrier
    // Work on a local vector: the vector headers of neighbouring threads share a cache line.
    // J is used as a raw buffer: its first `used` entries are this thread's list.
    std::vector<std::int32_t> J;
    J.swap(thread_j_[t]);
    std::size_t used = 0;
    const Vec3* const X = s.x.data();
    const double* const R = s.radius.data();
    const std::int32_t* const start = cell_start_.data();
    std::int32_t* const offset = s.pair_offset.data();
    std::int64_t* const work = s.pair_work.data();
    // The cells after a particle's own in the numbering, within one cell: its own row (from
    // the particle itself on) and four more rows of three cells (x-1..x+1 are one contiguous
    // index range). The earlier rows list their pairs with this one themselves.
    long cell = -1;
    std::int32_t row_begin[5], row_end[5];
    int rows = 0;
    std::int32_t span = 0;  // candidates in the rows: at most this many hits
    for (std::size_t a = a0; a < a1; ++a) {
      if (cell_of_[a] != cell) {  // the rows are the same for every particle of a cell
        cell = cell_of_[a];
        const long cx = cell % nx, cy = (cell / nx) % ny, cz = cell / (nx * ny);
        const long x0 = std::max(cx - 1, 0L), x1 = std::min(cx + 1, nx - 1);
        rows = 0;
        const long dzdy[5][2] = {{0, 0}, {0, 1}, {1, -1}, {1, 0}, {1, 1}};
        for (const auto& d : dzdy) {
          const long z = cz + d[0], y = cy + d[1];
          if (z >= nz || y < 0 || y >= ny) continue;
          const long row = (z * ny + y) * nx;
          row_begin[rows] = start[row + x0];
          row_end[rows] = start[row + x1 + 1];
          if (row_end[rows] > row_begin[rows]) ++rows;
        }
        span = 0;
        for (int r = 0; r < rows; ++r) span += row_end[r] - row_begin[r];
      }
      const std::size_t need = used + static_cast<std::size_t>(span) + detail::kRowHitsSlack;
      if (need > J.size()) J.resize(std::max(need, 2 * J.size()));  // rare: grows once
      std::int32_t touching = 0;
      const std::int32_t count = row_hits(rd, X[a], R[a], skin, static_cast<std::int32_t>(a),
                                          row_begin, row_end, rows, J.data() + used, touching);
      used += static_cast<std::size_t>(count);
      offset[a + 1] = count;
      // Work of the row for the threads of the pair forces: a touching pair costs about four
      // times a candidate that is not (docs/performance.md).
      work[a + 1] = 1 + count + 4 * touching;
    }
    thread_used_[t] = used;
    std::int64_t wsum = 0;
    for (std::size_t a = a0; a < a1; ++a) work[a + 1] = wsum += work[a + 1];
    work_base_[t + 1] = wsum;
#pragma omp barrier
#pragma omp single
    {
      for (int k = 0; k < T; ++k) thread_base_[k + 1] = thread_base_[k] + thread_used_[k];
      for (int k = 0; k < T; ++k) work_base_[k + 1] += work_base_[k];
      s.pair_j.resize(thread_base_[T]);
      s.pair_spring.resize(thread_base_[T]);
    }
    std::int32_t run = static_cast<std::int32_t>(thread_base_[t]);
    for (std::size_t a = a0; a < a1; ++a) offset[a + 1] = run += offset[a + 1];
    for (std::size_t a = a0; a < a1; ++a) work[a + 1] += work_base_[t];
    std::copy(J.begin(), J.begin() + used, s.pair_j.begin() + thread_base_[t]);
    std::fill(s.pair_spring.begin() + thread_base_[t],
              s.pair_spring.begin() + thread_base_[t] + used, Vec3{});
    J.swap(thread_j_[t]);
  }
}

void BroadPhase::carry_history(State& s, int T) {
  const std::size_t n = s.size();
  // --- history: carry the tangential springs of pairs in contact over to the new list. Only
  // non-zero springs are looked up: most candidates are not touching. Each old pair maps to
  // at most one new entry, so the parallel writes never collide.
  // The rotating model's rolling springs go with the tangential ones (the torque on the pair's
  // lower index).
  const bool rolls = !old_roll_.empty() && old_roll_.size() == old_j_.size();
  if (rolls) s.pair_roll.assign(s.pair_j.size(), Vec3{});
  {
    new_index_.resize(n);
#pragma omp parallel for schedule(static) num_threads(T)
    for (std::size_t p = 0; p < n; ++p) new_index_[order_[p]] = static_cast<std::int32_t>(p);
    // A row whose new row lists the new indices of the same partners in the same order (most
    // rows of a bed between two broad phases, whether or not particles were renumbered) takes
    // each held spring to the same place: copied without a look-up (and without the branch on
    // whether it is held, which a bed's mix of touching and apart candidates mispredicts). No
    // other old row writes into that new row: a pair of its particle with a partner not in the
    // old row would be an entry the comparison did not find.
    const bool same_rows = history_same_rows_;
    std::int64_t copied = 0, looked_up = 0;
#pragma omp parallel for schedule(static) num_threads(T) reduction(+ : copied, looked_up)
    for (std::size_t oa = 0; oa < n; ++oa) {
      const std::int32_t k0 = old_offset_[oa], k1 = old_offset_[oa + 1];
      const std::int32_t na = new_index_[oa];
      if (same_rows && s.pair_offset[na + 1] - s.pair_offset[na] == k1 - k0) {
        const std::int32_t q0 = s.pair_offset[na] - k0;  // new entry of old pair k: q0 + k
        bool same = true;
        for (std::int32_t k = k0; k < k1 && same; ++k)
          same = s.pair_j[q0 + k] == new_index_[old_j_[k]];
        if (same) {
          // The look-up's result: a pair with history (a held spring, or a rolling one) as it
          // was, else the new list's zeros.
          const auto kept = [](bool keep, Vec3 a) {
            return Vec3{select(keep, a.x, 0.0), select(keep, a.y, 0.0), select(keep, a.z, 0.0)};
          };
          for (std::int32_t k = k0; k < k1; ++k) {
            const bool keep = nonzero(old_spring_[k]) | (rolls && nonzero(old_roll_[k]));
            s.pair_spring[q0 + k] = kept(keep, old_spring_[k]);
            if (rolls) s.pair_roll[q0 + k] = kept(keep, old_roll_[k]);
          }
          ++copied;
          continue;
        }
      }
      ++looked_up;
      for (std::int32_t k = k0; k < k1; ++k) {
        const Vec3 sp = old_spring_[k];
        if (!nonzero(sp) && !(rolls && nonzero(old_roll_[k]))) continue;
        const std::int32_t na = new_index_[oa], nb = new_index_[old_j_[k]];
        const bool swap = na > nb;  // the spring is stored on the lower index of the pair
        const std::int32_t row = swap ? nb : na, col = swap ? na : nb;
        for (std::int32_t q = s.pair_offset[row]; q < s.pair_offset[row + 1]; ++q)
          if (s.pair_j[q] == col) {
            s.pair_spring[q] = swap ? -sp : sp;
            if (rolls) s.pair_roll[q] = swap ? -old_roll_[k] : old_roll_[k];
            break;
          }
      }
    }
    rows_copied_ += copied;
    rows_looked_up_ += looked_up;
  }
}

void BroadPhase::list_mesh_candidates(const Scene& scene, State& s,
                                      const std::vector<std::vector<Vec3>>& tool_vertices, int T,
                                      double skin) {
  const std::size_t n = s.size();
  const double rmax = scene.r_max();
  // --- mesh candidates: each triangle visits the cells its box (grown by the largest radius
  // and the skin) overlaps. Threads take contiguous triangle ranges and their lists are joined
  // in thread order: the same list as one thread makes.
  const long nx = nx_, ny = ny_, nz = nz_;
  const Vec3 lo = box_lo_, hi = box_hi_;
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
          for (long y = y0; y <= y1; ++y) {
            const long row = (z * ny + y) * nx;
            for (std::int32_t p = cell_start_[row + x0]; p < cell_start_[row + x1 + 1]; ++p) {
              // Outside the triangle's box grown by r_max + skin: farther than r + skin from
              // the triangle, so not a candidate (the cells reach beyond the box).
              const Vec3 xp = s.x[p];
              if (xp.x < bmin.x || xp.x > bmax.x || xp.y < bmin.y || xp.y > bmax.y ||
                  xp.z < bmin.z || xp.z > bmax.z)
                continue;
              const double cut = s.radius[p] + skin;
              if (closest_on_triangle(mesh, wv, t, xp).dist2 < cut * cut)
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
}

// Walls within r + skin of each particle (one bit per wall; all bits if > 32 walls), the
// positions the guard measures displacements from, and the boundary slot pool: a block for
// every particle that has a wall or triangle candidate or still remembers a contact, in
// particle order (the same pool for any thread count), copied from its old block or zeroed.
void BroadPhase::boundary_slots(const Scene& scene, State& s, double skin) {
  const std::size_t n = s.size();
  const int T = threads_;
  const std::size_t nw = scene.walls.size();
  s.wall_mask.resize(n);
  s.x_at_rebuild.resize(n);
  thread_used_.assign(T, 0);
  thread_base_.assign(T + 1, 0);
  constexpr std::size_t B = kBoundarySlots;
  const bool rolls = !s.slot_roll.empty() && s.slot_roll.size() == s.slot_key.size();  // rotating
#pragma omp parallel num_threads(T)
  {
    const int t = omp_get_thread_num();
    const std::size_t a0 = n * t / T, a1 = n * (t + 1) / T;
    std::size_t blocks = 0;
    for (std::size_t i = a0; i < a1; ++i) {
      std::uint32_t mask = 0;
      if (nw > 32) {
        mask = ~0u;
      } else {
        for (std::size_t w = 0; w < nw; ++w)
          if (dot(s.x[i] - scene.walls[w].point, scene.walls[w].normal) < s.radius[i] + skin)
            mask |= 1u << w;
      }
      s.wall_mask[i] = mask;
      s.x_at_rebuild[i] = s.x[i];
      blocks += mask != 0 || s.tri_offset[i + 1] > s.tri_offset[i] || s.slot_count[i] > 0;
    }
    thread_used_[t] = blocks;
#pragma omp barrier
#pragma omp single
    {
      for (int k = 0; k < T; ++k) thread_base_[k + 1] = thread_base_[k] + thread_used_[k];
      pool_key_.resize(thread_base_[T] * B);
      pool_spring_.resize(thread_base_[T] * B);
      pool_roll_.resize(rolls ? thread_base_[T] * B : 0);
      s.slot_particle.resize(thread_base_[T]);
    }
    std::size_t next = thread_base_[t];
    for (std::size_t i = a0; i < a1; ++i) {
      const bool need =
          s.wall_mask[i] != 0 || s.tri_offset[i + 1] > s.tri_offset[i] || s.slot_count[i] > 0;
      const std::int32_t old = s.slot_block[i];
      if (!need) {
        s.slot_block[i] = -1;
        continue;
      }
      const std::size_t k = next++;
      s.slot_block[i] = static_cast<std::int32_t>(k);
      s.slot_particle[k] = static_cast<std::int32_t>(i);
      if (old >= 0) {
        std::copy_n(s.slot_key.begin() + old * B, B, pool_key_.begin() + k * B);
        std::copy_n(s.slot_spring.begin() + old * B, B, pool_spring_.begin() + k * B);
        if (rolls) std::copy_n(s.slot_roll.begin() + old * B, B, pool_roll_.begin() + k * B);
      } else {
        std::fill_n(pool_key_.begin() + k * B, B, 0);
        std::fill_n(pool_spring_.begin() + k * B, B, Vec3{});
        if (rolls) std::fill_n(pool_roll_.begin() + k * B, B, Vec3{});
      }
    }
  }
  s.slot_key.swap(pool_key_);
  s.slot_spring.swap(pool_spring_);
  s.slot_roll.swap(pool_roll_);
}

}  // namespace dem
