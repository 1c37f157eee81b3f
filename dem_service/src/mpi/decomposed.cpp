#include "dem/mpi/decomposed.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include <time.h>

#include "cosim/yaml_config.hpp"
#include "dem/broad_phase.hpp"
#include "dem/far_movers.hpp"
#include "dem/rotation.hpp"
#include "dem/sleepers.hpp"

namespace dem::mpi {

namespace cfg = cosim::config;

// --- Options, launch, session.

Options take_options(YAML::Node& root) {
  Options o;
  if (!root.IsMap() || !root["mpi"]) return o;
  const YAML::Node node = root["mpi"];
  cfg::check_keys(node, "mpi", {"decomposition", "rebalance"});
  const std::string d = node["decomposition"] ? node["decomposition"].as<std::string>("") : "slabs";
  if (d == "grid")
    throw cfg::ConfigError(
        "mpi.decomposition: 'grid' is not supported yet (only slabs: cuts along the longest axis "
        "of the particles); set mpi.decomposition: slabs");
  if (d != "slabs")
    throw cfg::ConfigError("mpi.decomposition: unknown decomposition '" + d +
                           "' (allowed: slabs); set mpi.decomposition: slabs");
  o.decomposition = d;
  o.rebalance = cfg::get_double_or(node, "mpi", "rebalance", o.rebalance);
  if (!(o.rebalance >= 1.0) || !std::isfinite(o.rebalance))
    throw cfg::ConfigError("mpi.rebalance: " + std::to_string(o.rebalance) +
                           " is below 1 (the largest rank's particle count over the mean, which "
                           "is at least 1); use e.g. 1.2");
  root.remove("mpi");
  return o;
}

bool launched_by_mpirun() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS"})
    if (std::getenv(v)) return true;
  return false;
}

int launched_ranks() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"})
    if (const char* s = std::getenv(v)) return std::max(1, std::atoi(s));
  return 1;
}

