// The machine's limits for the roofline of the DEM kernels (docs/performance.md, "Roofline"):
//  * memory bandwidth: the four STREAM kernels (McCalpin's copy a=b, scale a=q*b, add a=b+c,
//    triad a=b+q*c) over arrays far larger than the caches, counted as STREAM counts them
//    (bytes read + written, no write-allocate traffic), the best of --reps passes;
//  * the same kernels over arrays that fit in L2 (--cache-kib, default 256 KiB in all), the
//    bandwidth a kernel whose working set stays in cache can reach;
//  * the vector peak: FMA throughput with 16 independent accumulators (enough to cover the
//    FMA latency), AVX-512 where the processor has it, else AVX2+FMA, else scalar; a
//    floating-point operation is one multiply or one add (an FMA counts two).
// Each at 1 thread and at --threads (default 2), OpenMP static schedule, one array slice per
// thread first touched by its thread.
//
//   build/bin/machine_limits [--mib 128] [--cache-kib 256] [--reps 10] [--threads 2]
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

struct Arrays {
  double* a;
  double* b;
  double* c;
  std::size_t n;
};

// One pass of kernel k (0 copy, 1 scale, 2 add, 3 triad) over the arrays on T threads.
void pass(const Arrays& v, int k, int T) {
  double* __restrict a = v.a;
  const double* __restrict b = v.b;
  const double* __restrict c = v.c;
  const double q = 3.0;
  const std::size_t n = v.n;
#pragma omp parallel num_threads(T)
  {
    const int t = omp_get_thread_num();
    const std::size_t i0 = n * t / T, i1 = n * (t + 1) / T;
    switch (k) {
      case 0:
        for (std::size_t i = i0; i < i1; ++i) a[i] = b[i];
        break;
      case 1:
        for (std::size_t i = i0; i < i1; ++i) a[i] = q * b[i];
        break;
      case 2:
        for (std::size_t i = i0; i < i1; ++i) a[i] = b[i] + c[i];
        break;
      default:
        for (std::size_t i = i0; i < i1; ++i) a[i] = b[i] + q * c[i];
        break;
    }
  }
}

// Bytes a pass moves as STREAM counts them: copy and scale 2 arrays, add and triad 3.
double pass_bytes(int k, std::size_t n) { return (k < 2 ? 2.0 : 3.0) * 8.0 * static_cast<double>(n); }

// Best bandwidth [GB/s] per kernel over reps passes (the first pass is a warm-up).
std::vector<double> stream(std::size_t n, int T, int reps) {
  auto* a = static_cast<double*>(std::aligned_alloc(64, (n * 8 + 63) / 64 * 64));
  auto* b = static_cast<double*>(std::aligned_alloc(64, (n * 8 + 63) / 64 * 64));
  auto* c = static_cast<double*>(std::aligned_alloc(64, (n * 8 + 63) / 64 * 64));
  if (!a || !b || !c) {
    std::fprintf(stderr, "machine_limits: cannot allocate 3 x %zu doubles; use a smaller --mib\n", n);
    std::exit(1);
  }
#pragma omp parallel num_threads(T)
  {
    const int t = omp_get_thread_num();
    for (std::size_t i = n * t / T; i < n * (t + 1) / T; ++i) a[i] = 1.0, b[i] = 2.0, c[i] = 0.5;
  }
  const Arrays v{a, b, c, n};
  // Small arrays: repeat each pass so that one timing is at least ~1 ms.
  const int inner = static_cast<int>(std::max<std::size_t>(1, (1u << 20) / std::max<std::size_t>(n, 1)));
  std::vector<double> best(4, 0.0);
  for (int r = 0; r <= reps; ++r)
    for (int k = 0; k < 4; ++k) {
      const double t0 = now();
      for (int i = 0; i < inner; ++i) pass(v, k, T);
      const double dt = now() - t0;
      if (r > 0) best[k] = std::max(best[k], inner * pass_bytes(k, n) / dt * 1e-9);
    }
  double check = 0;
  for (std::size_t i = 0; i < n; i += 4096) check += a[i];
  if (check != check) std::fprintf(stderr, "machine_limits: NaN in the arrays\n");
  std::free(a);
  std::free(b);
  std::free(c);
  return best;
}

