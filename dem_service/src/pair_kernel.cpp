#include "dem/pair_kernel.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace dem::detail {

namespace {

// Wakes sleeper p: directly in this thread's range, queued otherwise (the partner j > i of a
// pair in this range is never in an earlier thread's range).
inline void wake(const PairSleep& sl, std::size_t p, std::size_t a1) {
  if (p < a1)
    sl.wake[p] = 1;
  else
    sl.remote_wake->push_back(static_cast<std::int32_t>(p));
}

// The partner's share of a pair force: subtracted directly in this thread's range, handed on
// (in pair order) beyond it.
inline void on_partner(Vec3* F, std::vector<PairRemote>& remote, std::int32_t j, Vec3 f,
                       std::size_t a1) {
  if (static_cast<std::size_t>(j) < a1)
    F[j] -= f;
  else
    remote.push_back({j, f});
}

inline void add_stats(PairRowStats& stats, std::int64_t contacts, double max_overlap,
                      double max_overlap_ratio) {
  stats.contacts += contacts;
  stats.max_overlap = std::max(stats.max_overlap, max_overlap);
  stats.max_overlap_ratio = std::max(stats.max_overlap_ratio, max_overlap_ratio);
}

template <bool Sleep>
void pair_rows_scalar(const PairRows& p, const PairSleep& sl, std::size_t a0, std::size_t a1,
                      std::size_t direct, std::vector<PairRemote>& remote, PairRowStats& stats) {
  const ContactLaw law = p.law;  // a local copy: no reloads after stores
  const double dt = p.dt;
  const Vec3* const X = p.x;
  const Vec3* const U = p.u;
  const double* const R = p.radius;
  const double* const M = p.mass;
  const std::int32_t* const off = p.offset;
  const std::int32_t* const J = p.partner;
  Vec3* const spring = p.spring;
  const std::int32_t* const SI = p.spring_index;  // close pairs: their springs' homes
  Vec3* const HOME = p.spring_home;
  Vec3* const F = p.force;
  const std::int32_t* const REST = sl.rest;
  const std::int32_t S = sl.steps;
  std::int64_t contacts = 0;
  double max_overlap = 0, max_overlap_ratio = 0;
  ContactCoefficients c;
  double last_ri = -1, last_mi = -1, last_rj = -1, last_mj = -1;
  for (std::size_t i = a0; i < a1; ++i) {
    const Vec3 xi = X[i], ui = U[i];
    const double ri = R[i], mi = M[i];
    if (ri != last_ri || mi != last_mi) {
      last_ri = ri;
      last_mi = mi;
      last_rj = last_mj = -1;
    }
    const bool si = Sleep && REST[i] >= S;
    // A sleeper with only sleepers in its row: nothing to compute (the loop below would skip
    // every pair), so its row is not read at all.
    if (Sleep && si && sl.awake_partners && sl.awake_partners[i] == 0) continue;
    Vec3 fi{};
    for (std::int32_t k = off[i]; k < off[i + 1]; ++k) {
      const std::int32_t j = J[k];
      Vec3& sk = spring[k];
      bool sj = false;
      if (Sleep) {
        sj = REST[j] >= S;
        if (si && sj) continue;  // two sleepers: no force, the spring stays as it was
      }
      const Vec3 d = xi - X[j];
      const double rsum = ri + R[j];
      const double d2 = norm2(d);
      const Vec3 urel = ui - U[j];
      if (d2 >= rsum * rsum && surely_apart(d2, rsum, norm2(urel), dt)) {
        // Contact ended: history is forgotten (write only if there is something to clear).
        if (nonzero(sk)) {
          // A sleeper whose contact with an awake particle ends may have lost its support.
          if (Sleep && (si || sj)) wake(sl, si ? i : static_cast<std::size_t>(j), direct);
          sk = Vec3{};
          if (SI) HOME[SI[k]] = sk;
        }
        continue;
      }
      const double dist = std::sqrt(d2);
      const Vec3 nrm = dist > 0 ? (1.0 / dist) * d : Vec3{0, 0, 1};
      const double rj = R[j], mj = M[j];
      // Monodisperse beds repeat the same pair: reuse the coefficients (saves a sqrt).
      if (rj != last_rj || mj != last_mj) {
        c = coefficients(law, ri * rj / rsum, mi * mj / (mi + mj));
        last_rj = rj;
        last_mj = mj;
      }
      Vec3 f;
      const bool acts = contact_force(law, c, rsum - dist, nrm, urel, sk, dt, f);
      if (!acts) sk = Vec3{};
      if (SI) HOME[SI[k]] = sk;
      if (!acts) continue;
      ++contacts;
      max_overlap = std::max(max_overlap, rsum - dist);
      max_overlap_ratio = std::max(max_overlap_ratio, (rsum - dist) / std::min(ri, rj));
      // Awake against asleep: the force acts on the awake particle only; a partner moving
      // faster than scene.sleep.wake_speed (by default speed) relative to the sleeper wakes it.
      if (Sleep && (si || sj) && norm2(urel) > sl.wake_speed2)
        wake(sl, si ? i : static_cast<std::size_t>(j), direct);
      if (!Sleep || !si) fi += f;
      if (!Sleep || !sj) on_partner(F, remote, j, f, direct);
    }
    F[i] += fi;
  }
  add_stats(stats, contacts, max_overlap, max_overlap_ratio);
}

#if defined(__x86_64__) && defined(__GNUC__)
#define DEM_AVX512 __attribute__((target("avx512f,avx512vl,avx512dq")))

// The lanes of a mask blend: pick ? a : b.
DEM_AVX512 inline __m512d pick(__mmask8 m, __m512d a, __m512d b) {
  return _mm512_mask_blend_pd(m, b, a);
}

// Lane l of the result holds component c of the Vec3 at base + 3 j[l] (j = 0 in dead lanes):
// 8 loads of 3 doubles (masked: no read past the array) and a transpose, cheaper than three
// gathers.
struct Lanes3 {
  __m512d x, y, z;
};
static_assert(sizeof(Vec3) == 3 * sizeof(double), "the kernel reads Vec3 arrays as doubles");
DEM_AVX512 inline __m512d load_two(const double* base, const std::int32_t* j) {
  const std::ptrdiff_t j0 = j[0], j1 = j[1];
  return _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_maskz_loadu_pd(0x7, base + 3 * j0)),
                            _mm256_maskz_loadu_pd(0x7, base + 3 * j1), 1);
}
DEM_AVX512 inline Lanes3 load_vec3(const double* base, const std::int32_t* j) {
  const __m512d p0 = load_two(base, j), p1 = load_two(base, j + 2), p2 = load_two(base, j + 4),
                p3 = load_two(base, j + 6);
  // p0 = x0 y0 z0 _ x1 y1 z1 _, ...: x and y of 4 Vec3 from two, then z.
  const __m512i xy = _mm512_setr_epi64(0, 4, 8, 12, 1, 5, 9, 13);
  const __m512i zz = _mm512_setr_epi64(2, 6, 10, 14, 2, 6, 10, 14);
  const __m512d a = _mm512_permutex2var_pd(p0, xy, p1), b = _mm512_permutex2var_pd(p2, xy, p3);
  const __m512d c = _mm512_permutex2var_pd(p0, zz, p1), d = _mm512_permutex2var_pd(p2, zz, p3);
  return {_mm512_shuffle_f64x2(a, b, 0x44), _mm512_shuffle_f64x2(a, b, 0xEE),
          _mm512_shuffle_f64x2(c, d, 0x44)};
}