Session::Session(int* argc, char*** argv) {
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Session::~Session() { MPI_Finalize(); }

void Session::abort(int code) {
  MPI_Abort(MPI_COMM_WORLD, code);
  std::exit(code);
}

int Session::max_over_ranks(int code) {
  int out = code;
  MPI_Allreduce(&code, &out, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  return out;
}

void check_supported(const RunConfig& rc, const EngineOptions& options, int ranks) {
  if (ranks <= 1) return;
  const std::string n = std::to_string(ranks) + " ranks";
  auto refuse = [&](const std::string& what) {
    throw std::invalid_argument("mpi: " + what + " (docs/mpi.md lists what runs on several ranks)");
  };
  const Scene& sc = rc.scene;
  if (sc.sleep.enabled)
    refuse("scene.sleep is not supported on " + n +
           ": a sleeper's rest and wake tests read its neighbours' state, which a rank boundary "
           "splits; set scene.sleep.enabled: false or run on one rank");
  if (sc.region.enabled)
    refuse("scene.region is not supported on " + n +
           ": removing particles would change the ranks' counts between broad phases; disable "
           "scene.region or run on one rank");
  if (options.close_margin > 0)
    refuse("performance.close_margin is not supported on " + n +
           ": close pairs are re-listed by each rank's own tally, which the ghosts' copies do not "
           "keep; set performance.close_margin: 0 or run on one rank");
  if (rc.prepare.enabled)
    refuse("prepare: (deposition and freeze) is not supported on " + n +
           ": prepare the bed on one rank (dem_run without mpirun) and start from its checkpoint");
  if (rc.settle.enabled)
    refuse("settle: is not supported on " + n +
           ": settle the bed on one rank (dem_run without mpirun) and start from its checkpoint "
           "(particles.checkpoint)");
}

// --- Wire formats.

namespace {

constexpr int B = kBoundarySlots;
constexpr int kTagGhost = 11;

// A ghost's or a gathered particle's data, also what migration sends first.
struct Core {
  Vec3 x, v, u, w, wu;
  double radius, mass;
  std::int64_t id;
  std::int32_t species;
  std::int32_t nslot;  // migration: boundary slots that follow
  std::int32_t nrec;   // migration: pair records that follow
  std::int32_t pad = 0;
};
static_assert(std::is_trivially_copyable_v<Core>);
struct Slot {
  std::uint64_t key;
  Vec3 spring, roll;
};
struct Record {  // one touching pair as its particle feels it
  std::int64_t partner;
  Vec3 spring, roll;
};

struct Writer {
  std::vector<char> buf;
  template <class T>
  void put(const T& v) {
    const std::size_t o = buf.size();
    buf.resize(o + sizeof(T));
    std::memcpy(buf.data() + o, &v, sizeof(T));
  }
};
struct Reader {
  const char* p;
  const char* end;
  template <class T>
  T get() {
    if (p + sizeof(T) > end) throw std::logic_error("dem::mpi: truncated message");
    T v;
    std::memcpy(&v, p, sizeof(T));
    p += sizeof(T);
    return v;
  }
};

// Particles with their boundary slots and pair records (owned), or without (ghosts, gathers).
struct Particles {
  std::vector<Core> core;
  std::vector<std::int32_t> slot_offset{0};  // CSR: each particle's nslot slots
  std::vector<Slot> slot;
  std::vector<std::int32_t> rec_offset{0};
  std::vector<Record> rec;
  std::size_t size() const { return core.size(); }
  void clear() {
    core.clear();
    slot_offset.assign(1, 0);
    slot.clear();
    rec_offset.assign(1, 0);
    rec.clear();
  }
};

// Each particle's touching pairs (a non-zero spring or rolling spring) as it feels them, for the
// particles with own[i] (own empty: all), in CSR (offset n + 1).
void pair_records(const State& s, const std::vector<std::uint8_t>& ghost,
                  std::vector<std::int32_t>& offset, std::vector<Record>& rec) {
  const std::size_t n = s.size();
  offset.assign(n + 1, 0);
  rec.clear();
  if (!s.lists_valid || s.pair_offset.size() != n + 1) return;
  const bool rolls = s.pair_roll.size() == s.pair_j.size() && !s.pair_roll.empty();
  auto owned = [&](std::size_t i) { return ghost.empty() || !ghost[i]; };
  auto live = [&](std::int32_t k) {
    return nonzero(s.pair_spring[k]) || (rolls && nonzero(s.pair_roll[k]));
  };
  for (std::size_t a = 0; a < n; ++a)
    for (std::int32_t k = s.pair_offset[a]; k < s.pair_offset[a + 1]; ++k) {
      if (!live(k)) continue;
      const std::size_t b = static_cast<std::size_t>(s.pair_j[k]);
      if (owned(a)) ++offset[a + 1];
      if (owned(b)) ++offset[b + 1];
    }
  for (std::size_t i = 0; i < n; ++i) offset[i + 1] += offset[i];
  rec.resize(static_cast<std::size_t>(offset[n]));
  std::vector<std::int32_t> fill(offset.begin(), offset.end() - 1);
  for (std::size_t a = 0; a < n; ++a)
    for (std::int32_t k = s.pair_offset[a]; k < s.pair_offset[a + 1]; ++k) {
      if (!live(k)) continue;
      const std::size_t b = static_cast<std::size_t>(s.pair_j[k]);
      const Vec3 sp = s.pair_spring[k], ro = rolls ? s.pair_roll[k] : Vec3{};
      if (owned(a)) rec[static_cast<std::size_t>(fill[a]++)] = {s.id[b], sp, ro};
      if (owned(b)) rec[static_cast<std::size_t>(fill[b]++)] = {s.id[a], -sp, -ro};
    }
}

Core core_of(const State& s, std::size_t i) {
  Core c{};
  c.x = s.x[i];
  c.v = s.v[i];
  c.u = s.u[i];
  if (s.w.size() == s.size()) {
    c.w = s.w[i];
    c.wu = s.wu[i];
  }
  c.radius = s.radius[i];
  c.mass = s.mass[i];
  c.id = s.id[i];
  c.species = s.species[i];
  return c;
}

// Particle i of s with its slots and records onto w.
void pack_owned(const State& s, std::size_t i, const std::vector<std::int32_t>& rec_offset,
                const std::vector<Record>& rec, Writer& w) {
  Core c = core_of(s, i);
  // As the broad phase keeps them: a block's slots whatever the lists (a checkpoint loaded
  // with new tools has invalid lists but keeps its boundary history); the pair records only
  // with valid lists (pair_records), as the broad phase carries pair springs.
  const bool slots = s.slot_count.size() == s.size() && s.slot_block.size() == s.size() &&
                     s.slot_block[i] >= 0 &&
                     (static_cast<std::size_t>(s.slot_block[i]) + 1) * B <= s.slot_key.size();
  c.nslot = slots ? s.slot_count[i] : 0;
  c.nrec = rec_offset[i + 1] - rec_offset[i];
  w.put(c);
  const bool rolls = s.slot_roll.size() == s.slot_key.size() && !s.slot_roll.empty();
  for (int k = 0; k < c.nslot; ++k) {
    const std::size_t q = static_cast<std::size_t>(s.slot_block[i]) * B + k;
    w.put(Slot{s.slot_key[q], s.slot_spring[q], rolls ? s.slot_roll[q] : Vec3{}});
  }
  for (std::int32_t k = rec_offset[i]; k < rec_offset[i + 1]; ++k) w.put(rec[k]);
}

void unpack_owned(Reader& r, Particles& out) {
  while (r.p < r.end) {
    const Core c = r.get<Core>();
    out.core.push_back(c);
    for (int k = 0; k < c.nslot; ++k) out.slot.push_back(r.get<Slot>());
    out.slot_offset.push_back(static_cast<std::int32_t>(out.slot.size()));
    for (int k = 0; k < c.nrec; ++k) out.rec.push_back(r.get<Record>());
    out.rec_offset.push_back(static_cast<std::int32_t>(out.rec.size()));
  }
}

// Sorted by id (the canonical order of a rank's particles before its broad phase: the cell sort
// is stable, so the lists then depend on the particles alone, not on where they came from).
void sort_by_id(Particles& p) {
  const std::size_t n = p.size();
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return p.core[a].id < p.core[b].id; });
  Particles q;
  q.core.reserve(n);
  q.slot.reserve(p.slot.size());
  q.rec.reserve(p.rec.size());
  const bool slots = p.slot_offset.size() == n + 1;
  for (const std::size_t i : order) {
    q.core.push_back(p.core[i]);
    if (slots) {
      q.slot.insert(q.slot.end(), p.slot.begin() + p.slot_offset[i], p.slot.begin() + p.slot_offset[i + 1]);
      q.slot_offset.push_back(static_cast<std::int32_t>(q.slot.size()));
    }
    if (p.rec_offset.size() == n + 1) {
      q.rec.insert(q.rec.end(), p.rec.begin() + p.rec_offset[i], p.rec.begin() + p.rec_offset[i + 1]);
      q.rec_offset.push_back(static_cast<std::int32_t>(q.rec.size()));
    }
  }
  p = std::move(q);
}

// Byte buffers to every rank (MPI_Alltoallv after the counts). Returns the bytes this rank sent.
std::int64_t exchange(MPI_Comm comm, const std::vector<Writer>& out, std::vector<char>& in,
                      std::vector<int>& in_count, std::vector<int>& in_start) {
  int P = 1;
  MPI_Comm_size(comm, &P);
  std::vector<int> out_count(P), out_start(P + 1, 0);
  for (int r = 0; r < P; ++r) {
    if (out[r].buf.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
      throw std::runtime_error("dem::mpi: a migration message over 2 GB; run on more ranks");
    out_count[r] = static_cast<int>(out[r].buf.size());
    out_start[r + 1] = out_start[r] + out_count[r];
  }
  std::vector<char> send(static_cast<std::size_t>(out_start[P]));
  for (int r = 0; r < P; ++r)
    if (out_count[r]) std::memcpy(send.data() + out_start[r], out[r].buf.data(), out[r].buf.size());
  in_count.assign(P, 0);
  MPI_Alltoall(out_count.data(), 1, MPI_INT, in_count.data(), 1, MPI_INT, comm);
  in_start.assign(P + 1, 0);
  for (int r = 0; r < P; ++r) in_start[r + 1] = in_start[r] + in_count[r];
  in.resize(static_cast<std::size_t>(in_start[P]));
  MPI_Alltoallv(send.data(), out_count.data(), out_start.data(), MPI_BYTE, in.data(),
                in_count.data(), in_start.data(), MPI_BYTE, comm);
  int me = 0;
  MPI_Comm_rank(comm, &me);
  std::int64_t sent = 0;  // to the other ranks (a rank's own share is a copy)
  for (int r = 0; r < P; ++r)
    if (r != me) sent += out_count[r];
  return sent;
}

// Ranks - 1 cuts putting about the same count of the (unsorted) coordinates c on each side.
std::vector<double> cuts_by_count(std::vector<double> c, int P) {
  std::sort(c.begin(), c.end());
  const std::size_t n = c.size();
  std::vector<double> cuts(static_cast<std::size_t>(std::max(0, P - 1)), 0.0);
  for (int k = 1; k < P; ++k) {
    const std::size_t q = n * static_cast<std::size_t>(k) / static_cast<std::size_t>(P);
    if (n == 0)
      cuts[k - 1] = 0;
    else if (q == 0)
      cuts[k - 1] = c[0];
    else
      cuts[k - 1] = 0.5 * (c[q - 1] + c[q]);
  }
  return cuts;
}

double axis_of(const Vec3& p, int a) { return a == 0 ? p.x : a == 1 ? p.y : p.z; }

// Waits for the requests. spin: MPI_Waitall (Open MPI polls, holding the core). Otherwise (the
// engine's scene.thread_wait passive or brief) it tests for about 50 us and then sleeps 20 us
// between tests: on a host with more runnable tasks than cores a polling rank would burn the
// share of the core its neighbour needs to finish the step it waits for.
void wait_for(std::vector<MPI_Request>& req, bool spin) {
  if (req.empty()) return;
  const int n = static_cast<int>(req.size());
  if (spin) {
    MPI_Waitall(n, req.data(), MPI_STATUSES_IGNORE);
    return;
  }
  int done = 0;
  const cosim::Stopwatch watch;
  MPI_Testall(n, req.data(), &done, MPI_STATUSES_IGNORE);
  while (!done) {
    if (watch.seconds() > 50e-6) {
      const timespec nap{0, 20000};
      nanosleep(&nap, nullptr);
    }
    MPI_Testall(n, req.data(), &done, MPI_STATUSES_IGNORE);
  }
}

}  // namespace

// --- The decomposed run.

struct Decomposed::Impl {
  MPI_Comm comm = MPI_COMM_WORLD;
  int rank = 0, P = 1;
  std::vector<std::uint8_t> ghost;  // per particle of s: 1 = another rank's copy
  // The forward exchange: local indices sent to / received from each rank, in message order.
  std::vector<std::vector<std::int32_t>> send_idx, recv_idx;
  std::vector<std::vector<double>> send_buf, recv_buf;
  bool rotating = false;
  // The guard's tally over all ranks after the last step.
  double d1 = 0, d2 = 0, u2 = 0;
  Particles start_own;  // start(): this rank's share of the initial state
  State spare;  // rebuild_kept(): the arrays of the state before the last one, emptied (their
                // capacity kept: no page faults at the next broad phase)

  int owner(const std::vector<double>& cuts, double c) const {
    return static_cast<int>(std::upper_bound(cuts.begin(), cuts.end(), c) - cuts.begin());
  }
};

Decomposed::Decomposed(const Scene& scene, Engine& engine, const Options& options)
    : impl_(std::make_unique<Impl>()), scene_(scene), engine_(engine), options_(options) {
  MPI_Comm_rank(impl_->comm, &impl_->rank);
  MPI_Comm_size(impl_->comm, &impl_->P);
  impl_->rotating = scene.rotation.rotating();
}

Decomposed::~Decomposed() { engine_.set_ghosts(nullptr); }

void Decomposed::save_snapshot() {
  if (saved_)
    *saved_ = *impl_;  // reuses the vectors' capacity
  else
    saved_ = std::make_unique<Impl>(*impl_);
  saved_cuts_ = cuts_;
  saved_due_ = due_;
}

void Decomposed::restore_snapshot() {
  if (!saved_) throw std::logic_error("dem::mpi: restore_snapshot without a snapshot");
  *impl_ = *saved_;
  cuts_ = saved_cuts_;
  due_ = saved_due_;
  engine_.set_ghosts(&impl_->ghost);
}

void Decomposed::totals(const State& s, double& particles, double& kinetic_energy) const {
  const Impl& m = *impl_;
  double mine[2] = {0, 0};
  const bool spins = !s.w.empty();
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (i < m.ghost.size() && m.ghost[i]) continue;
    mine[0] += 1;
    mine[1] += 0.5 * s.mass[i] * norm2(s.v[i]);
    if (spins && i < s.w.size())
      mine[1] += 0.5 * moment_of_inertia(s.mass[i], s.radius[i]) * norm2(s.w[i]);
  }
  std::vector<double> all(static_cast<std::size_t>(2 * m.P));
  MPI_Allgather(mine, 2, MPI_DOUBLE, all.data(), 2, MPI_DOUBLE, m.comm);
  particles = kinetic_energy = 0;
  for (int q = 0; q < m.P; ++q) {  // in rank order: the same sums on every rank and run
    particles += all[2 * static_cast<std::size_t>(q)];
    kinetic_energy += all[2 * static_cast<std::size_t>(q) + 1];
  }
}

