#include "dem/mpi/service_ranks.hpp"

#include <mpi.h>

#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <iterator>
#include <new>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "cosim/time.hpp"
#include "cosim/yaml_config.hpp"

namespace dem::mpi {

namespace {

// --- The RankDriver: a Decomposed run of each session.

class Driver final : public RankDriver {
 public:
  explicit Driver(const Options& options) : options_(options) {
    MPI_Comm_size(MPI_COMM_WORLD, &ranks_);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  }
  int ranks() const override { return ranks_; }
  void check_supported(const RunConfig& rc, const EngineOptions& options) const override {
    dem::mpi::check_supported(rc, options, ranks_);
  }
  void start(const Scene& scene, Engine& engine, State& s) override {
    // The last session's decompositions unhook the last engine (the caller keeps it until here).
    dec_.reset();
    prev_.reset();
    recut_ = false;
    dec_ = std::make_unique<Decomposed>(scene, engine, options_);
    State whole = std::move(s);
    try {
      dec_->start(whole, s);
    } catch (...) {
      dec_.reset();  // a refused start: the caller drops `engine`
      throw;
    }
  }
  void recut(const Scene& scene, Engine& engine, State& s) override {
    // The old cut is kept until the next snapshot: a repeated step restores it. (Assigning
    // prev_ ends an older one, which unhooks the engine's ghosts; the new one hooks its own.)
    prev_ = std::move(dec_);
    recut_ = true;
    dec_ = std::make_unique<Decomposed>(scene, engine, options_);
    State whole = std::move(s);
    dec_->start(whole, s);
  }
  void step(State& s) override { dec_->step(s); }
  std::vector<Wrench> tool_wrenches() override {
    dec_->reduce_boundary(tools_, walls_);
    return tools_;
  }
  std::vector<Vec3> wall_forces() const override { return walls_; }
  bool lead() const override { return rank_ == 0; }
  // Detached (rank 0 ended without finishing its session): the gathers are empty and call no
  // MPI, so a follower's finish() does not wait for a rank 0 that never gathers.
  // (No decomposition: the session's start was refused on every rank alike.)
  State gather(const State& s) override { return detached_ || !dec_ ? State{} : dec_->gather(s); }
  State gather_checkpoint(const State& s) override {
    return detached_ || !dec_ ? State{} : dec_->gather_with_lists(s);
  }
  void detach() { detached_ = true; }
  void totals(const State& s, double& particles, double& kinetic_energy) override {
    dec_->totals(s, particles, kinetic_energy);
  }
  void save_snapshot() override {
    recut_ = false;
    dec_->save_snapshot();
  }
  void restore_snapshot() override {
    if (recut_ && prev_) {
      // The snapshot was taken before the last recut: back to that cut (ending the new one
      // unhooks the engine's ghosts; the restore hooks the old one's).
      dec_ = std::move(prev_);
      recut_ = false;
    }
    dec_->restore_snapshot();
  }

