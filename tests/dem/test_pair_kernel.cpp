// The pair forces' two implementations (dem/pair_kernel.hpp) give the same bits: forces,
// springs, the forces handed to later threads and the statistics, on rows built to reach every
// branch of contact_force (apart, ending inside the step's window, starting inside it, resting,
// coincident centres, springs with and without history, turned far out of the tangent plane,
// the Coulomb cap binding or not), rows of 0 to 21 candidates (the vector version's tails and
// second chunks), one size, two sizes and a continuum of sizes, and four contact laws. Whole runs
// through the engine are compared both ways as well.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <random>
#include <vector>

#include "dem/checkpoint.hpp"
#include "dem/contact_law.hpp"
#include "dem/pair_kernel.hpp"
#include "dem_test_util.hpp"

namespace {

using dem::Vec3;
using dem::detail::Kernel;
using dem::detail::PairRemote;
using dem::detail::PairRows;
using dem::detail::PairRowStats;

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
bool same_bits(Vec3 a, Vec3 b) {
  return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}

struct Rows {
  std::vector<Vec3> x, u, spring;
  std::vector<double> r, m;
  std::vector<std::int32_t> off, j;
};

Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  Vec3 v{g(rng), g(rng), g(rng)};
  return (1.0 / dem::norm(v)) * v;
}

// n particles; row i holds partners i+1..; every partner is placed relative to i by one of the
// cases of the header, so no geometry of a real bed is needed.
// sizes: 0 one radius, 1 two radii (the coefficient cache meets pairs of either kind), 2 uniform.
// rows: 0 rows of 0 to 21 candidates; 1 short rows (0 to 3); 2 mostly empty rows (70 % hold
// none, the others 1 or 2), so that 8 consecutive pairs span more than 8 rows.
Rows make_rows(std::mt19937_64& rng, int n, int sizes, double dt, int rows = 0) {
  Rows s;
  std::uniform_real_distribution<double> U01(0, 1);
  s.x.resize(n);
  s.u.resize(n);
  s.r.resize(n);
  s.m.resize(n);
  for (int i = 0; i < n; ++i) {
    s.r[i] = sizes == 2 ? 0.04 + 0.01 * U01(rng) : (sizes == 1 && U01(rng) < 0.5 ? 0.04 : 0.05);
    s.m[i] = 2600 * 4.18879 * s.r[i] * s.r[i] * s.r[i];
    s.x[i] = {U01(rng), U01(rng), U01(rng)};
    s.u[i] = {0.1 * (U01(rng) - 0.5), 0.1 * (U01(rng) - 0.5), 0.1 * (U01(rng) - 0.5)};
  }
  s.off.push_back(0);
  std::uniform_int_distribution<int> len(0, 21);
  for (int i = 0; i < n; ++i) {
    int want = len(rng);
    if (rows == 1) want %= 4;
    if (rows == 2) want = U01(rng) < 0.7 ? 0 : 1 + want % 2;
    want = std::min(want, n - 1 - i);
    // distinct partners above i, ascending (a row of the half list)
    std::vector<std::int32_t> row;
    for (int q = i + 1; q < n && static_cast<int>(row.size()) < want; ++q)
      if (U01(rng) < std::max(0.3, want / double(n - i))) row.push_back(q);
    for (const std::int32_t q : row) {
      s.j.push_back(q);
      const double rsum = s.r[i] + s.r[q];
      const Vec3 n1 = random_unit(rng);
      const int kind = static_cast<int>(U01(rng) * 8);
      double gap = 0;  // distance - rsum
      Vec3 urel = s.u[i] - s.u[q];
      switch (kind) {
        case 0:
          gap = 0.3 * rsum;
          break;  // far apart
        case 1:
          gap = -0.01 * rsum * U01(rng);
          break;  // resting contact
        case 2:
          gap = -0.05 * rsum * U01(rng);
          break;   // deep
        case 3: {  // ending or starting inside the window
          const double vn = 2.0 * (U01(rng) - 0.5);
          urel = urel + vn * n1;
          gap = (U01(rng) - 0.5) * dt * std::abs(vn);
          break;
        }
        case 4:
          gap = 1e-3 * dt * (U01(rng) - 0.5);
          break;   // grazing
        case 5: {  // fast approach, apart this step
          urel = urel + (-5.0) * n1;
          gap = 2.6 * dt;
          break;
        }
        case 6:
          gap = -rsum;
          break;  // coincident centres
        default:
          gap = -0.002 * rsum;
          break;
      }
      // x_i - x_q = (rsum + gap) n1, relative velocity u_i - u_q = urel.
      s.x[q] = s.x[i] - (rsum + gap) * n1;
      s.u[q] = s.u[i] - urel;
      // History: none, -0, tangential, far out of the tangent plane, along the normal (x = 1),
      // large (the cap binds).
      const int h = static_cast<int>(U01(rng) * 6);
      Vec3 sp{};
      const Vec3 t = dem::cross(n1, random_unit(rng));
      switch (h) {
        case 0:
          break;
        case 1:
          sp = {-0.0, 0.0, -0.0};
          break;
        case 2:
          sp = 1e-5 * t + 1e-9 * n1;
          break;
        case 3:
          sp = 1e-5 * t + 3e-6 * n1;
          break;
        case 4:
          sp = 1e-5 * n1;
          break;
        default:
          sp = 1e-2 * t;
          break;
      }
      s.spring.push_back(sp);
    }
    s.off.push_back(static_cast<std::int32_t>(s.j.size()));
  }
  return s;
}