int Decomposed::rank() const { return impl_->rank; }
int Decomposed::ranks() const { return impl_->P; }

namespace {

// A rebuilt state t keeps the clock, tool poses, broad-phase counters and tally of removed
// grains of the state s it replaces.
void copy_clock(const State& s, State& t) {
  t.step = s.step;
  t.tool_pose = s.tool_pose;
  t.tool_pose_at_rebuild = s.tool_pose_at_rebuild;
  t.rebuilds = s.rebuilds;
  t.early_rebuilds = s.early_rebuilds;
  t.removed_count = s.removed_count;
  t.removed_mass = s.removed_mass;
}

// s := owned (sorted by id) then ghosts (sorted by id), their lists built by `engine` (a broad
// phase), the springs from the owned particles' records; ghost: the mask. Keeps s's step, tool
// poses and counters.
void assemble(const Scene& scene, Particles& own, Particles& gh, State& s, Engine& engine,
              std::vector<std::uint8_t>& ghost) {
  sort_by_id(own);
  sort_by_id(gh);
  const bool rotating = scene.rotation.rotating();
  State t;
  copy_clock(s, t);
  const std::size_t no = own.size(), n = no + gh.size();
  t.x.reserve(n);
  auto add = [&](const Core& c) {
    t.x.push_back(c.x);
    t.v.push_back(c.v);
    t.u.push_back(c.u);
    t.radius.push_back(c.radius);
    t.mass.push_back(c.mass);
    t.species.push_back(c.species);
    t.id.push_back(c.id);
    if (rotating) {
      t.w.push_back(c.w);
      t.wu.push_back(c.wu);
    }
  };
  for (const Core& c : own.core) add(c);
  for (const Core& c : gh.core) add(c);
  // Boundary slot blocks of the owned particles that remember a contact: the broad phase copies
  // them into its new pool (as it does a block it handed out before).
  t.slot_count.assign(n, 0);
  t.slot_block.assign(n, -1);
  for (std::size_t i = 0; i < no; ++i) {
    const int ns = own.core[i].nslot;
    if (ns <= 0) continue;
    const std::int32_t blk = static_cast<std::int32_t>(t.slot_particle.size());
    t.slot_block[i] = blk;
    t.slot_count[i] = static_cast<std::uint8_t>(ns);
    t.slot_particle.push_back(static_cast<std::int32_t>(i));
    for (int k = 0; k < B; ++k) {
      const Slot sl = k < ns ? own.slot[static_cast<std::size_t>(own.slot_offset[i] + k)]
                             : Slot{0, Vec3{}, Vec3{}};
      t.slot_key.push_back(sl.key);
      t.slot_spring.push_back(sl.spring);
      if (rotating) t.slot_roll.push_back(sl.roll);
    }
  }
  t.lists_valid = false;
  s = std::move(t);
  engine.set_ghosts(nullptr);
  engine.rebuild(s);  // the broad phase sorts owned and ghosts together by cell
  // The mask and each owned particle's records, by id.
  std::unordered_map<std::int64_t, std::int32_t> own_at;  // id -> index in own
  own_at.reserve(no * 2);
  for (std::size_t p = 0; p < no; ++p) own_at.emplace(own.core[p].id, static_cast<std::int32_t>(p));
  ghost.assign(s.size(), 1);
  std::vector<std::int32_t> rec_of(s.size(), -1);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto it = own_at.find(s.id[i]);
    if (it != own_at.end()) {
      ghost[i] = 0;
      rec_of[i] = it->second;
    }
  }
  // Springs: a pair with an owned side takes the owned side's record (negated when that side is
  // the pair's second particle: the list's spring acts on its first).
  if (rotating) s.pair_roll.assign(s.pair_j.size(), Vec3{});
  auto find = [&](std::int32_t p, std::int64_t partner) -> const Record* {
    for (std::int32_t k = own.rec_offset[p]; k < own.rec_offset[p + 1]; ++k)
      if (own.rec[k].partner == partner) return &own.rec[k];
    return nullptr;
  };
  for (std::size_t a = 0; a + 1 < s.pair_offset.size(); ++a)
    for (std::int32_t k = s.pair_offset[a]; k < s.pair_offset[a + 1]; ++k) {
      const std::size_t b = static_cast<std::size_t>(s.pair_j[k]);
      if (rec_of[a] >= 0) {
        if (const Record* r = find(rec_of[a], s.id[b])) {
          s.pair_spring[k] = r->spring;
          if (rotating) s.pair_roll[k] = r->roll;
        }
      } else if (rec_of[b] >= 0) {
        if (const Record* r = find(rec_of[b], s.id[a])) {
          s.pair_spring[k] = -r->spring;
          if (rotating) s.pair_roll[k] = -r->roll;
        }
      }
    }
}

}  // namespace

void Decomposed::start(const State& all, State& s) {
  Impl& m = *impl_;
  const int P = m.P;
  // The axis: the longest of the particles' box (every rank holds every particle here).
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const Vec3& p : all.x) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  if (all.x.empty()) lo = hi = Vec3{};
  const double ext[3] = {hi.x - lo.x, hi.y - lo.y, hi.z - lo.z};
  axis_ = 0;
  for (int a = 1; a < 3; ++a)
    if (ext[a] > ext[axis_]) axis_ = a;
  const double h = 2 * scene_.r_max() + scene_.skin_distance();
  const long cells = static_cast<long>(ext[axis_] / h) + 1;
  if (P > cells) {
    std::ostringstream msg;
    const char* names[3] = {"x", "y", "z"};
    msg << "mpi: " << P << " ranks, but the particles span only " << cells
        << " broad-phase cell(s) along their longest axis " << names[axis_] << " ("
        << ext[axis_] << " m; a cell is 2 r_max + skin = " << h
        << " m): a rank's slab would be thinner than the interaction range. Run on at most "
        << cells << " rank(s) (mpirun -np " << cells << ") or a larger scene";
    throw std::invalid_argument(msg.str());
  }
  std::vector<double> c(all.size());
  for (std::size_t i = 0; i < all.size(); ++i) c[i] = axis_of(all.x[i], axis_);
  cuts_ = cuts_by_count(std::move(c), P);
  // This rank's particles with their records from the whole state's lists.
  std::vector<std::int32_t> rec_offset;
  std::vector<Record> rec;
  pair_records(all, {}, rec_offset, rec);
  Writer w;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (m.owner(cuts_, axis_of(all.x[i], axis_)) == m.rank) pack_owned(all, i, rec_offset, rec, w);
  m.start_own.clear();
  Reader r{w.buf.data(), w.buf.data() + w.buf.size()};
  unpack_owned(r, m.start_own);
  s = State{};
  s.step = all.step;
  s.tool_pose = all.tool_pose;
  s.tool_pose_at_rebuild = all.tool_pose_at_rebuild;
  s.rebuilds = all.rebuilds;
  s.early_rebuilds = all.early_rebuilds;
  rebuild(s, true);
  tally(s);
}