 private:
  Options options_;
  int ranks_ = 1, rank_ = 0;
  bool detached_ = false;
  bool recut_ = false;  // recut() since the last save_snapshot()
  std::unique_ptr<Decomposed> prev_;  // the cut before the last recut()
  std::unique_ptr<Decomposed> dec_;
  std::vector<Wrench> tools_;
  std::vector<Vec3> walls_;
};

// --- Commands from rank 0.

enum Command : std::int32_t { kConfigure = 1, kStep, kSave, kRestore, kEnd, kSaveCheckpoint, kLoadCheckpoint };

Driver* the_driver = nullptr;  // this process's driver (make_rank_driver), for follow()'s end

struct Buffer {
  std::vector<char> bytes;
  std::size_t at = 0;
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const std::size_t o = bytes.size();
    bytes.resize(o + sizeof(T));
    std::memcpy(bytes.data() + o, &v, sizeof(T));
  }
  void put_string(const std::string& s) {
    put(static_cast<std::int64_t>(s.size()));
    bytes.insert(bytes.end(), s.begin(), s.end());
  }
  template <class T>
  T get() {
    if (at + sizeof(T) > bytes.size()) throw std::logic_error("dem_service: truncated command");
    T v;
    std::memcpy(&v, bytes.data() + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
  std::string get_string() {
    const auto n = static_cast<std::size_t>(get<std::int64_t>());
    if (at + n > bytes.size()) throw std::logic_error("dem_service: truncated command");
    std::string s(bytes.data() + at, n);
    at += n;
    return s;
  }
};

// Rank 0's buffer to every rank (every rank calls it; the others' `b` is replaced).
void broadcast(Buffer& b) {
  std::int64_t n = static_cast<std::int64_t>(b.bytes.size());
  MPI_Bcast(&n, 1, MPI_INT64_T, 0, MPI_COMM_WORLD);
  b.bytes.resize(static_cast<std::size_t>(n));
  b.at = 0;
  // In pieces of at most 1 GiB (a checkpoint of millions of grains exceeds an int's count).
  constexpr std::int64_t kPiece = std::int64_t{1} << 30;
  for (std::int64_t at = 0; at < n; at += kPiece)
    MPI_Bcast(b.bytes.data() + at, static_cast<int>(std::min(kPiece, n - at)), MPI_BYTE, 0,
              MPI_COMM_WORLD);
}

// --- Agreement: a command's outcome on every rank.

enum Kind : int { kOk = 0, kInput, kConfig, kSimulation, kRefused, kOther };

struct Outcome {
  int kind = kOk;
  bool secondary = false;  // OtherRankFailed: another rank's step failed
  std::string message;
};

template <class F>
Outcome attempt(F&& f) {
  Outcome o;
  try {
    f();
  } catch (const cosim::InputError& e) {
    o = {kInput, false, e.what()};
  } catch (const cosim::config::ConfigError& e) {
    o = {kConfig, false, e.what()};
  } catch (const OtherRankFailed& e) {
    o = {kSimulation, true, e.what()};
  } catch (const SimulationError& e) {
    o = {kSimulation, false, e.what()};
  } catch (const std::invalid_argument& e) {
    o = {kRefused, false, e.what()};
  } catch (const std::bad_alloc&) {
    o = {kOther, false, "out of memory (std::bad_alloc)"};
  } catch (const std::exception& e) {
    o = {kOther, false, e.what()};
  }
  return o;
}

// Every rank: when the command failed on any rank, every rank throws the error of the first rank
// that failed of its own accord (the lowest such rank; else the lowest failing rank).
void agree(const Outcome& o) {
  int rank = 0, P = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &P);
  const int mine = o.kind == kOk ? 2 * P : (o.secondary ? P + rank : rank);
  int first = 2 * P;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (first == 2 * P) return;
  const int who = first < P ? first : first - P;
  Buffer b;
  if (rank == who) {
    b.put(static_cast<std::int32_t>(o.kind));
    b.put_string(o.message);
  }
  std::int64_t n = static_cast<std::int64_t>(b.bytes.size());
  MPI_Bcast(&n, 1, MPI_INT64_T, who, MPI_COMM_WORLD);
  b.bytes.resize(static_cast<std::size_t>(n));
  MPI_Bcast(b.bytes.data(), static_cast<int>(n), MPI_BYTE, who, MPI_COMM_WORLD);
  const int kind = b.get<std::int32_t>();
  const std::string msg = (who == 0 ? "" : "rank " + std::to_string(who) + ": ") + b.get_string();
  switch (kind) {
    case kInput: throw cosim::InputError(msg);
    case kConfig: throw cosim::config::ConfigError(msg);
    case kSimulation: throw SimulationError(msg);
    case kRefused: throw std::invalid_argument(msg);
    default: throw std::runtime_error(msg);
  }
}

void put_run(Buffer& b, const cosim::RunInfo& r) {
  b.put_string(r.participant);
  b.put(cosim::to_ns(r.t_start));
  b.put(cosim::to_ns(r.t_end));
  b.put(cosim::to_ns(r.macro_step));
  b.put(static_cast<std::int64_t>(r.resume_steps_done));
  b.put(cosim::to_ns(r.resume_time));
}

cosim::RunInfo get_run(Buffer& b) {
  cosim::RunInfo r;
  r.participant = b.get_string();
  r.t_start = cosim::time_point_ns(b.get<std::int64_t>());
  r.t_end = cosim::time_point_ns(b.get<std::int64_t>());
  r.macro_step = cosim::Duration(b.get<std::int64_t>());
  r.resume_steps_done = b.get<std::int64_t>();
  r.resume_time = cosim::time_point_ns(b.get<std::int64_t>());
  return r;
}

static_assert(std::is_trivially_copyable_v<ToolPose>);

}  // namespace

std::unique_ptr<RankDriver> make_rank_driver(const Options& options) {
  auto d = std::make_unique<Driver>(options);
  the_driver = d.get();
  return d;
}

namespace {

// The master's checkpoint file on every rank (collective): rank 0 reads it (on its own host,
// where the master's folder is) and sends its bytes; the other ranks write them to a private
// temporary file of their own host; every rank then runs `use` on its copy. Each part's outcome
// is agreed.
template <class Use>
void on_every_rank(const std::string& path, Use&& use) {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  Buffer file;
  agree(attempt([&] {
    if (rank != 0) return;
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot open the checkpoint " + path);
    file.bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (in.bad()) throw std::runtime_error("cannot read the checkpoint " + path);
  }));
  broadcast(file);
  std::string local = path;
  agree(attempt([&] {
    if (rank == 0) return;
    const char* dir = std::getenv("TMPDIR");
    std::string name = std::string(dir && *dir ? dir : "/tmp") + "/dem_service_resume_XXXXXX";
    std::vector<char> tmpl(name.begin(), name.end());
    tmpl.push_back('\0');
    const int fd = ::mkstemp(tmpl.data());
    if (fd < 0) throw std::runtime_error("cannot make a temporary file in " + name.substr(0, name.rfind('/')) + " for the checkpoint (set TMPDIR to a writable folder)");
    local = tmpl.data();
    std::size_t at = 0;
    while (at < file.bytes.size()) {
      const ssize_t w = ::write(fd, file.bytes.data() + at, file.bytes.size() - at);
      if (w <= 0) {
        ::close(fd);
        std::remove(local.c_str());
        throw std::runtime_error("cannot write the checkpoint's copy " + local);
      }
      at += static_cast<std::size_t>(w);
    }
    ::close(fd);
  }));
  file.bytes.clear();
  file.bytes.shrink_to_fit();
  Outcome o = attempt([&] { use(local); });
  if (rank != 0) std::remove(local.c_str());
  agree(o);
}

void load_on_every_rank(ServiceModel& model, const std::string& path) {
  on_every_rank(path, [&](const std::string& local) { model.load_checkpoint(local); });
}

// The master's checkpoint: rank 0 writes the gathered scene; then every rank continues from that
// file as a resume from it would (the slabs cut anew), so the resumed run repeats this one.
void save_on_every_rank(ServiceModel& model, const std::string& path) {
  agree(attempt([&] { model.save_checkpoint(path); }));
  on_every_rank(path, [&](const std::string& local) { model.recut_from_checkpoint(local); });
}

}  // namespace

// --- Rank 0.

void LeadModel::configure(const YAML::Node& parameters, const cosim::RunInfo& run) {
  Buffer b;
  b.put(static_cast<std::int32_t>(kConfigure));
  b.put_string(parameters && !parameters.IsNull() ? YAML::Dump(parameters) : std::string());
  put_run(b, run);
  broadcast(b);
  agree(attempt([&] { model_.configure(parameters, run); }));
}

cosim::StepResult LeadModel::step(const cosim::StepInputs& in, bool want_average) {
  // The inputs are checked here, on rank 0 alone: a refused input never reaches the others.
  const std::vector<std::vector<ToolPose>> poses = model_.step_poses(in);
  Buffer b;
  b.put(static_cast<std::int32_t>(kStep));
  b.put(cosim::to_ns(in.t_start()));
  b.put(cosim::to_ns(in.t_end()));
  b.put(static_cast<std::int32_t>(want_average));
  b.put(static_cast<std::int64_t>(poses.size()));
  b.put(static_cast<std::int64_t>(poses.empty() ? 0 : poses.front().size()));
  for (const auto& at : poses)
    for (const ToolPose& p : at) b.put(p);
  broadcast(b);
  cosim::StepResult r;
  agree(attempt([&] { r = model_.step_with_poses(in.t_start(), in.t_end(), poses, want_average); }));
  return r;
}

void LeadModel::save_snapshot() {
  Buffer b;
  b.put(static_cast<std::int32_t>(kSave));
  broadcast(b);
  agree(attempt([&] { model_.save_snapshot(); }));
}

void LeadModel::restore_snapshot() {
  Buffer b;
  b.put(static_cast<std::int32_t>(kRestore));
  broadcast(b);
  agree(attempt([&] { model_.restore_snapshot(); }));
}

void LeadModel::save_checkpoint(const std::string& path) {
  Buffer b;
  b.put(static_cast<std::int32_t>(kSaveCheckpoint));
  b.put_string(path);
  broadcast(b);
  save_on_every_rank(model_, path);
}

void LeadModel::load_checkpoint(const std::string& path) {
  Buffer b;
  b.put(static_cast<std::int32_t>(kLoadCheckpoint));
  b.put_string(path);
  broadcast(b);
  load_on_every_rank(model_, path);
}

void end_followers() {
  // Called from a handler (run_participant threw), rank 0 does not finish its session: the
  // others must not wait in finish()'s gathers for it.
  const bool finishing = std::current_exception() == nullptr;
  Buffer b;
  b.put(static_cast<std::int32_t>(kEnd));
  b.put(static_cast<std::int32_t>(finishing));
  broadcast(b);
}

// --- Ranks 1..N-1.

int follow(ServiceModel& model) {
  for (;;) {
    Buffer b;
    broadcast(b);
    const auto command = b.get<std::int32_t>();
    try {
      switch (command) {
        case kConfigure: {
          const std::string text = b.get_string();
          const YAML::Node parameters = text.empty() ? YAML::Node() : YAML::Load(text);
          const cosim::RunInfo run = get_run(b);
          agree(attempt([&] { model.configure(parameters, run); }));
          break;
        }
        case kStep: {
          const cosim::TimePoint t0 = cosim::time_point_ns(b.get<std::int64_t>());
          const cosim::TimePoint t1 = cosim::time_point_ns(b.get<std::int64_t>());
          const bool want_average = b.get<std::int32_t>() != 0;
          const auto n = static_cast<std::size_t>(b.get<std::int64_t>());
          const auto tools = static_cast<std::size_t>(b.get<std::int64_t>());
          std::vector<std::vector<ToolPose>> poses(n, std::vector<ToolPose>(tools));
          for (auto& at : poses)
            for (ToolPose& p : at) p = b.get<ToolPose>();
          agree(attempt([&] { model.step_with_poses(t0, t1, poses, want_average); }));
          break;
        }
        case kSave: agree(attempt([&] { model.save_snapshot(); })); break;
        case kRestore: agree(attempt([&] { model.restore_snapshot(); })); break;
        case kSaveCheckpoint: save_on_every_rank(model, b.get_string()); break;
        case kLoadCheckpoint: load_on_every_rank(model, b.get_string()); break;
        case kEnd:
          if (b.get<std::int32_t>() == 0 && the_driver) the_driver->detach();
          return 0;
        default: throw std::logic_error("dem_service: unknown command from rank 0");
      }
    } catch (const std::invalid_argument&) {
      // An agreed refusal (below: a logic_error of this program, which ends it).
    } catch (const std::logic_error&) {
      throw;
    } catch (const std::exception&) {
      // Agreed: rank 0 replies with it; the master decides what follows (commands or the end).
    }
  }
}

}  // namespace dem::mpi