struct Result {
  std::vector<Vec3> force, spring;
  std::vector<PairRemote> remote;
  PairRowStats stats;
};

// The kernels' view of `in`, writing springs and forces into `out` (springs copied from `in`,
// forces starting from a value with a -0 component).
PairRows start(const Rows& in, Result& out, const dem::ContactLaw& law, double dt) {
  out.spring = in.spring;
  out.force.assign(in.x.size(), Vec3{1.0, -0.0, 2.0});
  PairRows p;
  p.x = in.x.data();
  p.u = in.u.data();
  p.radius = in.r.data();
  p.mass = in.m.data();
  p.offset = in.off.data();
  p.partner = in.j.data();
  p.spring = out.spring.data();
  p.force = out.force.data();
  p.law = law;
  p.dt = dt;
  return p;
}

Result run(const Rows& in, const dem::ContactLaw& law, double dt, std::size_t a0, std::size_t a1,
           Kernel kernel, bool branch_free_chunks = dem::detail::branch_free_chunks_default(),
           bool screened = false, int queue_pairs = 256) {
  Result out;
  PairRows p = start(in, out, law, dt);
  p.branch_free_chunks = branch_free_chunks;
  p.screened = screened;
  p.queue_pairs = queue_pairs;
  dem::detail::pair_rows(p, a0, a1, out.remote, out.stats, kernel);
  return out;
}

// The chunk kernel's implementations held to the scalar loop's bits: its source with the lanes
// emulated in portable code everywhere, and the AVX-512 one where the processor has it. No
// test skips: without AVX-512 the emulated lanes still check the vector path.
// The AVX2 kernel (all awake; the scalar loop with sleepers) where the processor has AVX2.
std::vector<Kernel> chunk_kernels() {
  std::vector<Kernel> k{Kernel::emulated};
  if (dem::detail::pair_rows_vector_available()) k.push_back(Kernel::vector);
  if (dem::detail::pair_rows_avx2_available()) k.push_back(Kernel::avx2);
  return k;
}
const char* name(Kernel k) {
  return k == Kernel::vector     ? "vector"
         : k == Kernel::emulated ? "emulated"
         : k == Kernel::avx2     ? "avx2"
                                 : "scalar";
}