void Decomposed::rebuild(State& s, bool first) {
  if (!first) {
    rebuild_kept(s);
    return;
  }
  Impl& m = *impl_;
  const int P = m.P;
  Particles own;
  std::vector<char> in;
  std::vector<int> in_count, in_start;
  own = std::move(m.start_own);  // start(): this rank's share, with slots and records
  m.start_own.clear();
  // Ghosts: every owned particle within the interaction range (2 r_max + skin) of another
  // rank's slab goes there as a copy.
  const double range = 2 * scene_.r_max() + scene_.skin_distance();
  std::vector<Writer> gout(static_cast<std::size_t>(P));
  for (const Core& c0 : own.core) {
    const double a = axis_of(c0.x, axis_);
    Core c = c0;
    c.nslot = c.nrec = 0;
    for (int q = 0; q < P; ++q) {
      if (q == m.rank) continue;
      const double lo = q == 0 ? -std::numeric_limits<double>::infinity() : cuts_[q - 1];
      const double hi = q == P - 1 ? std::numeric_limits<double>::infinity() : cuts_[q];
      if (a > lo - range && a < hi + range) gout[static_cast<std::size_t>(q)].put(c);
    }
  }
  halo_.migration_bytes += exchange(m.comm, gout, in, in_count, in_start);
  Particles gh;
  std::vector<std::vector<std::int64_t>> recv_ids(static_cast<std::size_t>(P));
  for (int q = 0; q < P; ++q) {
    Reader r{in.data() + in_start[q], in.data() + in_start[q] + in_count[q]};
    while (r.p < r.end) {
      const Core c = r.get<Core>();
      gh.core.push_back(c);
      recv_ids[static_cast<std::size_t>(q)].push_back(c.id);
    }
  }
  gh.rec_offset.clear();
  std::vector<std::vector<std::int64_t>> send_ids(static_cast<std::size_t>(P));
  for (int q = 0; q < P; ++q) {
    const std::vector<char>& b = gout[static_cast<std::size_t>(q)].buf;
    for (std::size_t o = 0; o < b.size(); o += sizeof(Core)) {
      Core c;
      std::memcpy(&c, b.data() + o, sizeof c);
      send_ids[static_cast<std::size_t>(q)].push_back(c.id);
    }
  }
  assemble(scene_, own, gh, s, engine_, m.ghost);
  // The forward exchange's index lists (after the broad phase's sort).
  std::unordered_map<std::int64_t, std::int32_t> at;
  at.reserve(s.size() * 2);
  for (std::size_t i = 0; i < s.size(); ++i) at.emplace(s.id[i], static_cast<std::int32_t>(i));
  m.send_idx.assign(static_cast<std::size_t>(P), {});
  m.recv_idx.assign(static_cast<std::size_t>(P), {});
  for (int q = 0; q < P; ++q) {
    for (const std::int64_t id : send_ids[static_cast<std::size_t>(q)])
      m.send_idx[static_cast<std::size_t>(q)].push_back(at.at(id));
    for (const std::int64_t id : recv_ids[static_cast<std::size_t>(q)])
      m.recv_idx[static_cast<std::size_t>(q)].push_back(at.at(id));
  }
  engine_.set_ghosts(&m.ghost);
  halo_.owned = static_cast<std::int64_t>(own.size());
  halo_.ghosts = static_cast<std::int64_t>(gh.size());
  ++halo_.migrations;
}

namespace {
// A ghost in the ghost lists of rebuild_kept: its id, and whether its data follow (a Core) or
// the receiver holds it already (it was a ghost there, from the same rank, since the last
// broad phase, and the forward exchange has kept it current).
struct GhostHead {
  std::int64_t id;
  std::int32_t full;
  std::int32_t pad = 0;
};
static_assert(std::is_trivially_copyable_v<GhostHead>);
}  // namespace

