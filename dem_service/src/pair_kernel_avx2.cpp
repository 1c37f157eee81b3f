// The pair forces, all awake or with the sleeping rules, on processors with AVX2 but no
// AVX-512 (AMD Zen 2 and 3, most Intel client parts), where the chunk kernel (pair_kernel_chunks.inc, written for 32
// 512-bit registers) does not run. Two passes over blocks of whole rows:
//   1. the screen of every candidate (surely_apart on 4 candidates of a row at a time, in the
//      lanes of a 4-double register, without a branch on its outcome): the pairs not surely
//      apart queued in pair order with their rows, the springs of ended contacts cleared;
//   2. the contact forces of 4 queued pairs at a time, one per lane of a 4-double AVX2 register
//      (every lane a pair past the screen), then applied by scalar code in pair order: each
//      row's sum added to its particle once the queue has passed the row (a row without queued
//      pairs adds its zero, as the loop does), the partners' shares and springs; the statistics
//      in lanes.
// Every operation of the scalar loop (pair_kernel.cpp, pair_rows_scalar) on the same operands in
// the same order: IEEE add, sub, mul, div and sqrt per lane, no fused multiply-add (the target is
// avx2 without fma; the engine is built with -ffp-contract=off), the loop's branches as selects;
// the divisions of the rarer branches (a first touch's ramp, a spring turned far, the friction
// cap) only when a lane acting takes them.
// So the same bits (dem_PairKernel.*). Written with GCC's vector extensions; in the clang fuzz
// build and off x86-64 it is absent and never chosen.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "dem/pair_kernel.hpp"
#include "pair_kernel_parts.hpp"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define DEM_HAVE_AVX2_PAIRS 1
#endif

