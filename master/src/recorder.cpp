#include "recorder.hpp"

#include "cosim/bus.hpp"
#include "cosim/files.hpp"
#include "cosim/h5.hpp"
#include "cosim/timer.hpp"

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <stdexcept>

namespace master {

void write_number(hid_t file, const std::string& group, const std::string& name, double value) {
  if (H5Lexists(file, group.c_str(), H5P_DEFAULT) <= 0) {
    const hid_t g = H5Gcreate2(file, group.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g >= 0) H5Gclose(g);
  }
  const hid_t g = H5Gopen2(file, group.c_str(), H5P_DEFAULT);
  if (g < 0) return;
  cosim::h5::write(g, name, std::vector<double>{value});
  H5Gclose(g);
}

namespace {

// The records of one run (its HDF5 file and CSV export): when one cannot be written, none of
// them replaces the earlier file of its name. Writers alive at the same time share one group.
struct RecordGroup {
  bool failed = false;
};
std::shared_ptr<RecordGroup> join_record_group() {
  static std::weak_ptr<RecordGroup> current;
  auto g = current.lock();
  if (!g) {
    g = std::make_shared<RecordGroup>();
    current = g;
  }
  return g;
}

// The message for a failed write of the record at `path`: names the file and the cause.
std::string record_failure(const std::string& path, const std::string& what) {
  if (what.rfind("cannot write '", 0) == 0) return what;  // already says which file
  return cosim::write_failure(path, what);
}

// The file descriptor HDF5 writes `file` through (sec2 driver), or -1.
int file_descriptor(hid_t file) {
  void* handle = nullptr;
  if (H5Fget_vfd_handle(file, H5P_DEFAULT, &handle) < 0 || !handle) return -1;
  return *static_cast<int*>(handle);
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using cosim::h5::Table;

// A recorded series: a table of `width` doubles per step, with its unit.
std::unique_ptr<Table> table(hid_t parent, const std::string& name, std::size_t width,
                             const std::string& units = "") {
  auto t = std::make_unique<Table>(parent, name, width);
  if (!units.empty()) t->attribute("units", units);
  return t;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ",") + x;
  return s;
}


// The bus counters (docs/output.md): totals under /bus, per participant under its group.
void write_bus_stats(hid_t file, const RunSetup& setup) {
  const cosim::ExchangeStats& st = *setup.bus;
  write_number(file, "bus", "resends", static_cast<double>(st.resends));
  write_number(file, "bus", "dropped_by_plan", static_cast<double>(st.dropped_by_plan));
  write_number(file, "bus", "ignored_replies", static_cast<double>(st.ignored_replies));
  // Authentication (docs/security.md): what the master's end of the bus accepted and dropped.
  const auto& au = st.auth;
  write_number(file, "bus/auth", "keyed", au.keyed ? 1.0 : 0.0);
  write_number(file, "bus/auth", "accepted", static_cast<double>(au.counts.accepted));
  write_number(file, "bus/auth", "malformed", static_cast<double>(au.counts.malformed));
  write_number(file, "bus/auth", "forged", static_cast<double>(au.counts.forged));
  write_number(file, "bus/auth", "other_session", static_cast<double>(au.counts.other_session));
  write_number(file, "bus/auth", "replayed", static_cast<double>(au.counts.replayed));
  write_number(file, "bus/auth", "unreadable", static_cast<double>(au.unreadable));
  write_number(file, "bus/auth", "truncated", static_cast<double>(au.truncated));
  for (const auto& [name, info] : setup.participants) {
    const std::string g = "participants/" + name + "/bus";
    auto value = [&](const auto& m) { auto it = m.find(name); return it == m.end() ? 0.0 : static_cast<double>(it->second); };
    write_number(file, g, "resends", value(st.resends_to));
    write_number(file, g, "resend_timeout", value(st.resend_timeout_s));
    write_number(file, g, "round_trip_smoothed", value(st.srtt_s));
    write_number(file, g, "configure_sends", value(st.configure_sends));
  }
}

bool exists(hid_t file, const std::string& path) {
  // Every parent must exist before H5Lexists may ask about a child.
  std::size_t pos = 0;
  while ((pos = path.find('/', pos + 1)) != std::string::npos)
    if (H5Lexists(file, path.substr(0, pos).c_str(), H5P_DEFAULT) <= 0) return false;
  return H5Lexists(file, path.c_str(), H5P_DEFAULT) > 0;
}

void remove_if_present(hid_t file, const std::string& path) {
  if (exists(file, path)) H5Ldelete(file, path.c_str(), H5P_DEFAULT);
}

// Overwrites the one number of an existing 1-element dataset.
void set_number(hid_t file, const std::string& path, double value) {
  cosim::h5::Handle d(H5Dopen2(file, path.c_str(), H5P_DEFAULT), H5Dclose);
  if (!d.ok() || H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value) < 0)
    throw std::runtime_error("HDF5: cannot write '" + path + "'");
}

// Names of the datasets directly under a group.
std::vector<std::string> children(hid_t file, const std::string& group) {
  std::vector<std::string> out;
  if (!exists(file, group)) return out;
  cosim::h5::Handle g(H5Gopen2(file, group.c_str(), H5P_DEFAULT), H5Gclose);
  H5Literate(
      g, H5_INDEX_NAME, H5_ITER_INC, nullptr,
      [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
        static_cast<std::vector<std::string>*>(data)->push_back(name);
        return 0;
      },
      &out);
  return out;
}

}  // namespace

