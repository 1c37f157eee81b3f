// The AVX-512 intrinsics the chunk kernel uses (pair_kernel_chunks.inc), emulated lane by lane in
// portable C++ with the instructions' documented semantics: IEEE double arithmetic per lane
// (add, sub, mul, div, sqrt; no fused multiply-add: the engine is built with -ffp-contract=off),
// the compare predicates the kernel uses (ordered and unordered), blends, masked loads, gathers,
// permutes, bit operations, and x86 max/min (the second operand where either is NaN or both are
// zero). Compiled into pair_kernel_emulated.cpp only, never beside <immintrin.h>: it lets the
// same kernel source run and be tested bit for bit against the scalar loop on a processor
// without AVX-512. Slow; for tests.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

// The predicate numbers of <immintrin.h> (only the values matter to the emulated compare).
#ifndef _CMP_EQ_OQ
#define _CMP_EQ_OQ 0x00
#define _CMP_LT_OQ 0x11
#define _CMP_NLE_UQ 0x16
#define _CMP_GE_OQ 0x1d
#define _CMP_GT_OQ 0x1e
#define _MM_CMPINT_NLT 5
#define _MM_HINT_T0 3
#endif

namespace dem::detail::emulated {

using __mmask8 = unsigned char;
using __mmask16 = unsigned short;
struct __m512d {
  double v[8];
};
struct __m256d {
  double v[4];
};
struct __m512i {  // 8 x 64 bits or 16 x 32 bits
  std::int64_t q[8];
  std::int32_t d(int l) const {
    std::int32_t x;
    std::memcpy(&x, reinterpret_cast<const char*>(q) + 4 * l, 4);
    return x;
  }
  void set_d(int l, std::int32_t x) { std::memcpy(reinterpret_cast<char*>(q) + 4 * l, &x, 4); }
};
struct __m256i {
  std::int32_t d[8];
};

inline bool bit(unsigned m, int l) { return (m >> l) & 1u; }

// --- doubles
inline __m512d _mm512_setzero_pd() { return {}; }
inline __m512d _mm512_set1_pd(double a) {
  __m512d r;
  for (double& x : r.v) x = a;
  return r;
}
#define DEM_EMUL_BINARY(name, op)                                \
  inline __m512d name(__m512d a, __m512d b) {                    \
    __m512d r;                                                   \
    for (int l = 0; l < 8; ++l) r.v[l] = a.v[l] op b.v[l];       \
    return r;                                                    \
  }
DEM_EMUL_BINARY(_mm512_add_pd, +)
DEM_EMUL_BINARY(_mm512_sub_pd, -)
DEM_EMUL_BINARY(_mm512_mul_pd, *)
DEM_EMUL_BINARY(_mm512_div_pd, /)
#undef DEM_EMUL_BINARY
inline __m512d _mm512_sqrt_pd(__m512d a) {
  for (double& x : a.v) x = std::sqrt(x);
  return a;
}
// VMAXPD / VMINPD: a > b ? a : b (b where either is NaN or both are zero).
inline __m512d _mm512_mask_max_pd(__m512d src, __mmask8 k, __m512d a, __m512d b) {
  for (int l = 0; l < 8; ++l)
    if (bit(k, l)) src.v[l] = a.v[l] > b.v[l] ? a.v[l] : b.v[l];
  return src;
}
inline __m512d _mm512_min_pd(__m512d a, __m512d b) {
  for (int l = 0; l < 8; ++l) a.v[l] = a.v[l] < b.v[l] ? a.v[l] : b.v[l];
  return a;
}
inline bool compare(double a, double b, int predicate) {
  switch (predicate) {
    case _CMP_EQ_OQ:
      return a == b;
    case _CMP_LT_OQ:
      return a < b;
    case _CMP_GE_OQ:
      return a >= b;
    case _CMP_GT_OQ:
      return a > b;
    case _CMP_NLE_UQ:
      return !(a <= b);  // unordered: true where either is NaN
  }
  std::abort();  // a predicate the kernel does not use: add it here
}
inline __mmask8 _mm512_mask_cmp_pd_mask(__mmask8 k, __m512d a, __m512d b, int predicate) {
  unsigned m = 0;
  for (int l = 0; l < 8; ++l)
    if (bit(k, l) && compare(a.v[l], b.v[l], predicate)) m |= 1u << l;
  return static_cast<__mmask8>(m);
}
inline __mmask8 _mm512_cmp_pd_mask(__m512d a, __m512d b, int predicate) {
  return _mm512_mask_cmp_pd_mask(0xFF, a, b, predicate);
}
inline __m512d _mm512_mask_blend_pd(__mmask8 k, __m512d a, __m512d b) {
  for (int l = 0; l < 8; ++l)
    if (bit(k, l)) a.v[l] = b.v[l];
  return a;
}
inline __m512d _mm512_maskz_loadu_pd(__mmask8 k, const double* p) {
  __m512d r{};
  for (int l = 0; l < 8; ++l)
    if (bit(k, l)) r.v[l] = p[l];
  return r;
}
inline void _mm512_store_pd(double* p, __m512d a) { std::memcpy(p, a.v, sizeof a.v); }
inline __m256d _mm256_maskz_loadu_pd(__mmask8 k, const double* p) {
  __m256d r{};
  for (int l = 0; l < 4; ++l)
    if (bit(k, l)) r.v[l] = p[l];
  return r;
}
inline __m512d _mm512_castpd256_pd512(__m256d a) {
  __m512d r{};  // the upper half is undefined on the processor; the kernel overwrites it
  for (int l = 0; l < 4; ++l) r.v[l] = a.v[l];
  return r;
}
inline __m512d _mm512_insertf64x4(__m512d a, __m256d b, int half) {
  for (int l = 0; l < 4; ++l) a.v[4 * (half & 1) + l] = b.v[l];
  return a;
}
inline __m512d _mm512_permutexvar_pd(__m512i idx, __m512d a) {
  __m512d r;
  for (int l = 0; l < 8; ++l) r.v[l] = a.v[idx.q[l] & 7];
  return r;
}
inline __m512d _mm512_permutex2var_pd(__m512d a, __m512i idx, __m512d b) {
  __m512d r;
  for (int l = 0; l < 8; ++l) {
    const int i = static_cast<int>(idx.q[l] & 15);
    r.v[l] = i < 8 ? a.v[i] : b.v[i - 8];
  }
  return r;
}
// 128-bit blocks: the result's blocks 0, 1 from a, 2, 3 from b, chosen by imm's 2-bit fields.
inline __m512d _mm512_shuffle_f64x2(__m512d a, __m512d b, int imm) {
  __m512d r;
  for (int blk = 0; blk < 4; ++blk) {
    const __m512d& src = blk < 2 ? a : b;
    const int from = (imm >> (2 * blk)) & 3;
    r.v[2 * blk] = src.v[2 * from];
    r.v[2 * blk + 1] = src.v[2 * from + 1];
  }
  return r;
}
inline __m512d _mm512_mask_i32gather_pd(__m512d src, __mmask8 k, __m256i idx, const double* base,
                                        int scale) {
  for (int l = 0; l < 8; ++l)
    if (bit(k, l))
      std::memcpy(&src.v[l], reinterpret_cast<const char*>(base) +
                                 static_cast<std::ptrdiff_t>(idx.d[l]) * scale, 8);
  return src;
}
inline __m512d _mm512_i32gather_pd(__m256i idx, const double* base, int scale) {
  return _mm512_mask_i32gather_pd(__m512d{}, 0xFF, idx, base, scale);
}

// --- bits of doubles, 64-bit integers
inline __m512i _mm512_castpd_si512(__m512d a) {
  __m512i r;
  std::memcpy(r.q, a.v, 64);
  return r;
}
inline __m512d _mm512_castsi512_pd(__m512i a) {
  __m512d r;
  std::memcpy(r.v, a.q, 64);
  return r;
}
inline __m512i _mm512_setzero_si512() { return {}; }
inline __m512i _mm512_set1_epi64(long long a) {
  __m512i r;
  for (auto& x : r.q) x = a;
  return r;
}
inline __m512i _mm512_setr_epi64(long long a, long long b, long long c, long long d, long long e,
                                 long long f, long long g, long long h) {
  return {{a, b, c, d, e, f, g, h}};
}
inline __m512i _mm512_load_si512(const void* p) {
  __m512i r;
  std::memcpy(r.q, p, 64);
  return r;
}
inline __m512i _mm512_or_si512(__m512i a, __m512i b) {
  for (int l = 0; l < 8; ++l) a.q[l] |= b.q[l];
  return a;
}
inline __m512i _mm512_xor_si512(__m512i a, __m512i b) {
  for (int l = 0; l < 8; ++l) a.q[l] ^= b.q[l];
  return a;
}
inline __m512i _mm512_andnot_si512(__m512i a, __m512i b) {
  for (int l = 0; l < 8; ++l) a.q[l] = ~a.q[l] & b.q[l];
  return a;
}
inline __m512i _mm512_slli_epi64(__m512i a, unsigned n) {
  for (auto& x : a.q) x = static_cast<std::int64_t>(static_cast<std::uint64_t>(x) << n);
  return a;
}
inline __mmask8 _mm512_mask_test_epi64_mask(__mmask8 k, __m512i a, __m512i b) {
  unsigned m = 0;
  for (int l = 0; l < 8; ++l)
    if (bit(k, l) && (a.q[l] & b.q[l]) != 0) m |= 1u << l;
  return static_cast<__mmask8>(m);
}
inline __m512i _mm512_cvtepi32_epi64(__m256i a) {
  __m512i r;
  for (int l = 0; l < 8; ++l) r.q[l] = a.d[l];
  return r;
}

// --- 16 x 32-bit integers (rows_to_read)
inline __m512i _mm512_set1_epi32(int a) {
  __m512i r;
  for (int l = 0; l < 16; ++l) r.set_d(l, a);
  return r;
}
inline __m512i _mm512_maskz_loadu_epi32(__mmask16 k, const std::int32_t* p) {
  __m512i r{};
  for (int l = 0; l < 16; ++l)
    if (bit(k, l)) r.set_d(l, p[l]);
  return r;
}
inline __m512i _mm512_sub_epi32(__m512i a, __m512i b) {
  for (int l = 0; l < 16; ++l)
    a.set_d(l, static_cast<std::int32_t>(static_cast<std::uint32_t>(a.d(l)) -
                                         static_cast<std::uint32_t>(b.d(l))));
  return a;
}
#define DEM_EMUL_CMP32(name, op)                                   \
  inline __mmask16 name(__mmask16 k, __m512i a, __m512i b) {       \
    unsigned m = 0;                                                \
    for (int l = 0; l < 16; ++l)                                   \
      if (bit(k, l) && a.d(l) op b.d(l)) m |= 1u << l;             \
    return static_cast<__mmask16>(m);                              \
  }
DEM_EMUL_CMP32(_mm512_mask_cmplt_epi32_mask, <)
DEM_EMUL_CMP32(_mm512_mask_cmpneq_epi32_mask, !=)
DEM_EMUL_CMP32(_mm512_mask_cmpeq_epi32_mask, ==)
#undef DEM_EMUL_CMP32

// --- 8 x 32-bit integers
inline __m256i _mm256_setzero_si256() { return {}; }
inline __m256i _mm256_set1_epi32(int a) {
  __m256i r;
  for (auto& x : r.d) x = a;
  return r;
}
inline __m256i _mm256_setr_epi32(int a, int b, int c, int d, int e, int f, int g, int h) {
  return {{a, b, c, d, e, f, g, h}};
}
inline __m256i _mm256_add_epi32(__m256i a, __m256i b) {
  for (int l = 0; l < 8; ++l)
    a.d[l] = static_cast<std::int32_t>(static_cast<std::uint32_t>(a.d[l]) +
                                       static_cast<std::uint32_t>(b.d[l]));
  return a;
}
inline __m256i _mm256_sub_epi32(__m256i a, __m256i b) {
  for (int l = 0; l < 8; ++l)
    a.d[l] = static_cast<std::int32_t>(static_cast<std::uint32_t>(a.d[l]) -
                                       static_cast<std::uint32_t>(b.d[l]));
  return a;
}
inline __m256i _mm256_mask_sub_epi32(__m256i src, __mmask8 k, __m256i a, __m256i b) {
  const __m256i d = _mm256_sub_epi32(a, b);
  for (int l = 0; l < 8; ++l)
    if (bit(k, l)) src.d[l] = d.d[l];
  return src;
}
inline __m256i _mm256_min_epi32(__m256i a, __m256i b) {
  for (int l = 0; l < 8; ++l) a.d[l] = a.d[l] < b.d[l] ? a.d[l] : b.d[l];
  return a;
}
inline __m256i _mm256_permutexvar_epi32(__m256i idx, __m256i a) {
  __m256i r;
  for (int l = 0; l < 8; ++l) r.d[l] = a.d[idx.d[l] & 7];
  return r;
}
inline __mmask8 _mm256_cmpge_epi32_mask(__m256i a, __m256i b) {
  unsigned m = 0;
  for (int l = 0; l < 8; ++l)
    if (a.d[l] >= b.d[l]) m |= 1u << l;
  return static_cast<__mmask8>(m);
}
inline __mmask8 _mm256_mask_cmp_epi32_mask(__mmask8 k, __m256i a, __m256i b, int predicate) {
  if (predicate != _MM_CMPINT_NLT) std::abort();  // the only one the kernel uses
  unsigned m = 0;
  for (int l = 0; l < 8; ++l)
    if (bit(k, l) && !(a.d[l] < b.d[l])) m |= 1u << l;
  return static_cast<__mmask8>(m);
}
inline __m256i _mm256_maskz_loadu_epi32(__mmask8 k, const std::int32_t* p) {
  __m256i r{};
  for (int l = 0; l < 8; ++l)
    if (bit(k, l)) r.d[l] = p[l];
  return r;
}
inline __m256i _mm256_mask_loadu_epi32(__m256i src, __mmask8 k, const std::int32_t* p) {
  for (int l = 0; l < 8; ++l)
    if (bit(k, l)) src.d[l] = p[l];
  return src;
}
inline __m256i _mm256_load_si256(const __m256i* p) {
  __m256i r;
  std::memcpy(r.d, p, 32);
  return r;
}
inline void _mm256_store_si256(__m256i* p, __m256i a) { std::memcpy(p, a.d, 32); }
inline void _mm256_storeu_si256(__m256i* p, __m256i a) { std::memcpy(p, a.d, 32); }
inline __m256i _mm256_loadu_si256(const __m256i* p) {
  __m256i r;
  std::memcpy(r.d, p, 32);
  return r;
}
// The lanes of k moved to the low lanes in order, the rest zero.
inline __m256i _mm256_maskz_compress_epi32(__mmask8 k, __m256i a) {
  __m256i r{};
  int n = 0;
  for (int l = 0; l < 8; ++l)
    if (bit(k, l)) r.d[n++] = a.d[l];
  return r;
}
inline __m256i _mm256_mmask_i32gather_epi32(__m256i src, __mmask8 k, __m256i idx,
                                            const std::int32_t* base, int scale) {
  for (int l = 0; l < 8; ++l)
    if (bit(k, l))
      std::memcpy(&src.d[l], reinterpret_cast<const char*>(base) +
                                 static_cast<std::ptrdiff_t>(idx.d[l]) * scale, 4);
  return src;
}
inline void _mm_prefetch(const char*, int) {}

}  // namespace dem::detail::emulated