// The 8 Vec3 stored contiguously at `base` (lanes beyond the row read as 0) as components: 3
// loads and 6 permutes instead of three gathers.
struct Interleave {
  __m512i first[3], second[3];  // component c
};
DEM_AVX512 inline Interleave make_interleave() {
  Interleave t;
  alignas(64) long long a[8], b[8];
  for (int c = 0; c < 3; ++c) {
    for (int l = 0; l < 8; ++l) {
      const int f = 3 * l + c;  // flat index of component c of lane l
      a[l] = f < 16 ? f : 0;
      b[l] = f < 16 ? l : 8 + (f - 16);
    }
    t.first[c] = _mm512_load_si512(a);
    t.second[c] = _mm512_load_si512(b);
  }
  return t;
}
// Masks of the doubles of the first `left` Vec3 (left <= 8) in the 3 registers.
DEM_AVX512 inline void vec3_masks(int left, __mmask8 m[3]) {
  for (int r = 0; r < 3; ++r) {
    const int n = std::min(std::max(3 * left - 8 * r, 0), 8);
    m[r] = static_cast<__mmask8>((1u << n) - 1);
  }
}
DEM_AVX512 inline Lanes3 load_contiguous(const Interleave& t, const double* base,
                                         const __mmask8 m[3]) {
  const __m512d l0 = _mm512_maskz_loadu_pd(m[0], base), l1 = _mm512_maskz_loadu_pd(m[1], base + 8),
                l2 = _mm512_maskz_loadu_pd(m[2], base + 16);
  __m512d v[3];
  for (int c = 0; c < 3; ++c)
    v[c] = _mm512_permutex2var_pd(_mm512_permutex2var_pd(l0, t.first[c], l1), t.second[c], l2);
  return {v[0], v[1], v[2]};
}
// The contact law of one chunk of up to 8 candidates, one per lane, whatever rows they come
// from: every lane computes the screen and the whole contact force (the scalar version's
// branches become masks). Its callers sum and apply the forces of the active lanes in pair
// order by scalar code, exactly as the scalar loop does. It also keeps the coefficients of the
// last uniform chunk and the statistics.
struct ChunkIn {
  __m512d xix, xiy, xiz, uix, uiy, uiz, ri, mi;  // the i side of each lane
  __m256i j;                                     // partners (0 in dead lanes)
  const std::int32_t* jl;                        // the same, stored
  const std::int32_t* kl;                        // Indexed: the homes of the lanes' springs
  __mmask8 live;                                 // lanes to compute
  int left;                                      // candidates from this chunk's first on
};
struct ChunkOut {
  __mmask8 clear = 0, act = 0;  // springs cleared (ended contacts); lanes with a force
  __m512d urel2;                // |u_i - u_j|^2
};
struct ChunkKernel {
  __m512d zero, one, two, four, half, tiny, ratio_margin, minus_one, vdt, quarter_dt2, half_dt, kn, two_zeta,
      eta_fixed, kt_ratio, etat_ratio, mu;
  __mmask8 per_length, from_restitution, clip;
  __m512i sign;
  Interleave mix;
  // The arrays of the rows (as doubles where the kernel reads Vec3 components).
  const double* X;
  const double* U;
  const double* R;
  const double* M;
  const std::int32_t* off;
  const std::int32_t* J;
  Vec3* spring;
  const std::int32_t* spring_index;  // close pairs (stream<true>): their springs' homes
  Vec3* spring_home;
  Vec3* F;
  // The coefficients of the last uniform chunk (no radius or mass is negative: nothing matches
  // before the first one).
  __m512d cached_ri, cached_mi, cached_rj, cached_mj, cached_k, cached_eta;
  std::int64_t contacts = 0;
  __m512d max_overlap, max_ratio;
  // Forces of the lanes (valid where act).
  alignas(64) double fx[8], fy[8], fz[8];