struct H5Recorder::Impl {
  std::string path;
  // Renamed onto `path` when the run starts (a resume: the record itself, with a copy of it
  // kept); the earlier file stays beside it until this one is closed.
  std::unique_ptr<cosim::StagedFile> staged;
  std::shared_ptr<RecordGroup> group = join_record_group();
  bool failed = false;  // a write, flush or close failed: this record is not kept
  bool closed = false;  // closed successfully
  hid_t file = -1;
  const RunSetup* setup = nullptr;
  std::unique_ptr<Table> time;
  std::map<std::string, std::unique_ptr<Table>> outputs;  // "participant/signal"
  std::map<std::string, std::unique_ptr<Table>> diagnostics;
  std::map<std::string, std::unique_ptr<Table>> compute, round_trip;
  std::unique_ptr<Table> master_s, wall_s, iterations;
  // received_average: use: average connections only (else null).
  struct Conn { std::unique_ptr<Table> sent, predicted, received, received_average, deviation; int width = 0; };
  std::vector<Conn> conns;
  struct Pow { std::unique_ptr<Table> force_side, motion_side, residual, energy_residual; double energy = 0; double last = kNaN; };
  std::vector<Pow> pows;
  std::unique_ptr<Table> coupling_residual;  // coupling.type: implicit only
  std::unique_ptr<Table> step_error, rejected;  // coupling.adaptive only
  cosim::Stopwatch since_flush;
  bool resume = false;  // continue an existing record (H5Recorder(Continue, ...))
  bool checkpoints = false;  // the record has /checkpoint (RunSetup::run_id != 0)
  int64_t checkpoint_steps = 0;  // what /checkpoint/steps_done says

  void start_new(const RunSetup& s);
  void continue_existing(const RunSetup& s);
  void drop_tables() {
    outputs.clear(), diagnostics.clear(), compute.clear(), round_trip.clear();
    conns.clear(), pows.clear();
    time.reset(), master_s.reset(), wall_s.reset(), iterations.reset();
    coupling_residual.reset(), step_error.reset(), rejected.reset();
  }
  // After a failed write: the file is closed as far as HDF5 still can, and taken off its name
  // (nothing else of this run may write it); the destructor puts the earlier file back.
  void abandon() {
    failed = true;
    group->failed = true;
    drop_tables();
    if (file >= 0) H5Fclose(file);  // fails on a broken file; the process can still exit cleanly
    file = -1;
    if (staged && staged->committed()) std::remove(path.c_str());
  }
  // Runs f; a failure to write marks this record failed and raises the message naming the file.
  template <class F>
  void checked(F&& f) {
    if (failed) throw std::runtime_error("the record '" + path + "' could not be written before");
    try {
      f();
    } catch (const std::exception& e) {
      const std::string message = record_failure(path, e.what());
      abandon();
      throw std::runtime_error(message);
    }
  }

  void flush_all() {
    auto f = [](auto& m) { for (auto& [k, t] : m) t->flush(); };
    time->flush();
    f(outputs); f(diagnostics); f(compute); f(round_trip);
    master_s->flush(); wall_s->flush(); iterations->flush();
    for (auto& c : conns) {
      c.sent->flush(), c.predicted->flush(), c.received->flush(), c.deviation->flush();
      if (c.received_average) c.received_average->flush();
    }
    for (auto& p : pows) p.force_side->flush(), p.motion_side->flush(), p.residual->flush(), p.energy_residual->flush();
    if (coupling_residual) coupling_residual->flush();
    if (step_error) step_error->flush(), rejected->flush();
    cosim::h5::flush(file, path);
  }
};