// FMA throughput of one thread [GFLOP/s]: 16 independent vector accumulators, iters rounds.
#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx512f"))) double fma_avx512(long iters) {
  __m512d acc[16];
  for (int j = 0; j < 16; ++j) acc[j] = _mm512_set1_pd(1.0 + 1e-3 * j);
  const __m512d m = _mm512_set1_pd(0.999999), p = _mm512_set1_pd(1e-7);
  for (long i = 0; i < iters; ++i)
    for (int j = 0; j < 16; ++j) acc[j] = _mm512_fmadd_pd(acc[j], m, p);
  __m512d s = acc[0];
  for (int j = 1; j < 16; ++j) s = _mm512_add_pd(s, acc[j]);
  double out[8];
  _mm512_storeu_pd(out, s);
  std::fprintf(stderr, "%s", out[0] == 12345.0 ? " " : "");  // keep the result live
  return 16.0 * 8 * 2 * static_cast<double>(iters);
}
__attribute__((target("avx2,fma"))) double fma_avx2(long iters) {
  __m256d acc[16];
  for (int j = 0; j < 16; ++j) acc[j] = _mm256_set1_pd(1.0 + 1e-3 * j);
  const __m256d m = _mm256_set1_pd(0.999999), p = _mm256_set1_pd(1e-7);
  for (long i = 0; i < iters; ++i)
    for (int j = 0; j < 16; ++j) acc[j] = _mm256_fmadd_pd(acc[j], m, p);
  __m256d s = acc[0];
  for (int j = 1; j < 16; ++j) s = _mm256_add_pd(s, acc[j]);
  double out[4];
  _mm256_storeu_pd(out, s);
  std::fprintf(stderr, "%s", out[0] == 12345.0 ? " " : "");
  return 16.0 * 4 * 2 * static_cast<double>(iters);
}
#endif
double fma_scalar(long iters) {
  double acc[16];
  for (int j = 0; j < 16; ++j) acc[j] = 1.0 + 1e-3 * j;
  for (long i = 0; i < iters; ++i)
    for (int j = 0; j < 16; ++j) acc[j] = acc[j] * 0.999999 + 1e-7;
  double s = 0;
  for (int j = 0; j < 16; ++j) s += acc[j];
  std::fprintf(stderr, "%s", s == 12345.0 ? " " : "");
  return 16.0 * 2 * static_cast<double>(iters);
}

const char* isa() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f")) return "avx512";
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "avx2";
#endif
  return "scalar";
}

double fma_flops(const std::string& which, long iters) {
#if defined(__x86_64__) && defined(__GNUC__)
  if (which == "avx512") return fma_avx512(iters);
  if (which == "avx2") return fma_avx2(iters);
#endif
  return fma_scalar(iters);
}

// Best GFLOP/s over reps, all T threads running the kernel at once (the sum of the threads).
double fma_peak(int T, int reps) {
  const std::string which = isa();
  // Short timings (about 1 ms each), many of them: on a shared machine the best is a slice
  // in which the thread ran alone.
  const long iters = 1'000'000;
  double best = 0;
  for (int r = 0; r <= reps; ++r) {
    double flops = 0;
    const double t0 = now();
#pragma omp parallel num_threads(T) reduction(+ : flops)
    flops += fma_flops(which, iters / 4);
    const double dt = now() - t0;
    if (r > 0) best = std::max(best, flops / dt * 1e-9);
  }
  return best;
}

long arg_long(int argc, char** argv, int& i, const char* name, long lo, long hi) {
  if (i + 1 >= argc) {
    std::fprintf(stderr, "machine_limits: %s needs a value\n", name);
    std::exit(2);
  }
  char* end = nullptr;
  const long v = std::strtol(argv[++i], &end, 10);
  if (*end != '\0' || v < lo || v > hi) {
    std::fprintf(stderr, "machine_limits: %s must be a whole number in [%ld, %ld] (got '%s')\n",
                 name, lo, hi, argv[i]);
    std::exit(2);
  }
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  long mib = 128, cache_kib = 256, reps = 10, threads = 2;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--mib")) mib = arg_long(argc, argv, i, "--mib", 16, 4096);
    else if (!std::strcmp(argv[i], "--cache-kib"))
      cache_kib = arg_long(argc, argv, i, "--cache-kib", 24, 65536);
    else if (!std::strcmp(argv[i], "--reps")) reps = arg_long(argc, argv, i, "--reps", 1, 1000);
    else if (!std::strcmp(argv[i], "--threads"))
      threads = arg_long(argc, argv, i, "--threads", 1, 256);
    else {
      std::fprintf(stderr,
                   "usage: machine_limits [--mib 128] [--cache-kib 256] [--reps 10] [--threads 2]\n"
                   "  --mib: each of the 3 memory arrays; --cache-kib: the 3 in-cache arrays together\n");
      return 2;
    }
  }
  const std::size_t n_mem = static_cast<std::size_t>(mib) * (1u << 20) / 8;
  const std::size_t n_cache = static_cast<std::size_t>(cache_kib) * 1024 / 24;
  std::printf("machine_limits: %s FMA; memory arrays 3 x %ld MiB, in-cache arrays 3 x %.0f KiB, best of %ld\n",
              isa(), mib, cache_kib / 3.0, reps);
  std::printf("| threads | what | copy | scale | add | triad | unit |\n|---|---|---:|---:|---:|---:|---|\n");
  std::vector<int> tlist{1};
  if (threads > 1) tlist.push_back(static_cast<int>(threads));
  for (int T : tlist) {
    for (int cache = 0; cache < 2; ++cache) {
      const auto bw = stream(cache ? n_cache : n_mem, T, static_cast<int>(reps));
      std::printf("| %d | %s | %.1f | %.1f | %.1f | %.1f | GB/s |\n", T, cache ? "in cache" : "memory",
                  bw[0], bw[1], bw[2], bw[3]);
    }
    std::printf("| %d | FMA peak | | | | %.1f | GFLOP/s |\n", T, fma_peak(T, static_cast<int>(20 * reps)));
  }
  return 0;
}