std::vector<dem::ContactLaw> laws() {
  std::vector<dem::ContactLaw> v;
  dem::ContactLaw a;  // the paper's: Pa, restitution, clipped
  a.normal_stiffness = 4e7;
  a.restitution = 0.3;
  a.tangential_stiffness_ratio = 0.5;
  a.friction = 0.6;
  dem::finalize(a, "a");
  v.push_back(a);
  dem::ContactLaw b = a;  // N/m, a damping coefficient, attraction allowed (LAMMPS-like)
  b.stiffness_per_length = false;
  b.normal_stiffness = 2e5;
  b.damping_from_restitution = false;
  b.normal_damping = 40;
  b.clip_attractive = false;
  b.tangential_stiffness_ratio = 2.0 / 7.0;
  dem::finalize(b, "b");
  v.push_back(b);
  dem::ContactLaw c = a;  // no tangential spring (k_T = 0): the cap resets to zero
  c.tangential_stiffness_ratio = 0;
  dem::finalize(c, "c");
  v.push_back(c);
  dem::ContactLaw d = a;  // frictionless
  d.friction = 0;
  dem::finalize(d, "d");
  v.push_back(d);
  return v;
}

TEST(dem_PairKernel, VectorAndScalarGiveTheSameBits) {
  const double dt = 1e-4;
  std::mt19937_64 rng(7);
  std::int64_t contacts = 0, rows_seen = 0, remotes = 0;
  for (const int sizes : {0, 1, 2}) {
    for (const dem::ContactLaw& law : laws()) {
      for (int rep = 0; rep < 6; ++rep) {
        // Long rows, short rows, mostly empty rows (the vector version takes 8 consecutive
        // pairs of any rows when all are awake).
        const Rows rows = make_rows(rng, 600, sizes, dt, rep % 3);
        // A thread's range in the middle: the partners beyond it go to the remote list.
        const std::size_t a0 = 40, a1 = 420;
        const Result s = run(rows, law, dt, a0, a1, Kernel::scalar);
        // The stream kernel's two ways with the spring's turn and the friction cap: every
        // chunk without a branch, or only the chunks that need them (the processor's default
        // is one of them).
        const bool branch_free = rep % 2 == 0;
        SCOPED_TRACE(branch_free ? "branch-free chunks" : "branching chunks");
        // The stream in one pass, or screened: the pairs past the screen queued and their
        // contact forces 8 at a time (PairRows::screened), with queues drained mid-row.
        for (const Kernel kernel : chunk_kernels())
        for (const bool screened : {false, true}) {
        SCOPED_TRACE(std::string(name(kernel)) + (screened ? ", screened" : ", one pass"));
        // The AVX2 kernel with its queue of 256 pairs, and (screened) of 8, shorter than some
        // rows (those run through the scalar loop alone) and ending mid-row.
        const Result v = run(rows, law, dt, a0, a1, kernel, branch_free, screened,
                             kernel == Kernel::avx2 && screened ? 8 : 256);
        for (std::size_t i = 0; i < rows.x.size(); ++i)
          ASSERT_TRUE(same_bits(s.force[i], v.force[i]))
              << "force of particle " << i << " (sizes " << sizes << ")";
        for (std::size_t k = 0; k < rows.spring.size(); ++k)
          ASSERT_TRUE(same_bits(s.spring[k], v.spring[k])) << "spring of pair " << k;
        ASSERT_EQ(s.remote.size(), v.remote.size());
        for (std::size_t q = 0; q < s.remote.size(); ++q) {
          ASSERT_EQ(s.remote[q].j, v.remote[q].j);
          ASSERT_TRUE(same_bits(s.remote[q].f, v.remote[q].f));
        }
        ASSERT_EQ(s.stats.contacts, v.stats.contacts);
        ASSERT_TRUE(same_bits(s.stats.max_overlap, v.stats.max_overlap));
        ASSERT_TRUE(same_bits(s.stats.max_overlap_ratio, v.stats.max_overlap_ratio));
        }
        contacts += s.stats.contacts;
        remotes += static_cast<std::int64_t>(s.remote.size());
        rows_seen += static_cast<std::int64_t>(a1 - a0);
        // Something happened: springs changed, forces were applied.
        int changed = 0;
        for (std::size_t k = 0; k < rows.spring.size(); ++k)
          changed += !same_bits(rows.spring[k], s.spring[k]);
        EXPECT_GT(changed, static_cast<int>(rows.spring.size() / 10));
      }
    }
  }
  EXPECT_GT(contacts, 10000);
  EXPECT_GT(remotes, 300);
  EXPECT_GT(rows_seen, 0);
}