void Decomposed::rebuild_kept(State& s) {
  Impl& m = *impl_;
  const int P = m.P;
  const std::size_t n0 = s.size();
  cosim::Stopwatch watch;
  // Rebalance by count when the largest rank holds too many.
  {
    std::int64_t mine = 0;
    for (const std::uint8_t g : m.ghost) mine += g == 0;
    std::vector<std::int64_t> counts(static_cast<std::size_t>(P));
    std::vector<MPI_Request> req(1);  // the first collective of the broad phase: waits for the slowest
    MPI_Iallgather(&mine, 1, MPI_INT64_T, counts.data(), 1, MPI_INT64_T, m.comm, req.data());
    wait_for(req, scene_.thread_wait == ThreadWait::spin);
    const std::int64_t total = std::accumulate(counts.begin(), counts.end(), std::int64_t{0});
    const std::int64_t most = *std::max_element(counts.begin(), counts.end());
    if (total > 0 && static_cast<double>(most) * P > options_.rebalance * static_cast<double>(total)) {
      std::vector<double> mine_c;
      mine_c.reserve(static_cast<std::size_t>(mine));
      for (std::size_t i = 0; i < n0; ++i)
        if (!m.ghost[i]) mine_c.push_back(axis_of(s.x[i], axis_));
      std::vector<int> cnt(P), at(P + 1, 0);
      for (int q = 0; q < P; ++q) {
        cnt[q] = static_cast<int>(counts[q]);
        at[q + 1] = at[q] + cnt[q];
      }
      std::vector<double> every(static_cast<std::size_t>(at[P]));
      MPI_Allgatherv(mine_c.data(), static_cast<int>(mine_c.size()), MPI_DOUBLE, every.data(),
                     cnt.data(), at.data(), MPI_DOUBLE, m.comm);
      cuts_ = cuts_by_count(std::move(every), P);
      ++halo_.rebalances;
    }
  }
  halo_.seconds_count += watch.lap();

  // Migration: only the owned particles that leave this rank's slab travel, with their slots
  // and pair records; the others stay where they are.
  std::vector<std::int32_t> dest(n0, -1);  // owned: the rank of its slab; ghosts: -1
  std::vector<std::uint8_t> not_leaving(n0, 1);
  bool leaving = false;
  for (std::size_t i = 0; i < n0; ++i) {
    if (m.ghost[i]) continue;
    dest[i] = m.owner(cuts_, axis_of(s.x[i], axis_));
    if (dest[i] != m.rank) {
      not_leaving[i] = 0;
      leaving = true;
      ++halo_.migrated;
    }
  }
  std::vector<std::int32_t> rec_offset(n0 + 1, 0);
  std::vector<Record> rec;
  if (leaving) pair_records(s, not_leaving, rec_offset, rec);
  if (rec_offset.size() != n0 + 1) rec_offset.assign(n0 + 1, 0);
  std::vector<char> in;
  std::vector<int> in_count, in_start;
  Particles arr;  // the particles that arrive, by sender rank
  {
    std::vector<Writer> out(static_cast<std::size_t>(P));
    if (leaving)
      for (std::size_t i = 0; i < n0; ++i)
        if (dest[i] >= 0 && dest[i] != m.rank)
          pack_owned(s, i, rec_offset, rec, out[static_cast<std::size_t>(dest[i])]);
    halo_.migration_bytes += exchange(m.comm, out, in, in_count, in_start);
    for (int q = 0; q < P; ++q) {
      Reader r{in.data() + in_start[q], in.data() + in_start[q] + in_count[q]};
      unpack_owned(r, arr);
    }
  }
  halo_.seconds_migrate += watch.lap();

  // Ghost lists: every owned particle (staying or arrived) within the interaction range of
  // another rank's slab goes there: its id alone when that rank holds it as a ghost from here
  // already (it was in the last list sent there), else with its data.
  const double range = 2 * scene_.r_max() + scene_.skin_distance();
  std::vector<std::vector<std::int64_t>> sent_before(static_cast<std::size_t>(P));
  for (int q = 0; q < P; ++q) {
    auto& ids = sent_before[static_cast<std::size_t>(q)];
    for (const std::int32_t i : m.send_idx[static_cast<std::size_t>(q)]) ids.push_back(s.id[i]);
    std::sort(ids.begin(), ids.end());
  }
  // A provisional index of every particle of this rank after the broad phase: stayers and kept
  // ghosts by their old index (0 .. n0), the rest after them.
  std::vector<Writer> gout(static_cast<std::size_t>(P));
  std::vector<std::vector<std::int64_t>> send_key(static_cast<std::size_t>(P));  // old index, or n0 + arrival
  auto offer = [&](const Core& c0, std::int64_t key) {
    const double a = axis_of(c0.x, axis_);
    for (int q = 0; q < P; ++q) {
      if (q == m.rank) continue;
      const double lo = q == 0 ? -std::numeric_limits<double>::infinity() : cuts_[q - 1];
      const double hi = q == P - 1 ? std::numeric_limits<double>::infinity() : cuts_[q];
      if (!(a > lo - range && a < hi + range)) continue;
      const auto& before = sent_before[static_cast<std::size_t>(q)];
      const bool held = std::binary_search(before.begin(), before.end(), c0.id);
      Writer& w = gout[static_cast<std::size_t>(q)];
      w.put(GhostHead{c0.id, held ? 0 : 1});
      if (!held) {
        Core c = c0;
        c.nslot = c.nrec = 0;
        w.put(c);
      }
      send_key[static_cast<std::size_t>(q)].push_back(key);
    }
  };
  for (std::size_t i = 0; i < n0; ++i) {
    if (dest[i] != m.rank) continue;
    const double a = axis_of(s.x[i], axis_);
    // Cheap test first: most stayers are far from every other slab.
    const double lo = m.rank == 0 ? -std::numeric_limits<double>::infinity() : cuts_[m.rank - 1];
    const double hi = m.rank == P - 1 ? std::numeric_limits<double>::infinity() : cuts_[m.rank];
    if (a >= lo + range && a <= hi - range) continue;
    offer(core_of(s, i), static_cast<std::int64_t>(i));
  }
  for (std::size_t k = 0; k < arr.size(); ++k) offer(arr.core[k], static_cast<std::int64_t>(n0 + k));
  {
    const std::int64_t b = exchange(m.comm, gout, in, in_count, in_start);
    halo_.migration_bytes += b;
    halo_.ghost_bytes += b;
  }
  // The old particles a message may name: the ghosts and those that left, by id.
  std::vector<std::pair<std::int64_t, std::int32_t>> known;
  for (std::size_t i = 0; i < n0; ++i)
    if (dest[i] != m.rank) known.emplace_back(s.id[i], static_cast<std::int32_t>(i));
  std::sort(known.begin(), known.end());
  auto old_index = [&](std::int64_t id) -> std::int32_t {
    const auto it = std::lower_bound(known.begin(), known.end(), std::make_pair(id, std::int32_t{-1}));
    return it != known.end() && it->first == id ? it->second : -1;
  };
  // Every particle of the new set: where its data come from and what it is.
  struct Src {
    std::int32_t old;   // old index, or -1
    std::int32_t core;  // index in `cores` (data from a message), or -1 (data from s)
    std::int32_t arrival;  // index in arr (owned, with slots and records), or -1
    std::uint8_t owned;
  };
  std::vector<Src> src;
  src.reserve(n0 + arr.size());
  std::vector<Core> cores;
  std::vector<std::int32_t> entry_of_old(n0, -1);
  for (std::size_t i = 0; i < n0; ++i)
    if (dest[i] == m.rank) {
      entry_of_old[i] = static_cast<std::int32_t>(src.size());
      src.push_back({static_cast<std::int32_t>(i), -1, -1, 1});
    }
  std::vector<std::int32_t> entry_of_arrival(arr.size());
  for (std::size_t k = 0; k < arr.size(); ++k) {
    entry_of_arrival[k] = static_cast<std::int32_t>(src.size());
    const std::int32_t o = old_index(arr.core[k].id);
    cores.push_back(arr.core[k]);
    const Src e{o, static_cast<std::int32_t>(cores.size() - 1), static_cast<std::int32_t>(k), 1};
    if (o >= 0) entry_of_old[o] = static_cast<std::int32_t>(src.size());
    src.push_back(e);
  }
  std::vector<std::vector<std::int32_t>> recv_entry(static_cast<std::size_t>(P));
  for (int q = 0; q < P; ++q) {
    Reader r{in.data() + in_start[q], in.data() + in_start[q] + in_count[q]};
    while (r.p < r.end) {
      const GhostHead h = r.get<GhostHead>();
      const std::int32_t o = old_index(h.id);
      std::int32_t ci = -1;
      if (h.full) {
        cores.push_back(r.get<Core>());
        ci = static_cast<std::int32_t>(cores.size() - 1);
      } else if (o < 0 || !m.ghost[o]) {
        throw std::logic_error("dem::mpi: rank " + std::to_string(q) + " named ghost " +
                               std::to_string(h.id) + " as held, but this rank does not hold it");
      }
      if (o >= 0) entry_of_old[o] = static_cast<std::int32_t>(src.size());
      recv_entry[static_cast<std::size_t>(q)].push_back(static_cast<std::int32_t>(src.size()));
      src.push_back({o, ci, -1, 0});
    }
  }
  std::size_t ghosts_now = 0;
  for (int q = 0; q < P; ++q) ghosts_now += recv_entry[static_cast<std::size_t>(q)].size();
  halo_.seconds_ghosts += watch.lap();

  // The order of the broad phase (docs/mpi.md): by the engine's cell, then owned before ghosts, then by id: a
  // function of the particles alone (a restart from a checkpoint makes the same). The engine's
  // grid from the same positions (make_grid, set_grid), so its sort finds them in order.
  const std::size_t n = src.size();
  auto pos = [&](const Src& e) -> const Vec3& { return e.core >= 0 ? cores[e.core].x : s.x[e.old]; };
  auto idof = [&](const Src& e) { return e.core >= 0 ? cores[e.core].id : s.id[e.old]; };
  // Provisional order: the old particles in their old order (the last broad phase's: nearly
  // sorted), then the new ones.
  std::vector<std::int32_t> prov;
  prov.reserve(n);
  for (std::size_t i = 0; i < n0; ++i)
    if (entry_of_old[i] >= 0) prov.push_back(entry_of_old[i]);
  for (std::size_t e = 0; e < n; ++e)
    if (src[e].old < 0) prov.push_back(static_cast<std::int32_t>(e));
  if (prov.size() != n) throw std::logic_error("dem::mpi: a particle received twice");
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const Src& e : src) {
    const Vec3& p = pos(e);
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  if (n == 0) lo = hi = Vec3{};
  double h = 2 * scene_.r_max() + scene_.skin_distance();
  long nx = 1, ny = 1, nz = 1;
  detail::grid_cells(lo, hi, std::max<double>(4.0 * static_cast<double>(n), 64.0), h, nx, ny, nz);
  const double inv_h = 1.0 / h;
  auto coord = [&](double v, double l, long nmax) -> long {  // BroadPhase::cell_coord
    const double a = (v - l) * inv_h;
    return a > 0 ? (a < static_cast<double>(nmax) ? static_cast<long>(a) : nmax - 1) : 0;
  };
  std::vector<std::int32_t> cell(n);
  for (const std::int32_t e : prov) {
    const Vec3& p = pos(src[e]);
    cell[e] = static_cast<std::int32_t>((coord(p.z, lo.z, nz) * ny + coord(p.y, lo.y, ny)) * nx +
                                        coord(p.x, lo.x, nx));
  }
  const std::size_t ncells = static_cast<std::size_t>(nx * ny * nz);
  std::vector<std::int32_t> start(ncells + 1, 0);
  for (const std::int32_t e : prov) ++start[cell[e] + 1];
  for (std::size_t c = 0; c < ncells; ++c) start[c + 1] += start[c];
  std::vector<std::int32_t> order(n);  // new index -> entry
  {
    std::vector<std::int32_t> fill(start.begin(), start.end() - 1);
    for (const std::int32_t e : prov) order[fill[cell[e]]++] = e;
  }
  // Within each cell the owned particles first, each kind by id (assemble's order: the owned
  // by id, then the ghosts by id, sorted stably by cell). Insertion: cells are small.
  auto after = [&](std::int32_t e, std::int32_t f) {  // e goes after f
    if (src[e].owned != src[f].owned) return src[f].owned != 0;
    return idof(src[e]) > idof(src[f]);
  };
  for (std::size_t c = 0; c < ncells; ++c)
    for (std::int32_t p = start[c] + 1; p < start[c + 1]; ++p) {
      const std::int32_t e = order[p];
      std::int32_t q = p;
      while (q > start[c] && after(order[q - 1], e)) {
        order[q] = order[q - 1];
        --q;
      }
      order[q] = e;
    }
  // The new state in that order (the arrays of the state before last, emptied, hold it).
  const bool rotating = m.rotating;
  State t = std::move(m.spare);
  for_each_array(t, [](const char*, auto& a, Field) { a.clear(); });
  copy_clock(s, t);
  t.lists_valid = false;
  t.steps_since_rebuild = 0;
  t.max_displacement = t.second_displacement = 0;
  t.x.resize(n);
  t.v.resize(n);
  t.u.resize(n);
  t.radius.resize(n);
  t.mass.resize(n);
  t.species.resize(n);
  t.id.resize(n);
  if (rotating) {
    t.w.resize(n);
    t.wu.resize(n);
  }
  std::vector<std::uint8_t>& ghost = m.ghost;
  ghost.assign(n, 1);
  std::vector<std::int32_t> new_of_entry(n);
  t.slot_count.assign(n, 0);
  t.slot_block.assign(n, -1);
  const bool old_slots = s.slot_count.size() == n0 && s.slot_block.size() == n0;
  const bool old_rolls = s.slot_roll.size() == s.slot_key.size() && !s.slot_roll.empty();
  for (std::size_t p = 0; p < n; ++p) {
    const Src& e = src[order[p]];
    new_of_entry[order[p]] = static_cast<std::int32_t>(p);
    if (e.core >= 0) {
      const Core& c = cores[e.core];
      t.x[p] = c.x;
      t.v[p] = c.v;
      t.u[p] = c.u;
      t.radius[p] = c.radius;
      t.mass[p] = c.mass;
      t.species[p] = c.species;
      t.id[p] = c.id;
      if (rotating) {
        t.w[p] = c.w;
        t.wu[p] = c.wu;
      }
    } else {
      const std::size_t i = static_cast<std::size_t>(e.old);
      t.x[p] = s.x[i];
      t.v[p] = s.v[i];
      t.u[p] = s.u[i];
      t.radius[p] = s.radius[i];
      t.mass[p] = s.mass[i];
      t.species[p] = s.species[i];
      t.id[p] = s.id[i];
      if (rotating) {
        t.w[p] = s.w.size() == n0 ? s.w[i] : Vec3{};
        t.wu[p] = s.wu.size() == n0 ? s.wu[i] : Vec3{};
      }
    }
    if (!e.owned) continue;
    ghost[p] = 0;
    // Boundary slots of the owned particles that remember a contact (as assemble() makes them:
    // the broad phase copies them into its new pool).
    int ns = 0;
    const Slot* from = nullptr;
    std::size_t q0 = 0;
    if (e.arrival >= 0) {
      ns = arr.core[e.arrival].nslot;
      if (ns > 0) from = &arr.slot[static_cast<std::size_t>(arr.slot_offset[e.arrival])];
    } else if (old_slots) {
      const std::size_t i = static_cast<std::size_t>(e.old);
      if (s.slot_block[i] >= 0 && (static_cast<std::size_t>(s.slot_block[i]) + 1) * B <= s.slot_key.size()) {
        ns = s.slot_count[i];
        q0 = static_cast<std::size_t>(s.slot_block[i]) * B;
      }
    }
    if (ns <= 0) continue;
    t.slot_block[p] = static_cast<std::int32_t>(t.slot_particle.size());
    t.slot_count[p] = static_cast<std::uint8_t>(ns);
    t.slot_particle.push_back(static_cast<std::int32_t>(p));
    for (int k = 0; k < B; ++k) {
      Slot sl{0, Vec3{}, Vec3{}};
      if (k < ns) {
        if (from)
          sl = from[k];
        else
          sl = {s.slot_key[q0 + k], s.slot_spring[q0 + k], old_rolls ? s.slot_roll[q0 + k] : Vec3{}};
      }
      t.slot_key.push_back(sl.key);
      t.slot_spring.push_back(sl.spring);
      if (rotating) t.slot_roll.push_back(sl.roll);
    }
  }
  State old = std::move(s);
  s = std::move(t);
  halo_.seconds_local += watch.lap();
  engine_.set_ghosts(nullptr);
  engine_.rebuild(s);  // finds the particles in cell order: nothing to permute
  halo_.seconds_broad_phase += watch.lap();

  // Springs, by the rule of assemble(): a pair takes its spring from its first particle when
  // that one is owned, else from its second when owned, else none (two ghosts). A particle that
  // stayed on this rank has its springs in the old lists (this rank's); one that arrived brings
  // them in its records.
  if (rotating) s.pair_roll.assign(s.pair_j.size(), Vec3{});
  std::vector<std::int32_t> new_of_old(n0, -1);
  std::vector<std::uint8_t> stayer(n, 0);
  for (std::size_t i = 0; i < n0; ++i)
    if (entry_of_old[i] >= 0) new_of_old[i] = new_of_entry[entry_of_old[i]];
  for (std::size_t e = 0; e < n; ++e)
    if (src[e].owned && src[e].arrival < 0) stayer[new_of_entry[e]] = 1;
  auto chosen = [&](std::int32_t a, std::int32_t b) -> std::int32_t {
    return !ghost[a] ? a : !ghost[b] ? b : -1;
  };
  if (old.lists_valid && old.pair_offset.size() == n0 + 1) {
    const bool rolls = old.pair_roll.size() == old.pair_j.size() && !old.pair_roll.empty();
    for (std::size_t oa = 0; oa < n0; ++oa) {
      const std::int32_t na = new_of_old[oa];
      if (na < 0) continue;
      for (std::int32_t k = old.pair_offset[oa]; k < old.pair_offset[oa + 1]; ++k) {
        const Vec3 sp = old.pair_spring[k];
        const Vec3 ro = rolls ? old.pair_roll[k] : Vec3{};
        if (!nonzero(sp) && !(rolls && nonzero(ro))) continue;
        const std::int32_t nb = new_of_old[old.pair_j[k]];
        if (nb < 0) continue;
        const bool swap = na > nb;
        const std::int32_t row = swap ? nb : na, col = swap ? na : nb;
        const std::int32_t c = chosen(row, col);
        if (c < 0 || !stayer[c]) continue;
        for (std::int32_t q = s.pair_offset[row]; q < s.pair_offset[row + 1]; ++q)
          if (s.pair_j[q] == col) {
            s.pair_spring[q] = swap ? -sp : sp;
            if (rotating) s.pair_roll[q] = swap ? -ro : ro;
            break;
          }
      }
    }
  }
  if (!arr.core.empty()) {
    std::vector<std::int32_t> arrival_of(n, -1);
    for (std::size_t e = 0; e < n; ++e)
      if (src[e].arrival >= 0) arrival_of[new_of_entry[e]] = src[e].arrival;
    for (std::size_t a = 0; a + 1 < s.pair_offset.size(); ++a)
      for (std::int32_t k = s.pair_offset[a]; k < s.pair_offset[a + 1]; ++k) {
        const std::int32_t b = s.pair_j[k];
        const std::int32_t c = chosen(static_cast<std::int32_t>(a), b);
        if (c < 0 || arrival_of[c] < 0) continue;
        const std::int32_t p = arrival_of[c];
        const std::int64_t partner = c == static_cast<std::int32_t>(a) ? s.id[b] : s.id[a];
        for (std::int32_t r = arr.rec_offset[p]; r < arr.rec_offset[p + 1]; ++r)
          if (arr.rec[r].partner == partner) {
            const bool first = c == static_cast<std::int32_t>(a);
            s.pair_spring[k] = first ? arr.rec[r].spring : -arr.rec[r].spring;
            if (rotating) s.pair_roll[k] = first ? arr.rec[r].roll : -arr.rec[r].roll;
            break;
          }
      }
  }
  // The forward exchange's index lists, in message order.
  m.send_idx.assign(static_cast<std::size_t>(P), {});
  m.recv_idx.assign(static_cast<std::size_t>(P), {});
  for (int q = 0; q < P; ++q) {
    auto& si = m.send_idx[static_cast<std::size_t>(q)];
    for (const std::int64_t key : send_key[static_cast<std::size_t>(q)]) {
      const std::int32_t e = key < static_cast<std::int64_t>(n0)
                                 ? entry_of_old[static_cast<std::size_t>(key)]
                                 : entry_of_arrival[static_cast<std::size_t>(key) - n0];
      si.push_back(new_of_entry[static_cast<std::size_t>(e)]);
    }
    auto& ri = m.recv_idx[static_cast<std::size_t>(q)];
    for (const std::int32_t e : recv_entry[static_cast<std::size_t>(q)]) ri.push_back(new_of_entry[e]);
  }
  halo_.owned = static_cast<std::int64_t>(n - ghosts_now);
  halo_.ghosts = static_cast<std::int64_t>(ghosts_now);
  ++halo_.migrations;
  m.spare = std::move(old);
  for_each_array(m.spare, [](const char*, auto& a, Field) { a.clear(); });
  engine_.set_ghosts(&m.ghost);
  halo_.seconds_springs += watch.lap();
}

