// Two versions of the pair forces (dem_service/src/pair_kernel.cpp at two revisions) timed
// alternately in one process on the rows of a checkpoint: the A/B that this VM's drifting speed
// leaves possible (docs/performance.md, "Full chunks, and the contact window in the bound").
// Built and run by bench/dem/kernel_ab.sh, which passes the two sources as KERNEL_A and
// KERNEL_B; each is compiled into its own namespace. Not a test.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include "dem/checkpoint.hpp"
#include "dem/contact_law.hpp"
#include "dem/pair_kernel.hpp"
#include "dem/state.hpp"
#include "cosim/yaml_config.hpp"

// Each version sees the project's types through using-directives of its own namespace.
namespace version_a::dem::detail {
using namespace ::dem;
using namespace ::dem::detail;
}  // namespace version_a::dem::detail
namespace version_b::dem::detail {
using namespace ::dem;
using namespace ::dem::detail;
}  // namespace version_b::dem::detail
namespace version_a {
#include KERNEL_A
}
namespace version_b {
#include KERNEL_B
}

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5 && argc != 6) {
    std::fprintf(stderr, "usage: kernel_ab CONFIG CHECKPOINT PASSES THREADS [CLOSE_MARGIN_M]\n");
    return 2;
  }
  const std::string config = argv[1], checkpoint = argv[2];
  const int passes = std::atoi(argv[3]), threads = std::atoi(argv[4]);
  // With a margin, B reads the close pairs (the candidates within the margin of contact, as the
  // engine lists them for performance.close_margin) instead of every candidate.
  const double close_margin = argc == 6 ? std::atof(argv[5]) : 0.0;
  if (argc == 6 && !(close_margin > 0)) {
    std::fprintf(stderr, "kernel_ab: CLOSE_MARGIN_M must be > 0 (metres)\n");
    return 2;
  }
  if (passes < 3 || threads < 1 || threads > 2) {
    std::fprintf(stderr, "kernel_ab: PASSES must be >= 3 and THREADS 1 or 2\n");
    return 2;
  }
  // Only the particle-particle law and dt of the scene config are used.
  dem::ContactLaw law;
  double dt = 0;
  dem::State s;
  try {
    const YAML::Node root = cosim::config::load_file(config);
    law = dem::parse_contact_law(root["contact"]["particle_particle"], "contact.particle_particle");
    dt = cosim::config::get_positive(root["scene"], "scene", "dt");
    s = dem::load_checkpoint(checkpoint);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kernel_ab: %s\n", e.what());
    return 2;
  }
  const std::size_t n = s.size();
  if (s.pair_offset.size() != n + 1 || s.pair_spring.size() != s.pair_j.size() ||
      s.pair_work.size() != n + 1 || s.pair_j.empty()) {
    std::fprintf(stderr, "kernel_ab: %s holds no pair lists (a checkpoint written after a run "
                 "step has them, e.g. dem_run's output.checkpoint)\n", checkpoint.c_str());
    return 2;
  }
  // The split of the engine: equal work (State::pair_work).
  std::vector<std::size_t> bounds{0};
  for (int t = 1; t < threads; ++t)
    bounds.push_back(static_cast<std::size_t>(
        std::lower_bound(s.pair_work.begin(), s.pair_work.end(), s.pair_work[n] * t / threads) -
        s.pair_work.begin()));
  bounds.push_back(n);
  std::vector<dem::Vec3> force(n);
  const std::vector<dem::Vec3> springs = s.pair_spring;
  dem::detail::PairRows p;
  p.x = s.x.data();
  p.u = s.u.data();
  p.radius = s.radius.data();
  p.mass = s.mass.data();
  p.offset = s.pair_offset.data();
  p.partner = s.pair_j.data();
  p.force = force.data();
  p.law = law;
  p.dt = dt;
  // The close pairs of the checkpoint (every particle slow: the gap alone decides).
  std::vector<std::int32_t> close_offset{0}, close_j, close_index;
  std::vector<dem::Vec3> close_springs = springs;  // the left-out pairs' cleared, as listed
  std::vector<dem::Vec3> close_copy;               // the close pairs' springs in their order
  if (close_margin > 0) {
    for (std::size_t i = 0; i < n; ++i) {
      for (std::int32_t k = s.pair_offset[i]; k < s.pair_offset[i + 1]; ++k) {
        const std::int32_t j = s.pair_j[k];
        const double reach = s.radius[i] + s.radius[j] + close_margin;
        if (dem::norm2(s.x[i] - s.x[j]) < reach * reach) {
          close_j.push_back(j);
          close_index.push_back(k);
        } else if (dem::nonzero(close_springs[k])) {
          close_springs[k] = dem::Vec3{};
        }
      }
      close_offset.push_back(static_cast<std::int32_t>(close_j.size()));
    }
    std::printf("close pairs within %g m: %zu of %zu candidates (%.1f %%)\n", close_margin,
                close_j.size(), s.pair_j.size(), 100.0 * close_j.size() / s.pair_j.size());
  }
  std::vector<double> ms[2];
  std::vector<dem::Vec3> result[2];
  int b_faster = 0;
  std::vector<dem::Vec3> spring_after;
  bool springs_same = false;
  for (int pass = 0; pass < passes; ++pass) {
    for (int v = 0; v < 2; ++v) {
      s.pair_spring = v == 1 && close_margin > 0 ? close_springs : springs;  // the same every pass
      p.spring = s.pair_spring.data();
      p.offset = s.pair_offset.data();
      p.partner = s.pair_j.data();
      p.spring_index = nullptr;
      p.spring_home = nullptr;
      if (v == 1 && close_margin > 0) {
        p.offset = close_offset.data();
        p.partner = close_j.data();
        p.spring_index = close_index.data();
        p.spring_home = s.pair_spring.data();
        close_copy.resize(close_index.size());
        for (std::size_t q = 0; q < close_index.size(); ++q)
          close_copy[q] = close_springs[close_index[q]];
        p.spring = close_copy.data();
      }
      std::fill(force.begin(), force.end(), dem::Vec3{});
      const auto t0 = std::chrono::steady_clock::now();
#pragma omp parallel num_threads(threads)
      {
        const int t = omp_get_thread_num();
        std::vector<dem::detail::PairRemote> remote;
        dem::detail::PairRowStats st;
        if (v == 0)
          version_a::dem::detail::pair_rows(p, bounds[t], bounds[t + 1], remote, st,
                                            ::dem::detail::Kernel::vector);
        else
          version_b::dem::detail::pair_rows(p, bounds[t], bounds[t + 1], remote, st,
                                            ::dem::detail::Kernel::vector);
      }
      ms[v].push_back(
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() * 1e3);
      if (pass == 0) {
        result[v] = force;
        // The springs of the pairs the close list left out are cleared by its listing (they
        // are out of contact); the rest must match.
        if (v == 0) spring_after = s.pair_spring;
        if (v == 1)
          springs_same = std::memcmp(s.pair_spring.data(), spring_after.data(),
                                     spring_after.size() * sizeof(dem::Vec3)) == 0;
      }
    }
    b_faster += ms[1].back() < ms[0].back();
  }
  const bool same = std::memcmp(result[0].data(), result[1].data(),
                                n * sizeof(dem::Vec3)) == 0;
  std::printf("%zu particles, %zu pairs, %d thread(s), %d alternating passes\n", n,
              s.pair_j.size(), threads, passes);
  std::printf("A: median %.3f ms (%.2f ns per pair)\n", median(ms[0]),
              median(ms[0]) * 1e6 / static_cast<double>(s.pair_j.size()));
  std::printf("B: median %.3f ms (%.2f ns per pair)\n", median(ms[1]),
              median(ms[1]) * 1e6 / static_cast<double>(s.pair_j.size()));
  std::printf("B/A %.3f, B faster in %d of %d passes; forces of the first pass %s, springs %s\n",
              median(ms[1]) / median(ms[0]), b_faster, passes,
              same ? "identical" : "DIFFER", springs_same ? "identical" : "DIFFER");
  return 0;
}