  DEM_AVX512 explicit ChunkKernel(const PairRows& p) {
    const ContactLaw& law = p.law;
    const double dt = p.dt;
    X = reinterpret_cast<const double*>(p.x);
    U = reinterpret_cast<const double*>(p.u);
    R = p.radius;
    M = p.mass;
    off = p.offset;
    J = p.partner;
    spring = p.spring;
    spring_index = p.spring_index;
    spring_home = p.spring_home;
    F = p.force;
    zero = _mm512_setzero_pd();
    one = _mm512_set1_pd(1.0);
    two = _mm512_set1_pd(2.0);
    four = _mm512_set1_pd(4.0);
    half = _mm512_set1_pd(0.5);
    tiny = _mm512_set1_pd(1e-6);
    ratio_margin = _mm512_set1_pd(1 - 1e-9);
    minus_one = _mm512_set1_pd(-1.0);
    vdt = _mm512_set1_pd(dt);
    quarter_dt2 = _mm512_set1_pd(0.25 * dt * dt);  // surely_apart's (0.25 dt) dt
    half_dt = _mm512_set1_pd(0.5 * dt);
    kn = _mm512_set1_pd(law.normal_stiffness);
    two_zeta = _mm512_set1_pd(2.0 * law.zeta);
    eta_fixed = _mm512_set1_pd(law.normal_damping);
    kt_ratio = _mm512_set1_pd(law.tangential_stiffness_ratio);
    etat_ratio = _mm512_set1_pd(law.tangential_damping_ratio);
    mu = _mm512_set1_pd(law.friction);
    per_length = law.stiffness_per_length ? 0xFF : 0;
    from_restitution = law.damping_from_restitution ? 0xFF : 0;
    clip = law.clip_attractive ? 0xFF : 0;
    sign = _mm512_set1_epi64(static_cast<long long>(0x8000000000000000ull));
    mix = make_interleave();
    cached_ri = cached_mi = cached_rj = cached_mj = minus_one;
    cached_k = cached_eta = zero;
    max_overlap = max_ratio = zero;
  }

  // Reads the partners and the springs at `spring` (the chunk's first pair), writes the springs
  // of the lanes that changed and, where act, the forces to fx, fy, fz. Full: the chunks are
  // full (the stream kernel), so nearly every chunk has a lane with history and one sliding;
  // their parts are computed without a branch (a branch taken at random costs more than the
  // masked lanes). Else (row by row, 61 % of the lanes used) they are skipped when no lane
  // needs them.
  // Indexed (close pairs): the springs at spring + k are copies; each one written is also
  // written to its home, spring_home[in.kl[l]].
  template <bool Full, bool Indexed = false>
  DEM_AVX512 ChunkOut compute(const ChunkIn& in, std::int32_t k);
  // The two kernels (below): row by row with the sleeping rules, or the stream of pairs.
  template <bool Indexed>
  DEM_AVX512 void rows(const PairSleep& sl, std::size_t a0, std::size_t a1, std::size_t direct,
                       std::vector<PairRemote>& remote, PairRowStats& stats, bool full_chunks);
  // Full: the spring's turn and the friction cap computed in every chunk without a branch.
  // finish_stats: add the kernel's statistics to `stats` at the end (rows() streams runs of
  // rows and adds them once, at its own end).
  template <bool Indexed, bool Full>
  DEM_AVX512 void stream(std::size_t a0, std::size_t a1, std::size_t direct,
                         std::vector<PairRemote>& remote, PairRowStats& stats,
                         bool finish_stats = true);
  DEM_AVX512 void finish(PairRowStats& stats) const {
    // The lanes' maxima through memory: GCC 12 warns about _mm512_reduce_max_pd's undefined
    // upper half where rows() inlines this (a false alarm; the maximum is the same).
    alignas(64) double o[8], r[8];
    _mm512_store_pd(o, max_overlap);
    _mm512_store_pd(r, max_ratio);
    double mo = o[0], mr = r[0];
    for (int l = 1; l < 8; ++l) {
      mo = std::max(mo, o[l]);
      mr = std::max(mr, r[l]);
    }
    add_stats(stats, contacts, mo, mr);
  }
};