int Decomposed::tally(State& s, bool failed) {
  Impl& m = *impl_;
  double t[4] = {0, 0, 0, failed ? 1.0 : 0.0};
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (m.ghost[i]) continue;
    keep_two_largest(t[0], t[1], norm2(s.x[i] - s.x_at_rebuild[i]));
    t[2] = std::max(t[2], norm2(s.u[i]));
  }
  std::vector<double> all(static_cast<std::size_t>(4 * m.P));
  std::vector<MPI_Request> req(1);
  MPI_Iallgather(t, 4, MPI_DOUBLE, all.data(), 4, MPI_DOUBLE, m.comm, req.data());
  wait_for(req, scene_.thread_wait == ThreadWait::spin);
  m.d1 = m.d2 = m.u2 = 0;
  int first_failed = -1;
  for (int q = 0; q < m.P; ++q) {
    keep_two_largest(m.d1, m.d2, all[4 * q]);
    keep_two_largest(m.d1, m.d2, all[4 * q + 1]);
    m.u2 = std::max(m.u2, all[4 * q + 2]);
    if (all[4 * q + 3] != 0 && first_failed < 0) first_failed = q;
  }
  // The state's displacements are the whole scene's (what the guard's bound reads).
  s.max_displacement = std::sqrt(m.d1);
  s.second_displacement = std::sqrt(m.d2);
  return first_failed;
}