// The same with sleepers: a third of the particles asleep, the rows of some sleepers counted as
// holding an awake partner (read), or the true counts with sleepers in blocks (runs of awake
// rows with only awake partners streamed), over a range that starts and ends inside a 64-row word,
// with the rows that have sleeping rules computed a chunk per row or queued (their pairs past the
// screen run 8 at a time across rows, the queue drained mid-row and before each streamed run);
// forces, springs, the forces handed on, the statistics and the set of sleepers to wake
// agree bit for bit.
TEST(dem_PairKernel, WithSleepersVectorAndScalarGiveTheSameBits) {
  const double dt = 1e-4;
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> U01(0, 1);
  std::int64_t wakes = 0, contacts = 0, streamed_runs = 0;
  for (const int sizes : {0, 1, 2}) {
    for (const dem::ContactLaw& law : laws()) {
      // counts: 0 none (every row read), 1 made up (some sleepers' rows read), 2 the true
      // counts with the sleepers in blocks, so that runs of awake rows with only awake partners
      // go to the stream kernel (with both ways of its chunks).
      for (const int counts : {0, 1, 2}) {
        const Rows rows = make_rows(rng, 600, sizes, dt);
        const std::size_t n = rows.x.size(), a0 = 40, a1 = 420;
        std::vector<std::int32_t> rest(n), awake_partners(n);
        for (std::size_t i = 0; i < n; ++i) {
          const bool asleep = counts == 2 ? (i / 50) % 3 == 1 : U01(rng) < 0.35;
          rest[i] = asleep ? 200 : static_cast<std::int32_t>(U01(rng) * 150);
          awake_partners[i] = U01(rng) < 0.5 ? 1 + static_cast<std::int32_t>(U01(rng) * 3) : 0;
        }
        if (counts == 2) {
          std::size_t run = 0;
          for (std::size_t i = 0; i < n; ++i) {
            awake_partners[i] = 0;
            for (std::int32_t k = rows.off[i]; k < rows.off[i + 1]; ++k)
              awake_partners[i] += rest[static_cast<std::size_t>(rows.j[k])] < 200;
            const bool clean = rest[i] < 200 && awake_partners[i] == rows.off[i + 1] - rows.off[i];
            run = clean ? run + 1 : 0;
            if (run == 16 && i >= a0 + 15 && i < a1) ++streamed_runs;
          }
        }
        // The scalar loop, then each chunk kernel with its clean runs streamed in one pass or
        // screened.
        // The rows with sleeping rules a chunk per row or queued (PairRows::queued_rows).
        std::vector<Kernel> kernels{Kernel::scalar};
        std::vector<bool> screened{false}, queued{false};
        for (const Kernel k : chunk_kernels())
          for (const int variant : {0, 1, 2}) {
            kernels.push_back(k);
            screened.push_back(variant == 2);
            queued.push_back(variant > 0);
          }
        std::vector<Result> res(kernels.size());
        std::vector<std::vector<std::uint8_t>> woken(kernels.size());
        for (std::size_t q = 0; q < kernels.size(); ++q) {
          Result& out = res[q];
          PairRows p = start(rows, out, law, dt);
          p.branch_free_chunks = sizes % 2 == 0;
          p.screened = screened[q];
          p.queued_rows = queued[q];
          // The AVX2 kernel (screened: no meaning to it) with a queue of 8 pairs, shorter than
          // some rows.
          p.queue_pairs = kernels[q] == Kernel::avx2 && screened[q] ? 8 : 256;
          woken[q].assign(n, 0);
          std::vector<std::int32_t> remote_wake;
          dem::detail::PairSleep sl;
          sl.rest = rest.data();
          sl.steps = 200;
          sl.wake_speed2 = 0.03 * 0.03;
          sl.awake_partners = counts ? awake_partners.data() : nullptr;
          sl.wake = woken[q].data();
          sl.remote_wake = &remote_wake;
          dem::detail::pair_rows_sleep(p, sl, a0, a1, out.remote, out.stats, kernels[q]);
          for (const std::int32_t r : remote_wake) woken[q][r] = 1;
        }
        for (std::size_t v = 1; v < kernels.size(); ++v) {
        SCOPED_TRACE(std::string(name(kernels[v])) + (screened[v] ? ", screened" : ", one pass") +
                     (queued[v] ? ", rows queued" : ", a chunk per row"));
        for (std::size_t i = 0; i < n; ++i) {
          ASSERT_TRUE(same_bits(res[0].force[i], res[v].force[i])) << "force of particle " << i;
          ASSERT_EQ(woken[0][i], woken[v][i]) << "wake of particle " << i;
          if (v == 1) wakes += woken[0][i];
        }
        for (std::size_t k = 0; k < rows.spring.size(); ++k)
          ASSERT_TRUE(same_bits(res[0].spring[k], res[v].spring[k])) << "spring of pair " << k;
        ASSERT_EQ(res[0].remote.size(), res[v].remote.size());
        for (std::size_t q = 0; q < res[0].remote.size(); ++q) {
          ASSERT_EQ(res[0].remote[q].j, res[v].remote[q].j);
          ASSERT_TRUE(same_bits(res[0].remote[q].f, res[v].remote[q].f));
        }
        ASSERT_EQ(res[0].stats.contacts, res[v].stats.contacts);
        ASSERT_TRUE(same_bits(res[0].stats.max_overlap, res[v].stats.max_overlap));
        ASSERT_TRUE(same_bits(res[0].stats.max_overlap_ratio, res[v].stats.max_overlap_ratio));
        }
        contacts += res[0].stats.contacts;
      }
    }
  }
  EXPECT_GT(wakes, 100);
  EXPECT_GT(contacts, 5000);
  EXPECT_GT(streamed_runs, 12) << "too few runs of 16 clean rows: the stream is not exercised";
  std::printf("runs of 16 or more clean rows (streamed): %lld\n", static_cast<long long>(streamed_runs));
}