template <bool Full, bool Indexed>
DEM_AVX512 __attribute__((always_inline)) inline ChunkOut ChunkKernel::compute(
    const ChunkIn& in, std::int32_t k) {
  Vec3* const spring = this->spring + k;
  // Indexed: lane l's spring is also written to its home in the half list's array.
  const auto put = [&](int l, Vec3 v) {
    spring[l] = v;
    if constexpr (Indexed) spring_home[in.kl[l]] = v;
  };
  ChunkOut out;
  const __mmask8 live = in.live;
  const Lanes3 xj = load_vec3(X, in.jl), uj = load_vec3(U, in.jl);
  const __m512d rj = _mm512_mask_i32gather_pd(one, live, in.j, R, 8);
  __mmask8 smask[3];
  vec3_masks(std::min(in.left, 8), smask);
  const Lanes3 s0 = load_contiguous(mix, reinterpret_cast<const double*>(spring), smask);
  __m512d sx = s0.x, sy = s0.y, sz = s0.z;

  // The screen (surely_apart, after the d2 >= rsum^2 test).
  const __m512d dx = _mm512_sub_pd(in.xix, xj.x), dy = _mm512_sub_pd(in.xiy, xj.y),
                dz = _mm512_sub_pd(in.xiz, xj.z);
  const __m512d rsum = _mm512_add_pd(in.ri, rj);
  const __m512d d2 = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)),
                                   _mm512_mul_pd(dz, dz));
  const __m512d ux = _mm512_sub_pd(in.uix, uj.x), uy = _mm512_sub_pd(in.uiy, uj.y),
                uz = _mm512_sub_pd(in.uiz, uj.z);
  const __m512d urel2 = _mm512_add_pd(
      _mm512_add_pd(_mm512_mul_pd(ux, ux), _mm512_mul_pd(uy, uy)), _mm512_mul_pd(uz, uz));
  out.urel2 = urel2;
  const __m512d rs2 = _mm512_mul_pd(rsum, rsum);
  const __m512d g2 = _mm512_mul_pd(quarter_dt2, urel2);
  const __m512d q = _mm512_sub_pd(_mm512_sub_pd(d2, rs2), g2);
  const __m512d q4 = _mm512_mul_pd(_mm512_mul_pd(_mm512_mul_pd(four, rsum), rsum), g2);
  __mmask8 apart = _mm512_mask_cmp_pd_mask(live, d2, rs2, _CMP_GE_OQ);
  apart = _mm512_mask_cmp_pd_mask(apart, q, zero, _CMP_GE_OQ);
  apart = _mm512_mask_cmp_pd_mask(apart, _mm512_mul_pd(q, q), q4, _CMP_GE_OQ);
  // Ended contacts: a held spring is cleared.
  const __m512i sbits = _mm512_slli_epi64(
      _mm512_or_si512(_mm512_or_si512(_mm512_castpd_si512(sx), _mm512_castpd_si512(sy)),
                      _mm512_castpd_si512(sz)),
      1);
  out.clear = _mm512_mask_test_epi64_mask(apart, sbits, sbits);
  const __mmask8 cand = live & static_cast<__mmask8>(~apart);
  if (cand == 0) {
    for (unsigned m = out.clear; m != 0; m &= m - 1) put(__builtin_ctz(m), Vec3{});
    return out;
  }

  // The normal, the coefficients, contact_force.
  const __m512d dist = _mm512_sqrt_pd(d2);
  const __m512d inv = _mm512_div_pd(one, dist);
  const __mmask8 positive = _mm512_cmp_pd_mask(dist, zero, _CMP_GT_OQ);
  const __m512d nx = pick(positive, _mm512_mul_pd(inv, dx), zero);
  const __m512d ny = pick(positive, _mm512_mul_pd(inv, dy), zero);
  const __m512d nz = pick(positive, _mm512_mul_pd(inv, dz), one);
  const __m512d mj = _mm512_mask_i32gather_pd(one, cand, in.j, M, 8);
  // The contact coefficients of the pair. A monodisperse bed repeats one pair: the
  // coefficients of the last uniform chunk are reused when every candidate lane has its radii
  // and masses (the same bits as computing them again).
  __m512d ck, ceta;
  const __mmask8 same = _mm512_mask_cmp_pd_mask(cand, rj, cached_rj, _CMP_EQ_OQ) &
                        _mm512_mask_cmp_pd_mask(cand, mj, cached_mj, _CMP_EQ_OQ) &
                        _mm512_mask_cmp_pd_mask(cand, in.ri, cached_ri, _CMP_EQ_OQ) &
                        _mm512_mask_cmp_pd_mask(cand, in.mi, cached_mi, _CMP_EQ_OQ);
  if (same == cand) {
    ck = cached_k;
    ceta = cached_eta;
  } else {
    const __m512d length = _mm512_div_pd(_mm512_mul_pd(in.ri, rj), rsum);
    const __m512d m_eff = _mm512_div_pd(_mm512_mul_pd(in.mi, mj), _mm512_add_pd(in.mi, mj));
    ck = pick(per_length, _mm512_mul_pd(kn, length), kn);
    ceta = pick(from_restitution,
                _mm512_mul_pd(two_zeta, _mm512_sqrt_pd(_mm512_mul_pd(m_eff, ck))), eta_fixed);
    // Remember them if the chunk itself is uniform.
    const __m512i first = _mm512_set1_epi64(__builtin_ctz(cand));
    const __m512d ri0 = _mm512_permutexvar_pd(first, in.ri),
                  mi0 = _mm512_permutexvar_pd(first, in.mi),
                  rj0 = _mm512_permutexvar_pd(first, rj), mj0 = _mm512_permutexvar_pd(first, mj);
    if ((_mm512_mask_cmp_pd_mask(cand, rj, rj0, _CMP_EQ_OQ) &
         _mm512_mask_cmp_pd_mask(cand, mj, mj0, _CMP_EQ_OQ) &
         _mm512_mask_cmp_pd_mask(cand, in.ri, ri0, _CMP_EQ_OQ) &
         _mm512_mask_cmp_pd_mask(cand, in.mi, mi0, _CMP_EQ_OQ)) == cand) {
      cached_ri = ri0;
      cached_mi = mi0;
      cached_rj = rj0;
      cached_mj = mj0;
      cached_k = _mm512_permutexvar_pd(first, ck);
      cached_eta = _mm512_permutexvar_pd(first, ceta);
    }
  }
  const __m512d ckt = _mm512_mul_pd(kt_ratio, ck);
  const __m512d cetat = _mm512_mul_pd(etat_ratio, ceta);
  const __mmask8 kt_positive = _mm512_cmp_pd_mask(ckt, zero, _CMP_GT_OQ);

  const __m512d overlap = _mm512_sub_pd(rsum, dist);
  const __m512d vn = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(ux, nx), _mm512_mul_pd(uy, ny)),
                                   _mm512_mul_pd(uz, nz));
  const __m512d abs_vn = _mm512_castsi512_pd(_mm512_andnot_si512(sign, _mm512_castpd_si512(vn)));
  const __m512d hv = _mm512_mul_pd(half_dt, abs_vn);
  const __m512d neg_hv = _mm512_castsi512_pd(_mm512_xor_si512(sign, _mm512_castpd_si512(hv)));
  // active: not (overlap <= -half)
  const __mmask8 act = _mm512_mask_cmp_pd_mask(cand, overlap, neg_hv, _CMP_NLE_UQ);
  const __mmask8 full = _mm512_cmp_pd_mask(overlap, hv, _CMP_GE_OQ);
  __m512d active = one, fn = _mm512_mul_pd(ck, overlap);
  if (act & ~full) {  // a contact starting or ending inside the step's window: rare
    const __m512d w = _mm512_add_pd(overlap, hv);
    active = pick(full, one, _mm512_div_pd(w, _mm512_mul_pd(two, hv)));
    fn = pick(full, fn,
              _mm512_div_pd(_mm512_mul_pd(_mm512_mul_pd(ck, w), w), _mm512_mul_pd(four, hv)));
  }
  fn = _mm512_sub_pd(fn, _mm512_mul_pd(_mm512_mul_pd(active, ceta), vn));
  fn = pick(clip & _mm512_cmp_pd_mask(fn, zero, _CMP_LT_OQ), zero, fn);
  const __m512d vtx = _mm512_sub_pd(ux, _mm512_mul_pd(vn, nx));
  const __m512d vty = _mm512_sub_pd(uy, _mm512_mul_pd(vn, ny));
  const __m512d vtz = _mm512_sub_pd(uz, _mm512_mul_pd(vn, nz));

  // The spring turned into the tangent plane, its length kept.
  const __m512d s2 = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(sx, sx), _mm512_mul_pd(sy, sy)),
                                   _mm512_mul_pd(sz, sz));
  const __mmask8 held = _mm512_cmp_pd_mask(s2, zero, _CMP_GT_OQ);
  if (Full || held) {
    const __m512d sn = _mm512_add_pd(
        _mm512_add_pd(_mm512_mul_pd(sx, nx), _mm512_mul_pd(sy, ny)), _mm512_mul_pd(sz, nz));
    const __m512d spx = _mm512_sub_pd(sx, _mm512_mul_pd(sn, nx));
    const __m512d spy = _mm512_sub_pd(sy, _mm512_mul_pd(sn, ny));
    const __m512d spz = _mm512_sub_pd(sz, _mm512_mul_pd(sn, nz));
    const __m512d xs = _mm512_div_pd(_mm512_mul_pd(sn, sn), s2);
    const __mmask8 small = _mm512_cmp_pd_mask(xs, tiny, _CMP_LT_OQ);
    const __mmask8 below_one = _mm512_cmp_pd_mask(xs, one, _CMP_LT_OQ);
    __m512d fl = zero;
    if (Full || (below_one & ~small & held))
      fl = pick(below_one, _mm512_div_pd(one, _mm512_sqrt_pd(_mm512_sub_pd(one, xs))), zero);
    fl = pick(small, _mm512_add_pd(one, _mm512_mul_pd(half, xs)), fl);
    sx = pick(held, _mm512_mul_pd(fl, spx), sx);
    sy = pick(held, _mm512_mul_pd(fl, spy), sy);
    sz = pick(held, _mm512_mul_pd(fl, spz), sz);
  }
  const __m512d adt = _mm512_mul_pd(active, vdt);
  sx = _mm512_add_pd(sx, _mm512_mul_pd(adt, vtx));
  sy = _mm512_add_pd(sy, _mm512_mul_pd(adt, vty));
  sz = _mm512_add_pd(sz, _mm512_mul_pd(adt, vtz));
  const __m512d neg_kt = _mm512_castsi512_pd(_mm512_xor_si512(sign, _mm512_castpd_si512(ckt)));
  const __m512d aetat = _mm512_mul_pd(active, cetat);
  __m512d ftx = _mm512_sub_pd(_mm512_mul_pd(neg_kt, sx), _mm512_mul_pd(aetat, vtx));
  __m512d fty = _mm512_sub_pd(_mm512_mul_pd(neg_kt, sy), _mm512_mul_pd(aetat, vty));
  __m512d ftz = _mm512_sub_pd(_mm512_mul_pd(neg_kt, sz), _mm512_mul_pd(aetat, vtz));
  const __m512d cap = _mm512_mul_pd(mu, pick(_mm512_cmp_pd_mask(fn, zero, _CMP_GT_OQ), fn, zero));
  const __m512d ft2 = _mm512_add_pd(
      _mm512_add_pd(_mm512_mul_pd(ftx, ftx), _mm512_mul_pd(fty, fty)), _mm512_mul_pd(ftz, ftz));
  const __mmask8 binds = _mm512_cmp_pd_mask(ft2, _mm512_mul_pd(cap, cap), _CMP_GT_OQ) & act;
  if (Full || binds) {
    const __m512d neg_inv_kt = pick(kt_positive, _mm512_div_pd(minus_one, ckt), zero);
    const __m512d scale = _mm512_div_pd(cap, _mm512_sqrt_pd(ft2));
    const __m512d cx = _mm512_mul_pd(scale, ftx), cy = _mm512_mul_pd(scale, fty),
                  cz = _mm512_mul_pd(scale, ftz);
    sx = pick(binds, pick(kt_positive, _mm512_mul_pd(neg_inv_kt, cx), zero), sx);
    sy = pick(binds, pick(kt_positive, _mm512_mul_pd(neg_inv_kt, cy), zero), sy);
    sz = pick(binds, pick(kt_positive, _mm512_mul_pd(neg_inv_kt, cz), zero), sz);
    ftx = pick(binds, cx, ftx);
    fty = pick(binds, cy, fty);
    ftz = pick(binds, cz, ftz);
  }
  // Springs: advanced where active, cleared where the pair is out of contact.
  // One lane at a time: a masked vector store would overlap the next chunk's load and stall
  // it (no store forwarding from a partly masked store).
  _mm512_store_pd(fx, pick(act, sx, zero));
  _mm512_store_pd(fy, pick(act, sy, zero));
  _mm512_store_pd(fz, pick(act, sz, zero));
  for (unsigned m = cand | out.clear; m != 0; m &= m - 1) {
    const int l = __builtin_ctz(m);
    put(l, Vec3{fx[l], fy[l], fz[l]});
  }
  out.act = act;
  if (act == 0) return out;

  _mm512_store_pd(fx, _mm512_add_pd(_mm512_mul_pd(fn, nx), ftx));
  _mm512_store_pd(fy, _mm512_add_pd(_mm512_mul_pd(fn, ny), fty));
  _mm512_store_pd(fz, _mm512_add_pd(_mm512_mul_pd(fn, nz), ftz));
  contacts += __builtin_popcount(act);
  max_overlap = _mm512_mask_max_pd(max_overlap, act, max_overlap, overlap);
  // The ratio's division only where a lane may raise its maximum: below (1 - 1e-9) times the
  // maximum times the radius the quotient rounds to at most the maximum (the same maxima).
  const __m512d rmin = _mm512_min_pd(in.ri, rj);
  const __mmask8 may = _mm512_mask_cmp_pd_mask(
      act, overlap, _mm512_mul_pd(_mm512_mul_pd(max_ratio, rmin), ratio_margin), _CMP_GE_OQ);
  if (may)
    max_ratio = _mm512_mask_max_pd(max_ratio, may, max_ratio, _mm512_div_pd(overlap, rmin));
  return out;
}