void Decomposed::step(State& s) {
  Impl& m = *impl_;
  bool due = !s.lists_valid || s.steps_since_rebuild >= scene_.broad_phase_interval ||
             m.ghost.size() != s.size();
  if (!due) {
    // The guard's bound over every rank's particles (FarMoverGuard::bound, the same on every
    // rank); when it fires every rank rebuilds (no far-mover check: it would need the other
    // ranks' lists).
    s.max_displacement = std::sqrt(m.d1);
    s.second_displacement = std::sqrt(m.d2);
    const double moved = FarMoverGuard::bound(scene_, s, std::sqrt(m.u2));
    if (moved > scene_.skin_distance()) {
      if (scene_.guard == GuardMode::strict)
        throw SimulationError(FarMoverGuard::strict_message(scene_, s, moved));
      ++s.early_rebuilds;
      due = true;
    }
  }
  if (due) {
    const cosim::Stopwatch watch;
    rebuild(s, false);  // the engine's broad_phase row holds its broad phase; the rest is "other"
    halo_.seconds_rebuild += watch.seconds();
  }
  // A throw here on one rank would leave the others waiting in the exchange: it is held until
  // every rank has heard of it (the tally below).
  std::exception_ptr failed;
  try {
    engine_.step(s);
  } catch (...) {
    failed = std::current_exception();
  }
  const cosim::Stopwatch exchange_watch;
  // Forward: the owners' x, v, u (w, wu) onto their ghosts.
  const int P = m.P;
  const int per = m.rotating ? 15 : 9;
  m.send_buf.resize(static_cast<std::size_t>(P));
  m.recv_buf.resize(static_cast<std::size_t>(P));
  std::vector<MPI_Request> req;
  req.reserve(static_cast<std::size_t>(2 * P));
  for (int q = 0; q < P; ++q) {
    const auto& idx = m.recv_idx[static_cast<std::size_t>(q)];
    if (idx.empty()) continue;
    auto& b = m.recv_buf[static_cast<std::size_t>(q)];
    b.resize(idx.size() * per);
    req.emplace_back();
    MPI_Irecv(b.data(), static_cast<int>(b.size()), MPI_DOUBLE, q, kTagGhost, m.comm, &req.back());
  }
  for (int q = 0; q < P; ++q) {
    const auto& idx = m.send_idx[static_cast<std::size_t>(q)];
    if (idx.empty()) continue;
    auto& b = m.send_buf[static_cast<std::size_t>(q)];
    b.resize(idx.size() * per);
    double* o = b.data();
    for (const std::int32_t i : idx) {
      for (const Vec3* v : {&s.x[i], &s.v[i], &s.u[i]}) {
        *o++ = v->x;
        *o++ = v->y;
        *o++ = v->z;
      }
      if (m.rotating)
        for (const Vec3* v : {&s.w[i], &s.wu[i]}) {
          *o++ = v->x;
          *o++ = v->y;
          *o++ = v->z;
        }
    }
    req.emplace_back();
    MPI_Isend(b.data(), static_cast<int>(b.size()), MPI_DOUBLE, q, kTagGhost, m.comm, &req.back());
    halo_.bytes_sent += static_cast<std::int64_t>(b.size() * sizeof(double));
    ++halo_.messages_sent;
  }
  wait_for(req, scene_.thread_wait == ThreadWait::spin);
  for (int q = 0; q < P; ++q) {
    const auto& idx = m.recv_idx[static_cast<std::size_t>(q)];
    const double* o = m.recv_buf[static_cast<std::size_t>(q)].data();
    for (const std::int32_t i : idx) {
      for (Vec3* v : {&s.x[i], &s.v[i], &s.u[i]}) {
        v->x = *o++;
        v->y = *o++;
        v->z = *o++;
      }
      if (m.rotating)
        for (Vec3* v : {&s.w[i], &s.wu[i]}) {
          v->x = *o++;
          v->y = *o++;
          v->z = *o++;
        }
    }
  }
  ++halo_.steps;
  const double forward = exchange_watch.seconds();
  halo_.seconds_forward += forward;
  const int first_failed = tally(s, failed != nullptr);
  const double both = exchange_watch.seconds();
  halo_.seconds_tally += both - forward;
  halo_.seconds_exchange += both;
  if (failed) std::rethrow_exception(failed);
  if (first_failed >= 0)
    throw OtherRankFailed(first_failed, "the step failed on rank " + std::to_string(first_failed) +
                                            " (its message names the problem)");
}