H5Recorder::H5Recorder(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  impl_->staged = std::make_unique<cosim::StagedFile>(path);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  impl_->file = H5Fcreate(impl_->staged->current().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (impl_->file < 0)
    throw std::runtime_error("cannot create output file '" + path + "' (" + cosim::h5::error_cause() +
                             "): check that its folder exists and is writable (output.file / --output)");
}

H5Recorder::H5Recorder(Continue, const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  impl_->resume = true;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  // A copy of the record as it is, put back if this run cannot write it.
  impl_->staged = std::make_unique<cosim::StagedFile>(cosim::StagedFile::InPlace{}, path);
  impl_->file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  if (impl_->file < 0)
    throw std::runtime_error("cannot open the record '" + path + "' for writing: check that it exists and is writable");
}

H5Recorder::~H5Recorder() {
  auto& I = *impl_;
  if (I.file >= 0) {  // on_finish never ran: the file stays as the last flush left it
    I.drop_tables();
    H5Fclose(I.file);
  }
  if (!I.staged) return;
  if (I.group->failed && I.staged->committed()) {
    // This record, or another of the run (its CSV), could not be written.
    if (!I.failed) std::remove(I.path.c_str());
    std::cerr << "cosim_master: " << I.staged->restore() << "\n";
  } else if (I.closed) {
    I.staged->done();
  }
}

void H5Recorder::on_start(const RunSetup& s) {
  auto& I = *impl_;
  I.setup = &s;
  I.checkpoints = s.run_id != 0;
  I.checked([&] {
    // Not complete until the run finished and the file closed (docs/output.md).
    cosim::h5::set_int_attribute(I.file, "complete", 0);
    if (I.resume) I.continue_existing(s);
    else I.start_new(s);
    if (I.checkpoints) {
      // The checkpoint the participants and this record agree on so far (steps_done 0: none).
      set_number(I.file, "checkpoint/steps_done", static_cast<double>(s.first_step));
      I.checkpoint_steps = s.first_step;
      set_number(I.file, "checkpoint/time", cosim::to_seconds(s.first_time));
    }
    I.flush_all();
    // The run has started: now the file replaces one of its name (kept aside until closed).
    I.staged->commit();
  });
}

void H5Recorder::Impl::continue_existing(const RunSetup& s) {
  auto& I = *this;
  const Config& c = *s.config;
  const std::size_t keep = static_cast<std::size_t>(s.first_step) + 1;  // row 0: t_start
  using cosim::h5::Table;
  auto open = [&](const std::string& name) { return std::make_unique<Table>(Table::Existing{}, I.file, name, keep); };
  // What the interrupted run wrote at its end is rewritten at this one's.
  remove_if_present(I.file, "status");
  remove_if_present(I.file, "bus");
  I.time = open("time");
  I.master_s = open("timing/master");
  I.wall_s = open("timing/step_wall");
  I.iterations = open("timing/iterations");
  for (const auto& [name, info] : s.participants) {
    remove_if_present(I.file, "participants/" + name + "/bus");
    for (const auto& port : info.outputs)
      I.outputs[name + "/" + port.name] = open("participants/" + name + "/outputs/" + port.name);
    for (const auto& key : children(I.file, "participants/" + name + "/diagnostics"))
      I.diagnostics[name + "/" + key] = open("participants/" + name + "/diagnostics/" + key);
    I.compute[name] = open("participants/" + name + "/timing/compute");
    I.round_trip[name] = open("participants/" + name + "/timing/round_trip");
  }
  for (const auto& k : c.connections) {
    const std::string g = "connections/" + k.to.str();
    Impl::Conn cr;
    cr.sent = open(g + "/sent");
    cr.width = static_cast<int>(cr.sent->width());
    cr.predicted = open(g + "/predicted");
    cr.received = open(g + "/received");
    cr.deviation = open(g + "/deviation");
    if (k.use == Use::Average) cr.received_average = open(g + "/received_average");
    I.conns.push_back(std::move(cr));
  }
  for (const auto& p : c.power) {
    Impl::Pow pw;
    const std::string g = "power/" + p.name;
    pw.force_side = open(g + "/force_side");
    pw.motion_side = open(g + "/motion_side");
    pw.residual = open(g + "/residual");
    pw.energy_residual = open(g + "/energy_residual");
    // The running sums on_step continues: the energy so far and the last residual (NaN at
    // row 0, as in a run that starts there).
    pw.energy = cosim::h5::read_doubles(I.file, g + "/energy_residual").at(keep - 1);
    pw.last = cosim::h5::read_doubles(I.file, g + "/residual").at(keep - 1);
    I.pows.push_back(std::move(pw));
  }
  if (c.coupling.type == CouplingType::Implicit) I.coupling_residual = open("coupling/residual");
  if (c.coupling.adaptive.enabled) I.step_error = open("coupling/step_error"), I.rejected = open("coupling/rejected");
  if (I.checkpoints) {
    Table resumed(Table::Existing{}, I.file, "checkpoint/resumed_at",
                  cosim::h5::rows(I.file, "checkpoint/resumed_at"));
    resumed.append(static_cast<double>(s.first_step));
    resumed.flush();
  }
}

void H5Recorder::Impl::start_new(const RunSetup& s) {
  auto& I = *this;
  const Config& c = *s.config;
  cosim::h5::write_string(I.file, "config", c.source_text);
  cosim::h5::write_string(I.file, "config_effective", c.effective_yaml);
  I.time = table(I.file, "time", 1, "s");
  I.master_s = table(I.file, "timing/master", 1, "s");
  I.wall_s = table(I.file, "timing/step_wall", 1, "s");
  I.iterations = table(I.file, "timing/iterations", 1);
  I.time->append(cosim::to_seconds(c.t_start));
  I.master_s->append(0.0);
  I.wall_s->append(0.0);
  I.iterations->append(0.0);
  for (const auto& [name, info] : s.participants) {
    for (const auto& port : info.outputs) {
      auto t = table(I.file, "participants/" + name + "/outputs/" + port.name,
                                       cosim::value_size(port.kind));
      t->attribute("kind", std::string(cosim::kind_name(port.kind)));
      t->attribute("components", join(cosim::component_names(port.kind)));
      t->append(info.initial_outputs.at(port.name).value);
      I.outputs[name + "/" + port.name] = std::move(t);
    }
    I.compute[name] = table(I.file, "participants/" + name + "/timing/compute", 1, "s");
    I.round_trip[name] = table(I.file, "participants/" + name + "/timing/round_trip", 1, "s");
    I.compute[name]->append(0.0);
    I.round_trip[name]->append(0.0);
  }
  for (const auto& k : c.connections) {
    const auto& src = s.participants.at(k.from.participant);
    cosim::SignalKind kind = cosim::SignalKind::Scalar;
    for (const auto& p : src.outputs) if (p.name == k.from.signal) kind = p.kind;
    const std::string g = "connections/" + k.to.str();
    Impl::Conn cr;
    const int tw = cosim::tangent_size(kind);
    cr.width = (k.predictor.order + 1) * tw;
    cr.sent = table(I.file, g + "/sent", cr.width);
    cr.sent->attribute("layout", "coefficient j (multiplies s^j, s = (t - t_start)/macro_step) x tangent component, row-major; orientation as rotation vector relative to the latest sample");
    cr.predicted = table(I.file, g + "/predicted", cosim::value_size(kind));
    cr.received = table(I.file, g + "/received", cosim::value_size(kind));
    cr.deviation = table(I.file, g + "/deviation", tw);
    cr.predicted->attribute("source", k.from.str());
    cr.predicted->attribute("components", join(cosim::component_names(kind)));
    cr.predicted->attribute("use", use_name(k.use));
    cr.predicted->attribute("meaning", k.use == Use::Average
                                           ? "mean of the sent polynomial over the step"
                                           : "the sent polynomial at the step's end");
    if (k.use == Use::Average) {
      cr.received_average = table(I.file, g + "/received_average", cosim::value_size(kind));
      cr.received_average->attribute("source", k.from.str());
      cr.received_average->attribute("meaning", "the source's mean over the step ending at time[i]");
      cr.received_average->append(std::vector<double>(cosim::value_size(kind), kNaN));
    }
    cr.sent->append(kNaN);
    cr.predicted->append(kNaN);
    cr.received->append(src.initial_outputs.at(k.from.signal).value);
    cr.deviation->append(kNaN);
    I.conns.push_back(std::move(cr));
  }
  for (const auto& p : c.power) {
    Impl::Pow pw;
    const std::string g = "power/" + p.name;
    pw.force_side = table(I.file, g + "/force_side", 1, "W");
    pw.motion_side = table(I.file, g + "/motion_side", 1, "W");
    pw.residual = table(I.file, g + "/residual", 1, "W");
    pw.energy_residual = table(I.file, g + "/energy_residual", 1, "J");
    pw.force_side->append(kNaN);
    pw.motion_side->append(kNaN);
    pw.residual->append(kNaN);
    pw.energy_residual->append(0.0);
    I.pows.push_back(std::move(pw));
  }
  if (c.coupling.type == CouplingType::Implicit) {  // docs/output.md#implicit-coupling
    I.coupling_residual = table(I.file, "coupling/residual", c.coupling.convergence.size());
    std::vector<std::string> names;
    for (const auto& cs : c.coupling.convergence)
      names.push_back(c.connections[cs.connection].to.str() + " " + measure_name(cs.measure));
    I.coupling_residual->attribute("columns", join(names));
    I.coupling_residual->append(std::vector<double>(c.coupling.convergence.size(), kNaN));
  }
  if (c.coupling.adaptive.enabled) {  // docs/output.md#adaptive-macro-step
    I.step_error = table(I.file, "coupling/step_error", 1);
    I.step_error->attribute("meaning", "the adaptive step controller's error estimate of the step ending at time[i] (<= 1: within tolerance)");
    I.rejected = table(I.file, "coupling/rejected", 1);
    I.rejected->attribute("meaning", "attempts of the step ending at time[i] rejected and redone shorter before it (coupling.adaptive.reject_above)");
    I.step_error->append(kNaN);
    I.rejected->append(0.0);
  }
  if (I.checkpoints) {
    // docs/output.md#checkpoints-and-resume
    write_number(I.file, "checkpoint", "steps_done", 0.0);
    write_number(I.file, "checkpoint", "time", cosim::to_seconds(c.t_start));
    write_number(I.file, "checkpoint", "every", cosim::to_seconds(c.checkpoints.every));
    Table(I.file, "checkpoint/resumed_at", 1).attribute(
        "meaning", "steps done when the run was resumed (cosim_master --resume), one row per resume");
    cosim::h5::Handle g(H5Gopen2(I.file, "checkpoint", H5P_DEFAULT), H5Gclose);
    cosim::h5::write_string_attribute(g, "run_id", cosim::id_hex(s.run_id));
    cosim::h5::write_string_attribute(g, "folder", s.checkpoint_folder);
    std::error_code ec;
    cosim::h5::write_string_attribute(
        g, "csv", c.output.csv_file.empty() ? std::string() : std::filesystem::absolute(c.output.csv_file, ec).string());
  }
}

int64_t H5Recorder::checkpoint_steps() const { return impl_->checkpoint_steps; }

bool H5Recorder::started() const { return !impl_->failed && impl_->staged->committed(); }

void H5Recorder::on_step(const StepRecord& r) {
  impl_->checked([&] { step(r); });
}

void H5Recorder::step(const StepRecord& r) {
  auto& I = *impl_;
  const Config& c = *I.setup->config;
  I.time->append(cosim::to_seconds(r.t_end));
  I.master_s->append(r.master_seconds);
  I.wall_s->append(r.wall_seconds);
  I.iterations->append(r.iterations);
  if (I.coupling_residual) I.coupling_residual->append(r.coupling_residuals);
  if (I.step_error) I.step_error->append(r.step_error), I.rejected->append(static_cast<double>(r.rejected));
  for (const auto& [name, sigs] : r.outputs)
    for (const auto& [sig, v] : sigs) I.outputs.at(name + "/" + sig)->append(v.value);
  for (const auto& [name, diags] : r.diagnostics)
    for (const auto& [key, v] : diags) {
      auto& t = I.diagnostics[name + "/" + key];
      if (!t) {
        t = table(I.file, "participants/" + name + "/diagnostics/" + key, 1);
        for (int64_t i = 0; i <= r.step_index; ++i) t->append(kNaN);  // rows before it appeared
      }
    }
  for (const auto& [name, diags] : r.diagnostics)
    for (const auto& [key, v] : diags) I.diagnostics[name + "/" + key]->append(v);
  for (const auto& [name, v] : r.compute_seconds) I.compute.at(name)->append(v);
  for (const auto& [name, v] : r.round_trip_seconds) I.round_trip.at(name)->append(v);
  for (std::size_t i = 0; i < r.connections.size(); ++i) {
    const auto& cr = r.connections[i];
    std::vector<double> coeff = cr.sent.coefficients;
    coeff.resize(static_cast<std::size_t>(I.conns[i].width), 0.0);  // lower order at start-up
    I.conns[i].sent->append(coeff);
    I.conns[i].predicted->append(cr.predicted);
    I.conns[i].received->append(cr.received);
    if (I.conns[i].received_average) I.conns[i].received_average->append(cr.received_average);
    I.conns[i].deviation->append(cr.deviation);
  }
  // The step's own length: an adaptive step's is not time.macro_step.
  const double h = cosim::to_seconds(r.t_end - r.t_start);
  for (std::size_t i = 0; i < r.power.size(); ++i) {
    auto& p = I.pows[i];
    p.force_side->append(r.power[i].force_side);
    p.motion_side->append(r.power[i].motion_side);
    p.residual->append(r.power[i].residual);
    // trapezoid over macro steps; the first step counts its end value only
    p.energy += std::isnan(p.last) ? r.power[i].residual * h : 0.5 * (p.last + r.power[i].residual) * h;
    p.last = r.power[i].residual;
    p.energy_residual->append(p.energy);
  }
  if (r.checkpoint && I.checkpoints) {
    // Every participant has its checkpoint after this step: with the rows up to here on disk
    // first, the record now says a resume may start here.
    I.flush_all();
    // The coupling algorithm's state after this step (implicit, adaptive), for the resume.
    remove_if_present(I.file, "checkpoint/algorithm_state");
    if (!r.algorithm_state.empty()) cosim::h5::write_string(I.file, "checkpoint/algorithm_state", r.algorithm_state);
    set_number(I.file, "checkpoint/steps_done", static_cast<double>(r.step_index + 1));
    I.checkpoint_steps = r.step_index + 1;
    set_number(I.file, "checkpoint/time", cosim::to_seconds(r.t_end));
    cosim::h5::flush(I.file, I.path);
    I.since_flush.restart();
  } else if (I.since_flush.seconds() > 1.0) {
    I.flush_all();
    I.since_flush.restart();
  }
}

void H5Recorder::on_finish(bool ok, const std::string& message) {
  auto& I = *impl_;
  if (I.failed || I.file < 0) return;
  if (I.group->failed) {  // the CSV could not be written: this record is not kept either
    I.abandon();
    return;
  }
  try {
    I.checked([&] {
      if (I.time) {
        I.flush_all();
        cosim::h5::write_string(I.file, "status", ok ? "finished" : "stopped: " + message);
        if (ok && !message.empty()) cosim::h5::write_string(I.file, "ended", message);  // a participant ended the run
        if (I.setup && I.setup->bus) write_bus_stats(I.file, *I.setup);
        cosim::h5::set_int_attribute(I.file, "complete", ok ? 1 : 0);
        cosim::h5::flush(I.file, I.path);
        // On the disk before it replaces the earlier file for good.
        if (const int fd = file_descriptor(I.file); fd >= 0 && ::fsync(fd) != 0 && errno != EINVAL)
          throw std::runtime_error(cosim::write_failure(I.path, std::strerror(errno)));
      }
      I.drop_tables();
      const hid_t f = I.file;
      I.file = -1;
      cosim::h5::close(f, I.path);
      I.closed = true;
    });
  } catch (const std::exception& e) {
    // The run stopped for another reason and says so; this is the record's own failure.
    if (!ok) {
      std::cerr << "cosim_master: " << e.what() << "\n";
      return;
    }
    throw;  // the run did not finish: no "finished", a non-zero exit
  }
}

// ---------------------------------------------------------------------------------------------

struct CsvWriter::Shared {
  std::shared_ptr<RecordGroup> group = join_record_group();
};

CsvWriter::CsvWriter(const std::string& path)
    : path_(path), staged_(std::make_unique<cosim::StagedFile>(path)), shared_(std::make_unique<Shared>()) {
  file_ = std::fopen(staged_->current().c_str(), "w");
  if (!file_)
    throw std::runtime_error("cannot create CSV file '" + path + "': " + std::strerror(errno) +
                             ": check that its folder exists (output.csv / --csv)");
}

CsvWriter::~CsvWriter() {
  if (file_) std::fclose(file_);
  if (shared_->group->failed && staged_->committed()) {
    if (!failed_) std::remove(path_.c_str());
    std::cerr << "cosim_master: " << staged_->restore() << "\n";
  } else if (closed_) {
    staged_->done();
  }
}

void CsvWriter::fail() {
  // errno of the failed stdio call: "No space left on device", "File too large", ...
  const std::string message = cosim::write_failure(path_, std::strerror(errno));
  failed_ = true;
  shared_->group->failed = true;
  if (file_) std::fclose(file_);
  file_ = nullptr;
  if (staged_->committed()) std::remove(path_.c_str());  // the destructor puts the earlier one back
  throw std::runtime_error(message);
}

void CsvWriter::check_writable() const {
  if (failed_ || !file_)
    throw std::runtime_error("the CSV export '" + path_ + "' could not be written before");
}

void CsvWriter::on_start(const RunSetup& s) {
  check_writable();
  if (std::fprintf(file_, "time") < 0) fail();
  for (const auto& [name, info] : s.participants)
    for (const auto& port : info.outputs) {
      columns_.emplace_back(name, port.name);
      for (const auto& comp : cosim::component_names(port.kind)) {
        const int n = port.kind == cosim::SignalKind::Scalar
                          ? std::fprintf(file_, ",%s.%s", name.c_str(), port.name.c_str())
                          : std::fprintf(file_, ",%s.%s.%s", name.c_str(), port.name.c_str(), comp.c_str());
        if (n < 0) fail();
      }
    }
  if (std::fprintf(file_, "\n") < 0) fail();
  std::map<std::string, cosim::Signals> initial;
  for (const auto& [name, info] : s.participants) initial[name] = info.initial_outputs;
  if (continue_from_.empty()) {
    row(s.config->t_start, initial);
  } else {
    // The rows up to the resume point, from the record: the values on_step was given then.
    cosim::h5::Handle f(H5Fopen(continue_from_.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!f.ok()) throw std::runtime_error("cannot read the record '" + continue_from_ + "' for the CSV");
    std::map<std::string, std::vector<double>> data;
    const auto times = cosim::h5::read_doubles(f, "time");  // an adaptive step's are not i macro steps
    if (times.size() < static_cast<std::size_t>(s.first_step) + 1)
      throw std::runtime_error("the record '" + continue_from_ + "' is shorter than its checkpoint");
    for (const auto& [name, sig] : columns_)
      data[name + "/" + sig] = cosim::h5::read_doubles(f, "participants/" + name + "/outputs/" + sig);
    for (int64_t i = 0; i <= s.first_step; ++i) {
      std::map<std::string, cosim::Signals> outputs = initial;
      for (const auto& [name, sig] : columns_) {
        auto& v = outputs[name][sig].value;
        const auto& all = data.at(name + "/" + sig);
        const std::size_t w = v.size();
        if (all.size() < (static_cast<std::size_t>(i) + 1) * w)
          throw std::runtime_error("the record '" + continue_from_ + "' is shorter than its checkpoint");
        v.assign(all.begin() + static_cast<std::ptrdiff_t>(i * w), all.begin() + static_cast<std::ptrdiff_t>((i + 1) * w));
      }
      row(s.config->coupling.adaptive.enabled
              ? TimePoint(Duration(std::llround(times[static_cast<std::size_t>(i)] * 1e9)))
              : s.config->t_start + i * s.config->macro_step,
          outputs);
    }
  }
  if (std::fflush(file_) != 0) fail();
  staged_->commit();
}

void CsvWriter::row(TimePoint t, const std::map<std::string, cosim::Signals>& outputs) {
  check_writable();
  // A failed write shows in the return value of the call that flushes stdio's buffer.
  if (std::fprintf(file_, "%.9f", cosim::to_seconds(t)) < 0) fail();
  for (const auto& [name, sig] : columns_)
    for (double v : outputs.at(name).at(sig).value)
      if (std::fprintf(file_, ",%.17g", v) < 0) fail();
  if (std::fprintf(file_, "\n") < 0) fail();
}

void CsvWriter::on_step(const StepRecord& r) { row(r.t_end, r.outputs); }

void CsvWriter::on_finish(bool ok, const std::string&) {
  if (failed_ || !file_) return;
  if (shared_->group->failed) {  // the HDF5 record could not be written: nor is this kept
    std::fclose(file_);
    file_ = nullptr;
    failed_ = true;
    if (staged_->committed()) std::remove(path_.c_str());
    return;
  }
  try {
    if (std::fflush(file_) != 0 || (::fsync(::fileno(file_)) != 0 && errno != EINVAL)) fail();
    std::FILE* f = file_;
    file_ = nullptr;
    if (std::fclose(f) != 0) {
      failed_ = true;  // as fail(), without a second fclose
      const std::string message = cosim::write_failure(path_, std::strerror(errno));
      shared_->group->failed = true;
      if (staged_->committed()) std::remove(path_.c_str());
      throw std::runtime_error(message);
    }
    closed_ = true;
  } catch (const std::exception& e) {
    if (!ok) {  // the run stopped for another reason and says so
      std::cerr << "cosim_master: " << e.what() << "\n";
      return;
    }
    throw;
  }
}

// ---------------------------------------------------------------------------------------------

void Progress::on_start(const RunSetup& s) {
  setup_ = &s;
  run_wall_.restart();
  since_print_.restart();
  // A resumed run counts on from its resume point; rates are of this process's steps.
  steps_done_ = s.first_step;
  t_begin_ = t_done_ = s.first_time;
}

void Progress::on_step(const StepRecord& r) {
  ++steps_done_;
  t_done_ = r.t_end;
  wall_steps_ += r.wall_seconds;
  master_ += r.master_seconds;
  for (const auto& [n, v] : r.compute_seconds) compute_[n] += v;
  for (const auto& [n, v] : r.round_trip_seconds) round_trip_[n] += v;
  iterations_ += r.iterations;
  rejected_ += r.rejected;
  ++steps_here_;
  if (!live_ || since_print_.seconds() < 1.0) return;
  since_print_.restart();
  const double wall = run_wall_.seconds();
  const double sim = cosim::to_seconds(t_done_ - t_begin_);
  const double done = cosim::to_seconds(t_done_ - setup_->config->t_start);
  const double total = cosim::to_seconds(setup_->config->t_end - setup_->config->t_start);
  const double eta = sim > 0 ? wall / sim * (total - done) : 0;
  const bool adaptive = setup_->config->coupling.adaptive.enabled;
  char steps[96];  // an adaptive run's step count is known only at its end
  if (adaptive)
    std::snprintf(steps, sizeof steps, "step %lld (H %.3g s, %lld rejected)", static_cast<long long>(steps_done_),
                  cosim::to_seconds(r.t_end - r.t_start), static_cast<long long>(rejected_));
  else
    std::snprintf(steps, sizeof steps, "step %lld/%lld", static_cast<long long>(steps_done_),
                  static_cast<long long>(setup_->steps));
  std::fprintf(stderr, "\rt = %.4f / %.4f s (%3.0f%%)  %s  real-time factor %.3g  ETA %.0f s   ",
               cosim::to_seconds(t_done_), cosim::to_seconds(setup_->config->t_end), 100 * done / total, steps,
               wall / sim, eta);
  if (setup_->config->coupling.type == CouplingType::Implicit && !r.coupling_residuals.empty())
    std::fprintf(stderr, "iterations %d (mean %.2f)  |r| %.2e   ", r.iterations,
                 static_cast<double>(iterations_) / static_cast<double>(steps_here_), r.coupling_residuals[0]);
  std::fflush(stderr);  // stderr is line-buffered and this line ends in \r
}

void Progress::on_finish(bool ok, const std::string& message) {
  if (!setup_) return;
  if (live_) std::fprintf(stderr, "\n");
  const double wall = run_wall_.seconds();
  const double sim = cosim::to_seconds(t_done_ - t_begin_);
  char title[256], steps[96];
  if (setup_->config->coupling.adaptive.enabled)
    std::snprintf(steps, sizeof steps, "%lld adaptive macro steps (%lld rejected and redone)",
                  static_cast<long long>(steps_done_), static_cast<long long>(rejected_));
  else
    std::snprintf(steps, sizeof steps, "%lld of %lld macro steps", static_cast<long long>(steps_done_),
                  static_cast<long long>(setup_->steps));
  std::snprintf(title, sizeof title, "%s after %s, t = %.6g s, wall %.3f s, real-time factor %.3g",
                ok ? "finished" : "STOPPED", steps, cosim::to_seconds(t_done_), wall, sim > 0 ? wall / sim : 0.0);
  // Rows named after the recorded timing datasets (docs/output.md).
  std::vector<cosim::TimingRow> rows;
  for (const auto& [n, v] : compute_) {
    rows.push_back({n + ".compute", v});
    rows.push_back({n + ".bus_wait", round_trip_[n] - v});
  }
  rows.push_back({"master", master_});
  rows.push_back({"other", wall - wall_steps_});
  cosim::print_timing_table(
      std::cerr, title, rows, wall,
      {"<p>.compute: inside the participant's step; <p>.bus_wait: round_trip - compute;",
       "master: predictors and records; other: outside the steps (handshake, start-up).",
       "Participants that step in parallel share the wall time: the shares may add to more "
       "than 100 %."});
  if (setup_->bus) {  // per participant; the totals follow from cosim_master (docs/protocol.md)
    std::string line = "cosim_master: bus:";
    char buf[200];
    for (const auto& [name, info] : setup_->participants) {
      auto get = [&](const auto& m) { auto it = m.find(name); return it == m.end() ? 0.0 : static_cast<double>(it->second); };
      std::snprintf(buf, sizeof buf, " %s %.0f resent (resend timeout %.1f ms, network round trip %.3f ms);",
                    name.c_str(), get(setup_->bus->resends_to), 1e3 * get(setup_->bus->resend_timeout_s),
                    1e3 * get(setup_->bus->srtt_s));
      line += buf;
    }
    std::fprintf(stderr, "%s\n", line.c_str());
  }
}

}  // namespace master