constexpr int kPrefetchAhead = 24;  // candidates ahead (24-96 measured alike; 400 too far)

// The springs and partners of the chunks ahead (the hardware's prefetcher does not keep up
// with this stream here).
DEM_AVX512 inline void prefetch_ahead(const Vec3* spring, const std::int32_t* J, std::int32_t k,
                                      std::int32_t kend) {
  if (k + kPrefetchAhead + 8 < kend) {
    const double* const ahead = reinterpret_cast<const double*>(spring + k + kPrefetchAhead);
    for (int line = 0; line < 3; ++line)
      _mm_prefetch(reinterpret_cast<const char*>(ahead + 8 * line), _MM_HINT_T0);
    _mm_prefetch(reinterpret_cast<const char*>(J + k + kPrefetchAhead), _MM_HINT_T0);
  }
}

// The same for close pairs: their partners, indices and the springs they point to.
DEM_AVX512 inline void prefetch_indexed(const Vec3* spring, const Vec3* home,
                                        const std::int32_t* SI, const std::int32_t* J,
                                        std::int32_t k, std::int32_t kend) {
  prefetch_ahead(spring, J, k, kend);
  if (k + kPrefetchAhead + 8 < kend) {
    const std::int32_t s0 = SI[k + kPrefetchAhead], s1 = SI[k + kPrefetchAhead + 7];
    _mm_prefetch(reinterpret_cast<const char*>(home + s0), _MM_HINT_T0);
    _mm_prefetch(reinterpret_cast<const char*>(home + s1) + 16, _MM_HINT_T0);
    _mm_prefetch(reinterpret_cast<const char*>(SI + k + 2 * kPrefetchAhead), _MM_HINT_T0);
  }
}