void Decomposed::reduce_boundary(std::vector<Wrench>& tools, std::vector<Vec3>& walls) const {
  const Impl& m = *impl_;
  const std::vector<Wrench>& tw = engine_.tool_wrenches();
  const std::vector<Vec3>& wf = engine_.wall_forces();
  std::vector<double> mine;
  for (const Wrench& w : tw) mine.insert(mine.end(), {w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z});
  for (const Vec3& f : wf) mine.insert(mine.end(), {f.x, f.y, f.z});
  const int L = static_cast<int>(mine.size());
  std::vector<double> all(m.rank == 0 ? static_cast<std::size_t>(L) * m.P : 0);
  MPI_Gather(mine.data(), L, MPI_DOUBLE, all.data(), L, MPI_DOUBLE, 0, m.comm);
  std::vector<double> sum(static_cast<std::size_t>(L), 0.0);
  if (m.rank == 0)  // in rank order: the same sum on every run
    for (int q = 0; q < m.P; ++q)
      for (int k = 0; k < L; ++k) sum[k] += all[static_cast<std::size_t>(q) * L + k];
  MPI_Bcast(sum.data(), L, MPI_DOUBLE, 0, m.comm);
  tools.resize(tw.size());
  walls.resize(wf.size());
  std::size_t k = 0;
  for (Wrench& w : tools) {
    w.force = {sum[k], sum[k + 1], sum[k + 2]};
    w.torque = {sum[k + 3], sum[k + 4], sum[k + 5]};
    k += 6;
  }
  for (Vec3& f : walls) {
    f = {sum[k], sum[k + 1], sum[k + 2]};
    k += 3;
  }
}

namespace {
// Every rank's bytes to rank 0, in rank order (rank 0's: `in`, others: empty).
void gather_bytes(MPI_Comm comm, const std::vector<char>& mine, std::vector<char>& in,
                  std::vector<int>& count, std::vector<int>& start) {
  int P = 1, rank = 0;
  MPI_Comm_size(comm, &P);
  MPI_Comm_rank(comm, &rank);
  const int n = static_cast<int>(mine.size());
  count.assign(static_cast<std::size_t>(P), 0);
  MPI_Gather(&n, 1, MPI_INT, count.data(), 1, MPI_INT, 0, comm);
  start.assign(static_cast<std::size_t>(P) + 1, 0);
  for (int q = 0; q < P; ++q) start[q + 1] = start[q] + count[q];
  in.resize(rank == 0 ? static_cast<std::size_t>(start[P]) : 0);
  MPI_Gatherv(mine.data(), n, MPI_BYTE, in.data(), count.data(), start.data(), MPI_BYTE, 0, comm);
}
// A gathered state's clock, tools and broad-phase counters (the particles are added by the caller).
State counters_of(const State& s) {
  State g;
  g.step = s.step;
  g.tool_pose = s.tool_pose;
  g.rebuilds = s.rebuilds;
  g.early_rebuilds = s.early_rebuilds;
  return g;
}

}  // namespace

State Decomposed::gather(const State& s) const {
  const Impl& m = *impl_;
  Writer w;
  for (std::size_t i = 0; i < s.size(); ++i)
    if (!m.ghost[i]) w.put(core_of(s, i));
  std::vector<char> in;
  std::vector<int> count, start;
  gather_bytes(m.comm, w.buf, in, count, start);
  State g = counters_of(s);
  if (m.rank != 0) return g;
  std::vector<Core> cs(in.size() / sizeof(Core));
  if (!cs.empty()) std::memcpy(cs.data(), in.data(), cs.size() * sizeof(Core));
  std::sort(cs.begin(), cs.end(), [](const Core& a, const Core& b) { return a.id < b.id; });
  for (const Core& c : cs) {
    g.x.push_back(c.x);
    g.v.push_back(c.v);
    g.u.push_back(c.u);
    g.radius.push_back(c.radius);
    g.mass.push_back(c.mass);
    g.species.push_back(c.species);
    g.id.push_back(c.id);
    if (m.rotating) {
      g.w.push_back(c.w);
      g.wu.push_back(c.wu);
    }
  }
  return g;
}

State Decomposed::gather_with_lists(const State& s) const {
  const Impl& m = *impl_;
  std::vector<std::int32_t> rec_offset;
  std::vector<Record> rec;
  pair_records(s, m.ghost, rec_offset, rec);
  Writer w;
  for (std::size_t i = 0; i < s.size(); ++i)
    if (!m.ghost[i]) pack_owned(s, i, rec_offset, rec, w);
  std::vector<char> in;
  std::vector<int> count, start;
  gather_bytes(m.comm, w.buf, in, count, start);
  State g = counters_of(s);
  g.tool_pose_at_rebuild = s.tool_pose;
  if (m.rank != 0) return g;
  Particles own, none;
  Reader r{in.data(), in.data() + in.size()};
  unpack_owned(r, own);
  Engine e(scene_, engine_.options());
  std::vector<std::uint8_t> mask;
  assemble(scene_, own, none, g, e, mask);
  g.rebuilds = s.rebuilds;  // the broad phase of the gathering is not the run's
  return g;
}

std::string Decomposed::halo_summary() const {
  const Impl& m = *impl_;
  constexpr int K = 20;
  auto us = [](double sec) { return static_cast<std::int64_t>(std::llround(1e6 * sec)); };
  const std::int64_t mine[K] = {halo_.owned,         halo_.ghosts,    halo_.steps,
                                halo_.bytes_sent,    halo_.messages_sent, halo_.migrations,
                                halo_.migrated,      halo_.rebalances, halo_.migration_bytes,
                                us(halo_.seconds_rebuild), us(halo_.seconds_exchange),
                                halo_.ghost_bytes, us(halo_.seconds_count),
                                us(halo_.seconds_migrate), us(halo_.seconds_ghosts),
                                us(halo_.seconds_local), us(halo_.seconds_broad_phase),
                                us(halo_.seconds_springs), us(halo_.seconds_forward),
                                us(halo_.seconds_tally)};
  std::vector<std::int64_t> all(static_cast<std::size_t>(K * m.P));
  MPI_Gather(mine, K, MPI_INT64_T, all.data(), K, MPI_INT64_T, 0, m.comm);
  if (m.rank != 0) return {};
  std::ostringstream o;
  const char* names[3] = {"x", "y", "z"};
  o << "MPI: " << m.P << " ranks, slabs along " << names[axis_] << ", cuts at";
  for (const double c : cuts_) o << ' ' << c;
  o << " m\n";
  for (int q = 0; q < m.P; ++q) {
    const std::int64_t* h = &all[static_cast<std::size_t>(K * q)];
    const double steps = std::max<double>(1.0, static_cast<double>(h[2]));
    char line[400];
    std::snprintf(line, sizeof line,
                  "  rank %d: %lld owned, %lld ghosts (%.3g per owned); per step %.4g messages, "
                  "%.4g bytes sent; %lld broad phases with migration (%lld particles moved, "
                  "%lld rebalances, %.4g bytes); wall s: migration and broad phases %.3f, "
                  "forward exchange and tally %.3f\n",
                  q, static_cast<long long>(h[0]), static_cast<long long>(h[1]),
                  h[0] > 0 ? static_cast<double>(h[1]) / static_cast<double>(h[0]) : 0.0,
                  static_cast<double>(h[4]) / steps, static_cast<double>(h[3]) / steps,
                  static_cast<long long>(h[5]), static_cast<long long>(h[6]),
                  static_cast<long long>(h[7]), static_cast<double>(h[8]),
                  1e-6 * static_cast<double>(h[9]), 1e-6 * static_cast<double>(h[10]));
    o << line;
    // The rebuilds after the start by part (the ghost lists' bytes among the broad phases'),
    // then the step's exchange: the forward messages and the tally's wait for the slowest rank.
    std::snprintf(line, sizeof line,
                  "    (rank %d wall s: count %.3f, migrate %.3f, ghost lists %.3f (%.4g bytes), "
                  "local order %.3f, engine broad phase %.3f, springs and lists %.3f; forward "
                  "%.3f, tally and wait %.3f)\n",
                  q, 1e-6 * static_cast<double>(h[12]), 1e-6 * static_cast<double>(h[13]),
                  1e-6 * static_cast<double>(h[14]), static_cast<double>(h[11]),
                  1e-6 * static_cast<double>(h[15]), 1e-6 * static_cast<double>(h[16]),
                  1e-6 * static_cast<double>(h[17]), 1e-6 * static_cast<double>(h[18]),
                  1e-6 * static_cast<double>(h[19]));
    o << line;
  }
  return o.str();
}

}  // namespace dem::mpi