// A bed settling under gravity with walls, polydisperse, through the engine on 1 and 2 threads:
// every array of State after the run is the same with the scalar loop, the emulated chunk kernel
// (any processor) and the AVX-512 one (where the processor has it).
TEST(dem_PairKernel, WholeRunsAreTheSameWithEitherKernel) {
  using PK = dem::EngineOptions::PairKernel;
  // The scalar loop; the chunk kernel's stream in one pass or screened (EngineOptions::
  // pair_passes), emulated everywhere and on AVX-512 where the processor has it; the last
  // variant goes through a checkpoint and a new engine halfway.
  std::vector<PK> kernels{PK::scalar, PK::emulated, PK::emulated};
  std::vector<bool> screened{false, false, true};
  if (dem::detail::pair_rows_vector_available()) {
    kernels.insert(kernels.end(), {PK::vector, PK::vector, PK::vector});
    screened.insert(screened.end(), {false, true, true});
  }
  if (dem::detail::pair_rows_avx2_available()) {  // (screened: no meaning to it; a checkpoint)
    kernels.insert(kernels.end(), {PK::avx2, PK::avx2});
    screened.insert(screened.end(), {false, true});
  }
  for (const int threads : {1, 2}) {
    std::vector<dem::State> result(kernels.size());
    for (std::size_t q = 0; q < kernels.size(); ++q) {
      dem::EngineOptions options;
      options.pair_kernel = kernels[q];
      options.pair_passes = screened[q] ? dem::EngineOptions::PairPasses::two
                                        : dem::EngineOptions::PairPasses::one;
      const bool through_checkpoint = q + 1 == kernels.size();
      dem::Scene scene = demtest::one_species_scene(0.8e-3, 1.2e-3);
      scene.threads = threads;
      scene.broad_phase_interval = 10;
      scene.gravity = {0, 0, -9.81};
      scene.particle_particle = scene.particle_wall = demtest::law_n_per_m(500, 0.3, true, 0.5);
      scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
      scene.walls.push_back({"x0", {0, 0, 0}, {1, 0, 0}});
      scene.walls.push_back({"x1", {0.03, 0, 0}, {-1, 0, 0}});
      scene.dt = 2e-5;
      dem::State st;
      std::mt19937_64 rng(11);
      std::uniform_real_distribution<double> U01(0, 1);
      for (int k = 0; k < 1500; ++k) {
        const double r = 0.8e-3 + 0.4e-3 * U01(rng);
        demtest::add(
            st, {1.5e-3 + 2.5e-3 * (k % 11), 2.5e-3 * ((k / 11) % 11), 1.5e-3 + 2.5e-3 * (k / 121)},
            {0.05 * (U01(rng) - 0.5), 0.05 * (U01(rng) - 0.5), -0.2}, r);
      }
      auto engine = std::make_unique<dem::Engine>(scene, options);
      for (int k = 0; k < 1500; ++k) {
        if (through_checkpoint && k == 750) {
          const std::string file = (std::filesystem::temp_directory_path() /
                                    ("dem_pair_kernel_" + std::to_string(::getpid()) + ".h5"))
                                       .string();
          dem::save_checkpoint(st, file);
          st = dem::load_checkpoint(file);
          std::filesystem::remove(file);
          engine = std::make_unique<dem::Engine>(scene, options);
        }
        engine->step(st);
      }
      EXPECT_GT(engine->contact_stats().particle_contacts, 200);
      result[q] = st;
    }
    for (std::size_t v = 1; v < kernels.size(); ++v) {
    int arrays = 0;
    dem::for_each_array(result[0], [&](const char* name, const auto& a, dem::Field) {
      const char* other = nullptr;
      std::size_t bytes = 0;
      dem::for_each_array(result[v], [&](const char* n2, const auto& b, dem::Field) {
        if (std::strcmp(name, n2) == 0) {
          other = reinterpret_cast<const char*>(b.data());
          bytes = b.size() * sizeof(b[0]);
        }
      });
      ASSERT_EQ(bytes, a.size() * sizeof(a[0])) << name;
      EXPECT_TRUE(bytes == 0 || std::memcmp(a.data(), other, bytes) == 0)
          << name << " differs on " << threads << " threads, kernel " << static_cast<int>(kernels[v])
          << (screened[v] ? " screened" : " one pass");
      ++arrays;
    });
    EXPECT_GT(arrays, 20);
    }
  }
}