// The rows of [base, base + 64) within [a0, a1) that the sleeping row loop reads, as bits: the
// awake ones and the sleepers with an awake partner (with no counts, every row). `off` given,
// also the clean ones among them (*clean): awake, with every partner awake (the count of awake
// partners equals the row's length); else *clean = 0.
DEM_AVX512 inline std::uint64_t rows_to_read(const PairSleep& sl, std::size_t base,
                                             std::size_t a0, std::size_t a1,
                                             const std::int32_t* off, std::uint64_t* clean) {
  const std::size_t lo = a0 > base ? a0 - base : 0;
  const std::size_t hi = std::min<std::size_t>(64, a1 - base);
  const std::uint64_t range = (hi == 64 ? ~0ull : (1ull << hi) - 1) & (~0ull << lo);
  *clean = 0;
  if (!sl.awake_partners) return range;
  const __m512i steps = _mm512_set1_epi32(sl.steps), none = _mm512_setzero_si512();
  std::uint64_t bits = 0;
  for (int q = 0; q < 4; ++q) {
    const __mmask16 m = static_cast<__mmask16>(range >> (16 * q));
    if (m == 0) continue;
    const std::size_t r = base + 16 * static_cast<std::size_t>(q);
    const __m512i rest = _mm512_maskz_loadu_epi32(m, sl.rest + r);
    const __m512i count = _mm512_maskz_loadu_epi32(m, sl.awake_partners + r);
    const __mmask16 awake = _mm512_mask_cmplt_epi32_mask(m, rest, steps);
    const __mmask16 read = awake | _mm512_mask_cmpneq_epi32_mask(m, count, none);
    bits |= static_cast<std::uint64_t>(read) << (16 * q);
    if (off) {
      const __m512i len = _mm512_sub_epi32(_mm512_maskz_loadu_epi32(m, off + r + 1),
                                           _mm512_maskz_loadu_epi32(m, off + r));
      const __mmask16 c = _mm512_mask_cmpeq_epi32_mask(awake, count, len);
      *clean |= static_cast<std::uint64_t>(c) << (16 * q);
    }
  }
  return bits;
}