namespace dem::detail {

#ifdef DEM_HAVE_AVX2_PAIRS
namespace {

typedef double v4d __attribute__((vector_size(32)));
typedef long long v4q __attribute__((vector_size(32)));
#define DEM_AVX2 __attribute__((target("avx2")))
#define DEM_AVX2_INLINE __attribute__((target("avx2"), always_inline)) inline

DEM_AVX2_INLINE v4d splat(double a) { return v4d{a, a, a, a}; }
DEM_AVX2_INLINE v4d vabs(v4d a) {
  const v4q no_sign = {0x7fffffffffffffffLL, 0x7fffffffffffffffLL, 0x7fffffffffffffffLL,
                       0x7fffffffffffffffLL};
  return reinterpret_cast<v4d>(reinterpret_cast<v4q>(a) & no_sign);
}
DEM_AVX2_INLINE v4d vsqrt(v4d a) { return __builtin_ia32_sqrtpd256(a); }
// Bit l set where lane l of the comparison's result is true.
DEM_AVX2_INLINE int lanes_of(v4q m) { return __builtin_ia32_movmskpd256(reinterpret_cast<v4d>(m)); }

// Components x and y of 4 Vec3s in lanes: 16 bytes from each, two of them into one register
// ({x0, y0, x2, y2} and {x1, y1, x3, y3}), then interleaved. Fewer operations than 8 loads into
// lanes; the same values.
DEM_AVX2_INLINE void xy_lanes(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3,
                              v4d& x, v4d& y) {
  typedef double v2d __attribute__((vector_size(16)));
  v2d a0, a1, a2, a3;
  __builtin_memcpy(&a0, &p0.x, sizeof a0);
  __builtin_memcpy(&a1, &p1.x, sizeof a1);
  __builtin_memcpy(&a2, &p2.x, sizeof a2);
  __builtin_memcpy(&a3, &p3.x, sizeof a3);
  const v4d a = __builtin_shufflevector(a0, a2, 0, 1, 2, 3);  // x0 y0 x2 y2
  const v4d b = __builtin_shufflevector(a1, a3, 0, 1, 2, 3);  // x1 y1 x3 y3
  x = __builtin_shufflevector(a, b, 0, 4, 2, 6);
  y = __builtin_shufflevector(a, b, 1, 5, 3, 7);
}

// The contact force of 4 queued pairs (contact_force and its caller's geometry, lane by lane):
// pair pair[l] of row i[l] with partner j[l]. The lanes are built from 16-byte loads of x and y
// (xy_lanes) and scalar loads of the rest, not from whole 32-byte Vec3 reads (a Vec3 is 24 bytes,
// and a wide load of narrow stores would stall), and leave through memory.
struct Out4 {
  alignas(32) double f[3][4], s[3][4], overlap[4], ratio[4];  // ratio: overlap / min(ri, rj)
  alignas(32) long long acts[4];
};
struct Arrays {
  const Vec3* x;
  const Vec3* u;
  const double* r;
  const double* m;
  const Vec3* spring;
};

DEM_AVX2_INLINE void contact4(const ContactLaw& law, double dt, const Arrays& a,
                              const std::int32_t* i, const std::int32_t* j,
                              const std::int32_t* pair, Out4& out) {
  const auto store = [](double* p, v4d v) { __builtin_memcpy(p, &v, sizeof v); };
#define DEM_LANES(expr) v4d{expr(0), expr(1), expr(2), expr(3)}
#define DEM_XIZ(l) a.x[i[l]].z
#define DEM_XJZ(l) a.x[j[l]].z
#define DEM_UIZ(l) a.u[i[l]].z
#define DEM_UJZ(l) a.u[j[l]].z
#define DEM_SZ(l) a.spring[pair[l]].z
#define DEM_RI(l) a.r[i[l]]
#define DEM_RJ(l) a.r[j[l]]
#define DEM_MI(l) a.m[i[l]]
#define DEM_MJ(l) a.m[j[l]]
  const v4d zero = splat(0.0), one = splat(1.0);
  v4d xix, xiy, xjx, xjy, uix, uiy, ujx, ujy;
  xy_lanes(a.x[i[0]], a.x[i[1]], a.x[i[2]], a.x[i[3]], xix, xiy);
  xy_lanes(a.x[j[0]], a.x[j[1]], a.x[j[2]], a.x[j[3]], xjx, xjy);
  const v4d dx = xix - xjx, dy = xiy - xjy, dz = DEM_LANES(DEM_XIZ) - DEM_LANES(DEM_XJZ);
  const v4d ri = DEM_LANES(DEM_RI), rj = DEM_LANES(DEM_RJ), mi = DEM_LANES(DEM_MI),
            mj = DEM_LANES(DEM_MJ);
  const v4d rsum = ri + rj;
  const v4d d2 = dx * dx + dy * dy + dz * dz;
  xy_lanes(a.u[i[0]], a.u[i[1]], a.u[i[2]], a.u[i[3]], uix, uiy);
  xy_lanes(a.u[j[0]], a.u[j[1]], a.u[j[2]], a.u[j[3]], ujx, ujy);
  const v4d ux = uix - ujx, uy = uiy - ujy, uz = DEM_LANES(DEM_UIZ) - DEM_LANES(DEM_UJZ);
  const v4d dist = vsqrt(d2);
  const v4d inv = one / dist;
  const v4q pos = dist > zero;
  const v4d nx = pos ? inv * dx : zero, ny = pos ? inv * dy : zero, nz = pos ? inv * dz : one;
  // coefficients(law, ri rj / rsum, mi mj / (mi + mj))
  const v4d length = ri * rj / rsum, m_eff = mi * mj / (mi + mj);
  const v4d k = law.stiffness_per_length ? splat(law.normal_stiffness) * length
                                         : splat(law.normal_stiffness);
  const v4d eta = law.damping_from_restitution ? splat(2.0 * law.zeta) * vsqrt(m_eff * k)
                                               : splat(law.normal_damping);
  const v4d kt = splat(law.tangential_stiffness_ratio) * k;
  const v4d etat = splat(law.tangential_damping_ratio) * eta;
  // contact_force
  const v4d overlap = rsum - dist;
  const v4d vn = ux * nx + uy * ny + uz * nz;
  const v4d half = splat(0.5 * dt) * vabs(vn);
  const v4q acts = ~(overlap <= -half);
  const v4q full = overlap >= half;
  // The divisions below run only where a lane acting needs them (a lane not acting leaves with
  // its spring cleared and nothing else read, so its other values do not matter).
  v4d active = one, fn = k * overlap;
  if (lanes_of(acts & ~full)) {  // a contact within half a step's approach of its first touch
    const v4d w = overlap + half;
    active = full ? one : w / (splat(2.0) * half);
    fn = full ? fn : k * w * w / (splat(4.0) * half);
  }
  fn = fn - active * eta * vn;
  if (law.clip_attractive) fn = fn < zero ? zero : fn;
  const v4d vtx = ux - vn * nx, vty = uy - vn * ny, vtz = uz - vn * nz;
  v4d sx, sy, sz = DEM_LANES(DEM_SZ);
  xy_lanes(a.spring[pair[0]], a.spring[pair[1]], a.spring[pair[2]], a.spring[pair[3]], sx, sy);
#undef DEM_LANES
#undef DEM_XIZ
#undef DEM_XJZ
#undef DEM_UIZ
#undef DEM_UJZ
#undef DEM_SZ
#undef DEM_RI
#undef DEM_RJ
#undef DEM_MI
#undef DEM_MJ
  const v4d s2 = sx * sx + sy * sy + sz * sz;
  {  // the spring turned into the tangent plane, its length kept (where held: s2 > 0)
    const v4d sn = sx * nx + sy * ny + sz * nz;
    const v4d px = sx - sn * nx, py = sy - sn * ny, pz = sz - sn * nz;
    const v4d x = sn * sn / s2;
    const v4q held = s2 > zero;
    const v4q small = x < splat(1e-6);
    v4d f = one + splat(0.5) * x;
    if (lanes_of(held & ~small)) f = small ? f : (x < one ? one / vsqrt(one - x) : zero);
    sx = held ? f * px : sx;
    sy = held ? f * py : sy;
    sz = held ? f * pz : sz;
  }
  const v4d adt = active * splat(dt);
  sx = sx + adt * vtx;
  sy = sy + adt * vty;
  sz = sz + adt * vtz;
  const v4d neg_kt = -kt, aet = active * etat;
  v4d ftx = neg_kt * sx - aet * vtx, fty = neg_kt * sy - aet * vty, ftz = neg_kt * sz - aet * vtz;
  const v4d cap = splat(law.friction) * (fn > zero ? fn : zero);
  const v4d ft2 = ftx * ftx + fty * fty + ftz * ftz;
  const v4q binds = ft2 > cap * cap;
  if (lanes_of(binds & acts)) {  // a contact sliding: the force on the cap, the spring behind it
    const v4d q = cap / vsqrt(ft2);
    const v4d cx = q * ftx, cy = q * fty, cz = q * ftz;
    const v4q kt_pos = kt > zero;
    const v4d neg_inv_kt = kt_pos ? splat(-1.0) / kt : zero;
    sx = binds ? (kt_pos ? neg_inv_kt * cx : zero) : sx;
    sy = binds ? (kt_pos ? neg_inv_kt * cy : zero) : sy;
    sz = binds ? (kt_pos ? neg_inv_kt * cz : zero) : sz;
    ftx = binds ? cx : ftx;
    fty = binds ? cy : fty;
    ftz = binds ? cz : ftz;
  }
  store(out.f[0], fn * nx + ftx);
  store(out.f[1], fn * ny + fty);
  store(out.f[2], fn * nz + ftz);
  store(out.s[0], sx);
  store(out.s[1], sy);
  store(out.s[2], sz);
  store(out.overlap, overlap);
  store(out.ratio, overlap / (rj < ri ? rj : ri));  // std::min(ri, rj)
  __builtin_memcpy(out.acts, &acts, sizeof acts);
}

// The screen of 4 candidates of one row (surely_apart, lane by lane, the same operations in the
// same order): the row's particle broadcast once per row.
struct Screen4 {
  v4d x, y, z, ux, uy, uz, r;
};
DEM_AVX2_INLINE Screen4 screen_setup(Vec3 x0, Vec3 u0, double r0) {
  return {splat(x0.x), splat(x0.y), splat(x0.z), splat(u0.x), splat(u0.y), splat(u0.z), splat(r0)};
}
// The lanes surely apart (bit l: partner jj[l]); g2c = 0.25 dt dt as surely_apart computes it.
DEM_AVX2_INLINE int screen4(const Screen4& sc, const Vec3* X, const Vec3* U, const double* R,
                            const std::int32_t* jj, double g2c) {
#define DEM_LANES(expr) v4d{expr(0), expr(1), expr(2), expr(3)}
#define DEM_XJZ(l) X[jj[l]].z
#define DEM_UJZ(l) U[jj[l]].z
#define DEM_RJ(l) R[jj[l]]
  v4d xjx, xjy, ujx, ujy;
  xy_lanes(X[jj[0]], X[jj[1]], X[jj[2]], X[jj[3]], xjx, xjy);
  xy_lanes(U[jj[0]], U[jj[1]], U[jj[2]], U[jj[3]], ujx, ujy);
  const v4d dx = sc.x - xjx, dy = sc.y - xjy, dz = sc.z - DEM_LANES(DEM_XJZ);
  const v4d rsum = sc.r + DEM_LANES(DEM_RJ);
  const v4d ux = sc.ux - ujx, uy = sc.uy - ujy, uz = sc.uz - DEM_LANES(DEM_UJZ);
#undef DEM_LANES
#undef DEM_XJZ
#undef DEM_UJZ
#undef DEM_RJ
  const v4d d2 = dx * dx + dy * dy + dz * dz;
  const v4d u2 = ux * ux + uy * uy + uz * uz;
  const v4d rs2 = rsum * rsum;
  const v4d g2 = splat(g2c) * u2;
  const v4d q = d2 - rs2 - g2;
  const v4d rhs = splat(4.0) * rsum * rsum * g2;
  return lanes_of(~(d2 < rs2) & (q >= splat(0.0)) & (q * q >= rhs));
}
// The lanes set in a 4-bit mask, in order (the rest 0): the queue's entries of a screened group.
typedef std::int32_t v4si __attribute__((vector_size(16)));
alignas(16) constexpr std::int32_t kKeptLanes[16][4] = {
    {0, 0, 0, 0}, {0, 0, 0, 0}, {1, 0, 0, 0}, {0, 1, 0, 0}, {2, 0, 0, 0}, {0, 2, 0, 0},
    {1, 2, 0, 0}, {0, 1, 2, 0}, {3, 0, 0, 0}, {0, 3, 0, 0}, {1, 3, 0, 0}, {0, 1, 3, 0},
    {2, 3, 0, 0}, {0, 2, 3, 0}, {1, 2, 3, 0}, {0, 1, 2, 3}};
// Lanes 0 .. n - 1 all ones (n = 0 .. 4).
constexpr v4q kFirstLanes[5] = {{0, 0, 0, 0}, {-1, 0, 0, 0}, {-1, -1, 0, 0}, {-1, -1, -1, 0},
                                {-1, -1, -1, -1}};
// The lanes of pairs k.. k + 3 whose spring is held (nonzero: NaN counts, -0 does not), the
// lanes past k1 clear.
DEM_AVX2_INLINE int springs_held(const Vec3* spring, std::int32_t k, std::int32_t k1) {
  if (k1 - k >= 4) {  // 12 doubles in a row: 3 loads, bit 3 l + c is component c of lane l
    const double* d = &spring[k].x;
    v4d a, b, c;
    __builtin_memcpy(&a, d, sizeof a);
    __builtin_memcpy(&b, d + 4, sizeof b);
    __builtin_memcpy(&c, d + 8, sizeof c);
    const v4d zero = splat(0.0);
    const unsigned m = static_cast<unsigned>(lanes_of(a != zero) | lanes_of(b != zero) << 4 |
                                             lanes_of(c != zero) << 8);
    const unsigned any = m | m >> 1 | m >> 2;  // bit 3 l: a component of lane l nonzero
    return static_cast<int>((any & 1) | (any >> 2 & 2) | (any >> 4 & 4) | (any >> 6 & 8));
  }
  int held = 0;
  for (std::int32_t l = 0; l < k1 - k; ++l) held |= nonzero(spring[k + l]) << l;
  return held;
}

// Sleep: the scalar loop's sleeping rules (pair_rows_scalar<true>): a pair of two sleepers is
// skipped, a sleeper's row with no awake partner is not read (nor is its force touched), the
// force of a pair acts only on its awake side, and a sleeper wakes when its contact with history
// ends (found by the screen, woken at that pair's place in the second pass, so the wakes come in
// the loop's order) or when the partner is faster than the wake speed.
template <bool Sleep>
DEM_AVX2 void rows_avx2(const PairRows& p, const PairSleep& sl, std::size_t a0, std::size_t a1,
                        std::size_t direct, std::vector<PairRemote>& remote,
                        PairRowStats& stats) {
  constexpr std::int32_t kMaxQueue = 256;
  const std::int32_t kQueue = std::clamp(p.queue_pairs, 4, kMaxQueue);
  const ContactLaw law = p.law;
  const double dt = p.dt;
  const double dt_g2 = 0.25 * dt * dt;  // surely_apart's factor of the relative speed squared
  const Vec3* const X = p.x;
  const Vec3* const U = p.u;
  const double* const R = p.radius;
  const double* const M = p.mass;
  const std::int32_t* const off = p.offset;
  const std::int32_t* const J = p.partner;
  Vec3* const spring = p.spring;
  const std::int32_t* const SI = p.spring_index;
  Vec3* const HOME = p.spring_home;
  Vec3* const F = p.force;
  const std::int32_t* const REST = sl.rest;
  const std::int32_t S = sl.steps;
  const auto asleep = [&](std::size_t i) { return Sleep && REST[i] >= S; };
  // A sleeper's row without awake partners: skipped whole, its force untouched.
  const auto skipped = [&](std::size_t i) {
    return Sleep && asleep(i) && sl.awake_partners && sl.awake_partners[i] == 0;
  };
  std::int64_t contacts = 0;
  // The statistics' maxima lane by lane, as std::max takes them in pair order: a value enters
  // only above the lane's maximum, so the largest of the lanes' is the loop's.
  v4d max_overlap = splat(0.0), max_overlap_ratio = splat(0.0);
  std::int32_t queue[kMaxQueue + 4], queue_row[kMaxQueue + 4];
  // Sleep: the ended contacts' wakes, by pair (ascending), woken in the second pass.
  std::int32_t ended[Sleep ? kMaxQueue + 1 : 1], ended_who[Sleep ? kMaxQueue + 1 : 1];
  std::size_t row = a0;  // the second pass's row, and its force sum
  Vec3 fi{};
  const auto add_rows_before = [&](std::size_t i) {  // rows the queue has left
    for (; row < i; ++row) {
      if (!skipped(row)) F[row] += fi;
      fi = Vec3{};
    }
  };
  std::size_t next = a0;  // the first pass's next row
  while (next < a1) {
    // Pass 1: whole rows while they fit in the queue (and their ended contacts in `ended`); a row
    // longer than the queue alone runs through the scalar loop.
    std::int32_t n = 0, events = 0;
    const std::size_t first = next;
    while (next < a1 && off[next + 1] - off[next] <= kQueue - std::max(n, events)) {
      const bool si = asleep(next);
      if (skipped(next)) {
        ++next;
        continue;
      }
      const std::int32_t k1 = off[next + 1];
      const std::int32_t row32 = static_cast<std::int32_t>(next);
      const Screen4 sc = screen_setup(X[next], U[next], R[next]);
      const std::int32_t last = k1 - 1;
      for (std::int32_t k = off[next]; k < k1; k += 4) {
        // 4 candidates at a time: the lanes past the row repeat its last pair and are masked.
        std::int32_t jj[4];
        const bool whole = k1 - k >= 4;
        if (whole)
          __builtin_memcpy(jj, J + k, sizeof jj);
        else
          for (int l = 0; l < 4; ++l) jj[l] = J[std::min(k + l, last)];
        const int valid = whole ? 0xF : (1 << (k1 - k)) - 1;
        int skip = 0;  // two sleepers: no force, the spring stays as it was
        if (Sleep && si) {
          for (int l = 0; l < 4; ++l) skip |= (REST[jj[l]] >= S) << l;
          if ((valid & ~skip) == 0) continue;  // 4 sleeping partners of a sleeper: nothing to do
        }
        const int apart = screen4(sc, X, U, R, jj, dt_g2);
        const int keep = valid & ~skip & ~apart;
        {  // the kept pairs queued in pair order, without a branch: 4 entries written, the
           // first popcount(keep) of them kept
          v4si kept;
          __builtin_memcpy(&kept, kKeptLanes[keep], sizeof kept);
          kept += v4si{k, k, k, k};
          const v4si rows = {row32, row32, row32, row32};
          __builtin_memcpy(queue + n, &kept, sizeof kept);
          __builtin_memcpy(queue_row + n, &rows, sizeof rows);
          n += __builtin_popcount(static_cast<unsigned>(keep));
        }
        // The ended contacts among the pairs apart: their history forgotten (rare: one branch).
        int ended_here = valid & ~skip & apart & springs_held(spring, k, k1);
        while (ended_here) {
          const int l = __builtin_ctz(static_cast<unsigned>(ended_here));
          ended_here &= ended_here - 1;
          const std::int32_t kk = k + l;
          if (Sleep) {  // and its sleeper woken (in the second pass)
            const bool sj = asleep(static_cast<std::size_t>(jj[l]));
            if (si || sj) {
              ended[events] = kk;
              ended_who[events++] = si ? row32 : jj[l];
            }
          }
          spring[kk] = Vec3{};
          if (SI) HOME[SI[kk]] = spring[kk];
        }
      }
      ++next;
    }
    if (next == first) {  // a row longer than the queue (nothing pending: rows up to it added)
      PairRowStats one;
      if (Sleep)
        pair_rows_scalar_sleep(p, sl, next, next + 1, direct, remote, one);
      else
        pair_rows_scalar_awake(p, next, next + 1, direct, remote, one);
      add_stats(stats, one.contacts, one.max_overlap, one.max_overlap_ratio);
      row = ++next;
      continue;
    }
    // Pass 2: 4 queued pairs at a time (the last group padded with its last pair, not applied).
    for (std::int32_t q = n; n > 0 && q < n + 4; ++q) {  // the padding: the last pair again
      queue[q] = queue[n - 1];
      queue_row[q] = queue_row[n - 1];
    }
    if (Sleep) ended[events] = off[a1];  // past every pair
    std::int32_t event = 0;
    const Arrays arrays{X, U, R, M, spring};
    for (std::int32_t e = 0; e < n; e += 4) {
      const int lanes = std::min<std::int32_t>(4, n - e);
      std::int32_t jj[4];
      for (int l = 0; l < 4; ++l) jj[l] = J[queue[e + l]];
      Out4 out;
      contact4(law, dt, arrays, queue_row + e, jj, queue + e, out);
      {
        v4q acting, overlap, ratio;
        __builtin_memcpy(&acting, out.acts, sizeof acting);
        __builtin_memcpy(&overlap, out.overlap, sizeof overlap);
        __builtin_memcpy(&ratio, out.ratio, sizeof ratio);
        acting &= kFirstLanes[lanes];
        contacts += __builtin_popcount(static_cast<unsigned>(lanes_of(acting)));
        const v4d ov = reinterpret_cast<v4d>(overlap), ra = reinterpret_cast<v4d>(ratio);
        max_overlap = acting & (max_overlap < ov) ? ov : max_overlap;
        max_overlap_ratio = acting & (max_overlap_ratio < ra) ? ra : max_overlap_ratio;
      }
      for (int l = 0; l < lanes; ++l) {
        const std::int32_t k = queue[e + l];
        const std::size_t i = static_cast<std::size_t>(queue_row[e + l]);
        if (Sleep)
          for (; ended[event] < k; ++event)
            wake(sl, static_cast<std::size_t>(ended_who[event]), direct);
        add_rows_before(i);
        Vec3& sk = spring[k];
        if (!out.acts[l]) {
          sk = Vec3{};
          if (SI) HOME[SI[k]] = sk;
          continue;
        }
        sk = Vec3{out.s[0][l], out.s[1][l], out.s[2][l]};
        if (SI) HOME[SI[k]] = sk;
        const Vec3 f{out.f[0][l], out.f[1][l], out.f[2][l]};
        bool si = false, sj = false;
        if (Sleep) {
          si = asleep(i);
          sj = asleep(static_cast<std::size_t>(jj[l]));
          // Awake against asleep: a partner faster than the wake speed wakes the sleeper.
          if ((si || sj) && norm2(U[i] - U[jj[l]]) > sl.wake_speed2)
            wake(sl, si ? i : static_cast<std::size_t>(jj[l]), direct);
        }
        if (!Sleep || !si) fi += f;
        if (!Sleep || !sj) on_partner(F, remote, jj[l], f, direct);
      }
    }
    if (Sleep)
      for (; event < events; ++event) wake(sl, static_cast<std::size_t>(ended_who[event]), direct);
    add_rows_before(next);  // the rows the block ends with
  }
  double mo = 0, mr = 0;
  for (int l = 0; l < 4; ++l) {
    mo = std::max(mo, max_overlap[l]);
    mr = std::max(mr, max_overlap_ratio[l]);
  }
  add_stats(stats, contacts, mo, mr);
}

}  // namespace

bool pair_rows_avx2_available() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2");
}

void pair_rows_avx2(const PairRows& p, const PairSleep* sleep, std::size_t a0, std::size_t a1,
                    std::size_t direct, std::vector<PairRemote>& remote, PairRowStats& stats) {
  if (sleep)
    rows_avx2<true>(p, *sleep, a0, a1, direct, remote, stats);
  else
    rows_avx2<false>(p, PairSleep{}, a0, a1, direct, remote, stats);
}
#else
bool pair_rows_avx2_available() { return false; }

void pair_rows_avx2(const PairRows&, const PairSleep*, std::size_t, std::size_t, std::size_t,
                    std::vector<PairRemote>&, PairRowStats&) {
  throw std::logic_error("the AVX2 pair kernel is not built here (GCC on x86-64 only)");
}
#endif

}  // namespace dem::detail