// Runs `cmd` with stdout and stderr to a file; returns the exit status and the output.
std::pair<int, std::string> run_command(const std::string& cmd) {
  const std::filesystem::path log = std::filesystem::temp_directory_path() /
                                    ("dem_pair_kernel_" + std::to_string(::getpid()) + ".log");
  const int status = std::system((cmd + " > " + log.string() + " 2>&1").c_str());
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  std::filesystem::remove(log);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ss.str()};
}

// DEM_PAIR_KERNEL picks the kernel for timing; any other value than vector, avx2 or scalar stops
// dem_run and dem_service at start-up with a message naming the variable and its values.
TEST(dem_PairKernel, BadKernelInTheEnvironmentIsRefusedAtStartUp) {
  const std::string config = std::string(DEM_SOURCE_DIR) + "/configs/dem/drop_on_meshes.yaml";
  const std::string out =
      (std::filesystem::temp_directory_path() / ("dem_pair_kernel_" + std::to_string(::getpid()) +
                                                 ".h5"))
          .string();
  for (const char* exe : {DEM_RUN_EXE, DEM_SERVICE_EXE}) {
    const std::string args = std::string(exe) == DEM_RUN_EXE
                                 ? config + " --set run.duration=0.001 --output " + out
                                 : std::string(DEM_SOURCE_DIR) +
                                       "/configs/soil/pile.yaml --name soil --bus "
                                       "udpm://239.255.76.67:7667?ttl=0";
    const auto [code, text] = run_command("env DEM_PAIR_KERNEL=avx " + std::string(exe) + " " + args);
    EXPECT_EQ(code, 2) << text;
    EXPECT_NE(text.find("DEM_PAIR_KERNEL=avx: use vector (the default), avx2 or scalar, or unset it"),
              std::string::npos)
        << text;
  }
  // DEM_PAIR_CHUNKS likewise (branch-free or branching).
  {
    const auto [code, text] = run_command("env DEM_PAIR_CHUNKS=fast " + std::string(DEM_RUN_EXE) +
                                          " " + config + " --set run.duration=0.001 --output " +
                                          out);
    EXPECT_EQ(code, 2) << text;
    EXPECT_NE(text.find("DEM_PAIR_CHUNKS=fast: use branch-free or branching, or unset it"),
              std::string::npos)
        << text;
  }
  for (const char* v : {"branch-free", "branching"}) {
    const auto [code, text] = run_command(std::string("env DEM_PAIR_CHUNKS=") + v + " " +
                                          DEM_RUN_EXE + " " + config +
                                          " --set run.duration=0.001 --output " + out);
    EXPECT_EQ(code, 0) << v << ": " << text;
  }
  // DEM_PAIR_PASSES likewise (auto, one or two).
  {
    const auto [code, text] = run_command("env DEM_PAIR_PASSES=three " + std::string(DEM_RUN_EXE) +
                                          " " + config + " --set run.duration=0.001 --output " +
                                          out);
    EXPECT_EQ(code, 2) << text;
    EXPECT_NE(text.find("DEM_PAIR_PASSES=three: use auto (the default: two passes for scenes of "
                        "up to 50000 particles), one or two, or unset it"),
              std::string::npos)
        << text;
  }
  for (const char* v : {"auto", "one", "two"}) {
    const auto [code, text] = run_command(std::string("env DEM_PAIR_PASSES=") + v + " " +
                                          DEM_RUN_EXE + " " + config +
                                          " --set run.duration=0.001 --output " + out);
    EXPECT_EQ(code, 0) << v << ": " << text;
  }
  // DEM_ROW_TEST (the broad phase's distance test) and DEM_TRIANGLE_TEST (the boundary
  // contacts' triangle test) likewise: vector or scalar.
  struct Switch {
    const char* set;       // a bad setting
    const char* message;   // what it must say
  };
  for (const Switch& sw :
       {Switch{"DEM_ROW_TEST=avx", "DEM_ROW_TEST=avx: use vector (the default: AVX-512, else "
                                   "AVX2, where the processor has it) or scalar, or unset it"},
        Switch{"DEM_TRIANGLE_TEST=4",
               "DEM_TRIANGLE_TEST=4: use vector (the default: 4 triangles at a time with AVX2 "
               "where the processor has it) or scalar, or unset it"}}) {
    const auto [code, text] = run_command(std::string("env ") + sw.set + " " + DEM_RUN_EXE + " " +
                                          config + " --set run.duration=0.001 --output " + out);
    EXPECT_EQ(code, 2) << text;
    EXPECT_NE(text.find(sw.message), std::string::npos) << text;
    const std::string name = std::string(sw.set).substr(0, std::string(sw.set).find('='));
    for (const char* v : {"vector", "scalar"}) {
      const auto [ok, said] = run_command("env " + name + "=" + v + " " + DEM_RUN_EXE + " " +
                                          config + " --set run.duration=0.001 --output " + out);
      EXPECT_EQ(ok, 0) << name << "=" << v << ": " << said;
    }
  }
  // The good values run.
  for (const char* v : {"scalar", "vector", "avx2"}) {
    const auto [code, text] = run_command(std::string("env DEM_PAIR_KERNEL=") + v + " " +
                                          DEM_RUN_EXE + " " + config +
                                          " --set run.duration=0.001 --output " + out);
    EXPECT_EQ(code, 0) << v << ": " << text;
  }
  std::filesystem::remove(out);
  std::filesystem::remove(std::filesystem::path(out).replace_extension(".xdmf"));
}

}  // namespace