// With sleepers: row by row, 8 candidates of a row at a time (the sleeping rules are per row).
// Indexed: the rows are the close pairs' (PairRows::spring_index), as in stream<true>. The rows
// are taken 64 at a time as bits (rows_to_read), so a sleeper's row that has no awake partner
// costs no branch of its own.
template <bool Indexed>
DEM_AVX512 void ChunkKernel::rows(const PairSleep& sl, std::size_t a0, std::size_t a1,
                                  std::size_t direct, std::vector<PairRemote>& remote,
                                  PairRowStats& stats, bool full_chunks) {
  alignas(32) std::int32_t jl[8];
  const std::int32_t kend = off[a1];
  const __m256i sleep_steps = _mm256_set1_epi32(sl.steps);
  const __m512d wake_speed2 = _mm512_set1_pd(sl.wake_speed2);
  // Clean rows: an awake particle whose partners are all awake (its count of awake partners is
  // its row's length). No sleeping rule applies to them, so a run of at least kStreamRun
  // consecutive clean rows goes to the stream kernel, which fills every lane (the same pairs in
  // the same order: the same bits). Only with the counts of the half list (not close pairs).
  constexpr std::size_t kStreamRun = 8;
  const bool streams = !Indexed && sl.awake_partners != nullptr;
  std::size_t run0 = 0, run1 = 0;  // the pending run of clean rows [run0, run1)
  const auto one_row = [&](std::size_t i) DEM_AVX512 {
    const std::int32_t k1 = off[i + 1];
    const bool si = sl.rest[i] >= sl.steps;
    Vec3 fi{};
    if (off[i] < k1) {
      ChunkIn in;
      in.xix = _mm512_set1_pd(X[3 * i]);
      in.xiy = _mm512_set1_pd(X[3 * i + 1]);
      in.xiz = _mm512_set1_pd(X[3 * i + 2]);
      in.uix = _mm512_set1_pd(U[3 * i]);
      in.uiy = _mm512_set1_pd(U[3 * i + 1]);
      in.uiz = _mm512_set1_pd(U[3 * i + 2]);
      in.ri = _mm512_set1_pd(R[i]);
      in.mi = _mm512_set1_pd(M[i]);
      in.jl = jl;
      for (std::int32_t k = off[i]; k < k1; k += 8) {
        in.left = k1 - k;
        const __mmask8 row =
            in.left >= 8 ? 0xFF : static_cast<__mmask8>((1u << in.left) - 1);
        in.j = _mm256_maskz_loadu_epi32(row, J + k);
        _mm256_store_si256(reinterpret_cast<__m256i*>(jl), in.j);
        // Sleeping: sj = partners asleep; for a sleeper's row those pairs are skipped (their
        // springs stay as they were), and every remaining pair is awake against asleep.
        __mmask8 sj = 0, sleepy = 0;
        in.live = row;
        {
          const __m256i rest = _mm256_mmask_i32gather_epi32(_mm256_setzero_si256(), row, in.j,
                                                            sl.rest, 4);
          sj = _mm256_mask_cmp_epi32_mask(row, rest, sleep_steps, _MM_CMPINT_NLT);
          if (si) in.live = row & static_cast<__mmask8>(~sj);
          sleepy = si ? in.live : sj;
          if (in.live == 0) continue;
        }
        if constexpr (Indexed) {
          in.kl = spring_index + k;
          prefetch_indexed(spring, spring_home, spring_index, J, k, kend);
        } else {
          prefetch_ahead(spring, J, k, kend);
        }
        const ChunkOut out = compute<false, Indexed>(in, k);
        // A sleeper whose contact with an awake particle ends may have lost its support.
        for (unsigned m = out.clear & sleepy; m != 0; m &= m - 1)
            wake(sl, si ? i : static_cast<std::size_t>(jl[__builtin_ctz(m)]), direct);
        if (out.act == 0) continue;
        {  // a partner faster than scene.sleep.wake_speed relative to a sleeper wakes it
          const __mmask8 fast =
              _mm512_mask_cmp_pd_mask(out.act & sleepy, out.urel2, wake_speed2, _CMP_GT_OQ);
          for (unsigned m = fast; m != 0; m &= m - 1)
            wake(sl, si ? i : static_cast<std::size_t>(jl[__builtin_ctz(m)]), direct);
        }
        // The forces in pair order, as the scalar loop applies them (awake against asleep: on
        // the awake particle only).
        for (unsigned m = out.act; m != 0; m &= m - 1) {
          const int l = __builtin_ctz(m);
          const Vec3 f{fx[l], fy[l], fz[l]};
          if (!si) fi += f;
          if (!((sj >> l) & 1)) on_partner(F, remote, jl[l], f, direct);
        }
      }
    }
    F[i] += fi;
  };
  const auto flush = [&]() DEM_AVX512 {
    if (run1 - run0 >= kStreamRun) {
      if (full_chunks)
        stream<false, true>(run0, run1, direct, remote, stats, false);
      else
        stream<false, false>(run0, run1, direct, remote, stats, false);
    } else {
      for (std::size_t r = run0; r < run1; ++r) one_row(r);
    }
    run0 = run1 = 0;
  };
  for (std::size_t base = a0 - a0 % 64; base < a1; base += 64) {
    std::uint64_t clean;
    const std::uint64_t read = rows_to_read(sl, base, a0, a1, streams ? off : nullptr, &clean);
    for (std::uint64_t m = read; m != 0; m &= m - 1) {
      const std::size_t i = base + static_cast<std::size_t>(__builtin_ctzll(m));
      if ((clean >> (i - base)) & 1) {
        if (run1 != i) {
          if (run1 > run0) flush();
          run0 = i;
        }
        run1 = i + 1;
        continue;
      }
      if (run1 > run0) flush();
      one_row(i);
    }
  }
  if (run1 > run0) flush();
  finish(stats);
}

