/* omp_count: counts the OpenMP parallel regions a process enters and the barriers its threads
 * meet, by wrapping libgomp's entry points (LD_PRELOAD). A bench tool, not part of the product:
 *
 *   LD_PRELOAD=build/lib/libomp_count.so build/bin/step_counts CONFIG ...
 *
 * step_counts reads the counters between its steps (omp_count_read, found with dlsym) and prints
 * the regions and barriers per DEM step; any other program gets the totals on stderr at exit.
 * Counted: GOMP_parallel (every `#pragma omp parallel`, `parallel for`; GCC's entry since 4.9),
 * GOMP_barrier (every explicit barrier and the implicit one of a `for` or `single` without
 * nowait, once per thread that meets it), GOMP_single_start (once per thread). The region's own
 * closing barrier is inside GOMP_parallel and not counted as a barrier.
 * docs/performance.md, "One parallel region per DEM step". */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>

static long g_regions, g_barriers, g_singles;

typedef void (*parallel_fn)(void (*)(void*), void*, unsigned, unsigned);
typedef void (*void_fn)(void);
typedef int (*single_fn)(void);

static void* next_symbol(const char* name) {
  void* p = dlsym(RTLD_NEXT, name);
  if (!p) {
    fprintf(stderr, "omp_count: %s not found in the libraries after this one (%s)\n", name,
            dlerror());
    abort();
  }
  return p;
}

void GOMP_parallel(void (*fn)(void*), void* data, unsigned num_threads, unsigned flags) {
  static parallel_fn real;
  if (!real) real = (parallel_fn)next_symbol("GOMP_parallel");
  __atomic_fetch_add(&g_regions, 1, __ATOMIC_RELAXED);
  real(fn, data, num_threads, flags);
}

void GOMP_barrier(void) {
  static void_fn real;
  if (!real) real = (void_fn)next_symbol("GOMP_barrier");
  __atomic_fetch_add(&g_barriers, 1, __ATOMIC_RELAXED);
  real();
}

int GOMP_single_start(void) {
  static single_fn real;
  if (!real) real = (single_fn)next_symbol("GOMP_single_start");
  __atomic_fetch_add(&g_singles, 1, __ATOMIC_RELAXED);
  return real();
}

/* The counters so far (for a program that reads them between its steps). */
void omp_count_read(long* regions, long* barriers, long* singles) {
  *regions = __atomic_load_n(&g_regions, __ATOMIC_RELAXED);
  *barriers = __atomic_load_n(&g_barriers, __ATOMIC_RELAXED);
  *singles = __atomic_load_n(&g_singles, __ATOMIC_RELAXED);
}

__attribute__((destructor)) static void report(void) {
  fprintf(stderr, "omp_count: %ld parallel regions, %ld barrier calls, %ld single calls\n",
          g_regions, g_barriers, g_singles);
}