// All particles awake: 8 consecutive pairs of the half list at a time, whichever rows they are
// in, so that short rows do not leave lanes empty (rows of the paper's pile hold 5.5 candidates
// on average: 61 % of the lanes of a row-by-row chunk). The i side of each lane is read from
// the chunk's rows, which are consecutive. Row i's force is added when the stream has passed
// it, after its pairs' partners, as the row loop does.
template <bool Indexed, bool Full>
DEM_AVX512 void ChunkKernel::stream(std::size_t a0, std::size_t a1, std::size_t direct,
                                    std::vector<PairRemote>& remote, PairRowStats& stats,
                                    bool finish_stats) {
  alignas(32) std::int32_t jl[8], il[8], kl[8];
  const std::int32_t kend = off[a1];
  std::size_t scan = a0;  // the row of the pair being assigned to a lane
  std::size_t done = a0;  // rows before it have their force added
  Vec3 fi{};              // the sum of row `done`'s forces so far
  ChunkIn in;
  in.jl = jl;
  in.kl = kl;
  const __m256i lane_index = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  while (scan < a1 && off[scan + 1] == off[a0]) ++scan;  // rows without candidates first
  for (std::int32_t k = off[a0]; k < kend; k += 8) {
    in.left = kend - k;
    const int lanes = std::min(in.left, 8);
    in.live = in.left >= 8 ? 0xFF : static_cast<__mmask8>((1u << in.left) - 1);
    // The row of each lane: `scan` (the row of pair k) plus the row ends among the next 8
    // rows that the lane's pair has passed. If the chunk reaches beyond them (rows without
    // candidates, rare), one lane at a time.
    __m256i iv;
    const std::size_t ahead = std::min<std::size_t>(8, a1 - scan);
    const std::int32_t last = k + lanes - 1;
    if (scan + ahead == a1 || off[scan + 9] > last) {
      const __m256i ends = _mm256_mask_loadu_epi32(_mm256_set1_epi32(kend), (1u << ahead) - 1,
                                                   off + scan + 1);
      const __m256i pair = _mm256_add_epi32(_mm256_set1_epi32(k), lane_index);
      __m256i passed = _mm256_setzero_si256();
      for (int q = 0; q < 8; ++q) {
        const __m256i end = _mm256_permutexvar_epi32(_mm256_set1_epi32(q), ends);
        passed = _mm256_mask_sub_epi32(passed, _mm256_cmpge_epi32_mask(pair, end), passed,
                                       _mm256_set1_epi32(-1));
      }
      iv = _mm256_add_epi32(_mm256_set1_epi32(static_cast<std::int32_t>(scan)), passed);
      // dead lanes: the last live lane's row
      iv = _mm256_permutexvar_epi32(_mm256_min_epi32(lane_index, _mm256_set1_epi32(lanes - 1)),
                                    iv);
      _mm256_store_si256(reinterpret_cast<__m256i*>(il), iv);
    } else {
      for (int l = 0; l < lanes; ++l) {
        while (k + l >= off[scan + 1]) ++scan;
        il[l] = static_cast<std::int32_t>(scan);
      }
      for (int l = lanes; l < 8; ++l) il[l] = il[lanes - 1];
      iv = _mm256_load_si256(reinterpret_cast<const __m256i*>(il));
    }
    // The row of the next chunk's first pair.
    scan = static_cast<std::size_t>(il[7]);
    if (k + 8 < kend)
      while (k + 8 >= off[scan + 1]) ++scan;
    const std::int32_t i0 = il[0], span = il[lanes - 1] - i0 + 1;
    if (span <= 8) {
      // The rows' particles, contiguous from i0, and each lane's pick among them.
      __mmask8 m[3];
      vec3_masks(span, m);
      const __mmask8 rows = static_cast<__mmask8>((1u << span) - 1);
      const __m512i pickv = _mm512_cvtepi32_epi64(_mm256_sub_epi32(iv, _mm256_set1_epi32(i0)));
      const Lanes3 xi = load_contiguous(mix, X + 3 * static_cast<std::size_t>(i0), m);
      const Lanes3 ui = load_contiguous(mix, U + 3 * static_cast<std::size_t>(i0), m);
      in.xix = _mm512_permutexvar_pd(pickv, xi.x);
      in.xiy = _mm512_permutexvar_pd(pickv, xi.y);
      in.xiz = _mm512_permutexvar_pd(pickv, xi.z);
      in.uix = _mm512_permutexvar_pd(pickv, ui.x);
      in.uiy = _mm512_permutexvar_pd(pickv, ui.y);
      in.uiz = _mm512_permutexvar_pd(pickv, ui.z);
      in.ri = _mm512_permutexvar_pd(pickv, _mm512_maskz_loadu_pd(rows, R + i0));
      in.mi = _mm512_permutexvar_pd(pickv, _mm512_maskz_loadu_pd(rows, M + i0));
    } else {  // rows without candidates in between: rare
      const Lanes3 xi = load_vec3(X, il), ui = load_vec3(U, il);
      in.xix = xi.x;
      in.xiy = xi.y;
      in.xiz = xi.z;
      in.uix = ui.x;
      in.uiy = ui.y;
      in.uiz = ui.z;
      in.ri = _mm512_i32gather_pd(iv, R, 8);
      in.mi = _mm512_i32gather_pd(iv, M, 8);
    }
    in.j = _mm256_maskz_loadu_epi32(in.live, J + k);
    _mm256_store_si256(reinterpret_cast<__m256i*>(jl), in.j);
    if constexpr (Indexed) {
      _mm256_store_si256(reinterpret_cast<__m256i*>(kl),
                         _mm256_maskz_loadu_epi32(in.live, spring_index + k));
      prefetch_indexed(spring, spring_home, spring_index, J, k, kend);
    } else {
      prefetch_ahead(spring, J, k, kend);
    }
    const ChunkOut out = compute<Full, Indexed>(in, k);
    // The forces in pair order: a row's sum is added once the stream has left the row.
    for (unsigned m = out.act; m != 0; m &= m - 1) {
      const int l = __builtin_ctz(m);
      const std::size_t i = static_cast<std::size_t>(il[l]);
      for (; done < i; ++done) {
        F[done] += fi;
        fi = Vec3{};
      }
      fi += Vec3{fx[l], fy[l], fz[l]};
      on_partner(F, remote, jl[l], Vec3{fx[l], fy[l], fz[l]}, direct);
    }
  }
  for (; done < a1; ++done) {
    F[done] += fi;
    fi = Vec3{};
  }
  if (finish_stats) finish(stats);
}
#undef DEM_AVX512
#endif

}  // namespace

bool pair_rows_vector_available() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
         __builtin_cpu_supports("avx512dq");
#else
  return false;
#endif
}

static bool branch_free_by_processor() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_is("amd");
#else
  return false;
#endif
}

bool branch_free_chunks_default() {
  static const bool by_processor = branch_free_by_processor();
  return by_processor;
}

// The one place that picks the kernel: the vector one when asked for and available.
template <bool Sleep>
static void dispatch(const PairRows& p, const PairSleep& sleep, std::size_t a0, std::size_t a1,
                     std::vector<PairRemote>& remote, PairRowStats& stats, bool vector) {
  // Partners below `direct` are written directly (PairRows::direct_end; 0: the rows' end).
  const std::size_t direct = p.direct_end ? std::max(p.direct_end, a1) : a1;
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool available = pair_rows_vector_available();
  if (vector && available) {
    ChunkKernel kernel(p);
    const bool full = p.branch_free_chunks;
    if (Sleep && p.spring_index)
      kernel.rows<true>(sleep, a0, a1, direct, remote, stats, full);
    else if (Sleep)
      kernel.rows<false>(sleep, a0, a1, direct, remote, stats, full);
    else if (full)
      p.spring_index ? kernel.stream<true, true>(a0, a1, direct, remote, stats)
                     : kernel.stream<false, true>(a0, a1, direct, remote, stats);
    else
      p.spring_index ? kernel.stream<true, false>(a0, a1, direct, remote, stats)
                     : kernel.stream<false, false>(a0, a1, direct, remote, stats);
    return;
  }
#endif
  pair_rows_scalar<Sleep>(p, sleep, a0, a1, direct, remote, stats);
}

void pair_rows(const PairRows& p, std::size_t a0, std::size_t a1, std::vector<PairRemote>& remote,
               PairRowStats& stats, bool vector) {
  dispatch<false>(p, PairSleep{}, a0, a1, remote, stats, vector);
}

void pair_rows_sleep(const PairRows& p, const PairSleep& sleep, std::size_t a0, std::size_t a1,
                     std::vector<PairRemote>& remote, PairRowStats& stats, bool vector) {
  dispatch<true>(p, sleep, a0, a1, remote, stats, vector);
}

}  // namespace dem::detail
