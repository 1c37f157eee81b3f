#include "recorder.hpp"

#include <hdf5.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <stdexcept>

namespace master {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// An extendible 2-D dataset [rows x width] of doubles (1-D when width is 1) with rows
// buffered in memory and appended in blocks, so a run of many steps stays cheap.
class Table {
 public:
  Table(hid_t parent, const std::string& name, std::size_t width, const std::string& units = "")
      : width_(width) {
    const int rank = width == 1 ? 1 : 2;
    hsize_t dims[2] = {0, width}, maxdims[2] = {H5S_UNLIMITED, width};
    hsize_t chunk[2] = {256, width};
    hid_t space = H5Screate_simple(rank, dims, maxdims);
    hid_t props = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(props, rank, chunk);
    hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
    H5Pset_create_intermediate_group(lcpl, 1);
    id_ = H5Dcreate2(parent, name.c_str(), H5T_NATIVE_DOUBLE, space, lcpl, props, H5P_DEFAULT);
    H5Pclose(lcpl);
    H5Pclose(props);
    H5Sclose(space);
    if (id_ < 0) throw std::runtime_error("HDF5: cannot create dataset " + name);
    if (!units.empty()) attribute("units", units);
  }
  ~Table() { if (id_ >= 0) H5Dclose(id_); }
  Table(const Table&) = delete;
  Table& operator=(const Table&) = delete;

  void attribute(const std::string& key, const std::string& value) {
    hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, std::max<std::size_t>(1, value.size()));
    hid_t space = H5Screate(H5S_SCALAR);
    hid_t a = H5Acreate2(id_, key.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a, type, value.c_str());
    H5Aclose(a);
    H5Sclose(space);
    H5Tclose(type);
  }
  void append(const std::vector<double>& row) {
    if (row.size() == width_) buffer_.insert(buffer_.end(), row.begin(), row.end());
    else buffer_.insert(buffer_.end(), width_, kNaN);
  }
  void append(double v) { append(std::vector<double>{v}); }
  void flush() {
    const hsize_t n = buffer_.size() / width_;
    if (n == 0) return;
    const int rank = width_ == 1 ? 1 : 2;
    hsize_t size[2] = {rows_ + n, width_};
    H5Dset_extent(id_, size);
    hid_t file_space = H5Dget_space(id_);
    hsize_t start[2] = {rows_, 0}, count[2] = {n, width_};
    H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, count, nullptr);
    hid_t mem = H5Screate_simple(rank, count, nullptr);
    H5Dwrite(id_, H5T_NATIVE_DOUBLE, mem, file_space, H5P_DEFAULT, buffer_.data());
    H5Sclose(mem);
    H5Sclose(file_space);
    rows_ += n;
    buffer_.clear();
  }

 private:
  hid_t id_ = -1;
  std::size_t width_;
  hsize_t rows_ = 0;
  std::vector<double> buffer_;
};

void write_string(hid_t parent, const std::string& name, const std::string& value) {
  hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, std::max<std::size_t>(1, value.size()));
  hid_t space = H5Screate(H5S_SCALAR);
  hid_t d = H5Dcreate2(parent, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Dwrite(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, value.c_str());
  H5Dclose(d);
  H5Sclose(space);
  H5Tclose(type);
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ",") + x;
  return s;
}

}  // namespace

struct H5Recorder::Impl {
  std::string path;
  hid_t file = -1;
  const RunSetup* setup = nullptr;
  std::unique_ptr<Table> time;
  std::map<std::string, std::unique_ptr<Table>> outputs;  // "participant/signal"
  std::map<std::string, std::unique_ptr<Table>> diagnostics;
  std::map<std::string, std::unique_ptr<Table>> compute, round_trip;
  std::unique_ptr<Table> master_s, wall_s, iterations;
  struct Conn { std::unique_ptr<Table> sent, predicted, received, deviation; int width = 0; };
  std::vector<Conn> conns;
  struct Pow { std::unique_ptr<Table> force_side, motion_side, residual, energy_residual; double energy = 0; double last = kNaN; };
  std::vector<Pow> pows;
  std::chrono::steady_clock::time_point last_flush = std::chrono::steady_clock::now();

  void flush_all() {
    auto f = [](auto& m) { for (auto& [k, t] : m) t->flush(); };
    time->flush();
    f(outputs); f(diagnostics); f(compute); f(round_trip);
    master_s->flush(); wall_s->flush(); iterations->flush();
    for (auto& c : conns) c.sent->flush(), c.predicted->flush(), c.received->flush(), c.deviation->flush();
    for (auto& p : pows) p.force_side->flush(), p.motion_side->flush(), p.residual->flush(), p.energy_residual->flush();
    H5Fflush(file, H5F_SCOPE_GLOBAL);
  }
};

H5Recorder::H5Recorder(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  impl_->file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (impl_->file < 0)
    throw std::runtime_error("cannot create output file '" + path +
                             "': check that its folder exists and is writable (output.file / --output)");
}

H5Recorder::~H5Recorder() {
  if (impl_->file >= 0) {
    impl_->outputs.clear();
    H5Fclose(impl_->file);
  }
}

void H5Recorder::on_start(const RunSetup& s) {
  auto& I = *impl_;
  I.setup = &s;
  const Config& c = *s.config;
  write_string(I.file, "config", c.source_text);
  write_string(I.file, "config_effective", c.effective_yaml);
  I.time = std::make_unique<Table>(I.file, "time", 1, "s");
  I.master_s = std::make_unique<Table>(I.file, "timing/master", 1, "s");
  I.wall_s = std::make_unique<Table>(I.file, "timing/step_wall", 1, "s");
  I.iterations = std::make_unique<Table>(I.file, "timing/iterations", 1);
  I.time->append(cosim::to_seconds(c.t_start));
  I.master_s->append(0.0);
  I.wall_s->append(0.0);
  I.iterations->append(0.0);
  for (const auto& [name, info] : s.participants) {
    for (const auto& port : info.outputs) {
      auto t = std::make_unique<Table>(I.file, "participants/" + name + "/outputs/" + port.name,
                                       cosim::value_size(port.kind));
      t->attribute("kind", std::string(cosim::kind_name(port.kind)));
      t->attribute("components", join(cosim::component_names(port.kind)));
      t->append(info.initial_outputs.at(port.name).value);
      I.outputs[name + "/" + port.name] = std::move(t);
    }
    I.compute[name] = std::make_unique<Table>(I.file, "participants/" + name + "/timing/compute", 1, "s");
    I.round_trip[name] = std::make_unique<Table>(I.file, "participants/" + name + "/timing/round_trip", 1, "s");
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
    cr.sent = std::make_unique<Table>(I.file, g + "/sent", cr.width);
    cr.sent->attribute("layout", "coefficient j (multiplies s^j, s = (t - t_start)/macro_step) x tangent component, row-major; orientation as rotation vector relative to the latest sample");
    cr.predicted = std::make_unique<Table>(I.file, g + "/predicted", cosim::value_size(kind));
    cr.received = std::make_unique<Table>(I.file, g + "/received", cosim::value_size(kind));
    cr.deviation = std::make_unique<Table>(I.file, g + "/deviation", tw);
    cr.predicted->attribute("source", k.from.str());
    cr.predicted->attribute("components", join(cosim::component_names(kind)));
    cr.sent->append(kNaN);
    cr.predicted->append(kNaN);
    cr.received->append(src.initial_outputs.at(k.from.signal).value);
    cr.deviation->append(kNaN);
    I.conns.push_back(std::move(cr));
  }
  for (const auto& p : c.power) {
    Impl::Pow pw;
    const std::string g = "power/" + p.name;
    pw.force_side = std::make_unique<Table>(I.file, g + "/force_side", 1, "W");
    pw.motion_side = std::make_unique<Table>(I.file, g + "/motion_side", 1, "W");
    pw.residual = std::make_unique<Table>(I.file, g + "/residual", 1, "W");
    pw.energy_residual = std::make_unique<Table>(I.file, g + "/energy_residual", 1, "J");
    pw.force_side->append(kNaN);
    pw.motion_side->append(kNaN);
    pw.residual->append(kNaN);
    pw.energy_residual->append(0.0);
    I.pows.push_back(std::move(pw));
  }
  I.flush_all();
}

void H5Recorder::on_step(const StepRecord& r) {
  auto& I = *impl_;
  const Config& c = *I.setup->config;
  I.time->append(cosim::to_seconds(r.t_end));
  I.master_s->append(r.master_seconds);
  I.wall_s->append(r.wall_seconds);
  I.iterations->append(r.iterations);
  for (const auto& [name, sigs] : r.outputs)
    for (const auto& [sig, v] : sigs) I.outputs.at(name + "/" + sig)->append(v.value);
  for (const auto& [name, diags] : r.diagnostics)
    for (const auto& [key, v] : diags) {
      auto& t = I.diagnostics[name + "/" + key];
      if (!t) {
        t = std::make_unique<Table>(I.file, "participants/" + name + "/diagnostics/" + key, 1);
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
    I.conns[i].deviation->append(cr.deviation);
  }
  const Duration H = c.macro_step;
  const double h = cosim::to_seconds(H);
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
  const auto now = std::chrono::steady_clock::now();
  if (now - I.last_flush > std::chrono::seconds(1)) {
    I.flush_all();
    I.last_flush = now;
  }
}

void H5Recorder::on_finish(bool ok, const std::string& message) {
  auto& I = *impl_;
  if (I.time) {
    I.flush_all();
    write_string(I.file, "status", ok ? "finished" : "stopped: " + message);
  }
  I.outputs.clear();
  I.diagnostics.clear();
  I.compute.clear();
  I.round_trip.clear();
  I.conns.clear();
  I.pows.clear();
  I.time.reset();
  I.master_s.reset();
  I.wall_s.reset();
  I.iterations.reset();
  H5Fclose(I.file);
  I.file = -1;
}

// ---------------------------------------------------------------------------------------------

CsvWriter::CsvWriter(const std::string& path) : path_(path) {
  file_ = std::fopen(path.c_str(), "w");
  if (!file_)
    throw std::runtime_error("cannot create CSV file '" + path + "': check that its folder exists (output.csv / --csv)");
}

CsvWriter::~CsvWriter() {
  if (file_) std::fclose(file_);
}

void CsvWriter::on_start(const RunSetup& s) {
  std::fprintf(file_, "time");
  for (const auto& [name, info] : s.participants)
    for (const auto& port : info.outputs) {
      columns_.emplace_back(name, port.name);
      for (const auto& comp : cosim::component_names(port.kind)) {
        if (port.kind == cosim::SignalKind::Scalar) std::fprintf(file_, ",%s.%s", name.c_str(), port.name.c_str());
        else std::fprintf(file_, ",%s.%s.%s", name.c_str(), port.name.c_str(), comp.c_str());
      }
    }
  std::fprintf(file_, "\n");
  std::map<std::string, cosim::Signals> initial;
  for (const auto& [name, info] : s.participants) initial[name] = info.initial_outputs;
  row(s.config->t_start, initial);
}

void CsvWriter::row(TimePoint t, const std::map<std::string, cosim::Signals>& outputs) {
  std::fprintf(file_, "%.9f", cosim::to_seconds(t));
  for (const auto& [name, sig] : columns_)
    for (double v : outputs.at(name).at(sig).value) std::fprintf(file_, ",%.17g", v);
  std::fprintf(file_, "\n");
}

void CsvWriter::on_step(const StepRecord& r) { row(r.t_end, r.outputs); }

void CsvWriter::on_finish(bool, const std::string&) {
  if (file_) std::fclose(file_);
  file_ = nullptr;
}

// ---------------------------------------------------------------------------------------------

void Progress::on_start(const RunSetup& s) {
  setup_ = &s;
  start_ = last_print_ = std::chrono::steady_clock::now();
}

void Progress::on_step(const StepRecord& r) {
  ++steps_done_;
  t_done_ = r.t_end;
  wall_steps_ += r.wall_seconds;
  master_ += r.master_seconds;
  for (const auto& [n, v] : r.compute_seconds) compute_[n] += v;
  for (const auto& [n, v] : r.round_trip_seconds) round_trip_[n] += v;
  const auto now = std::chrono::steady_clock::now();
  if (!live_ || now - last_print_ < std::chrono::seconds(1)) return;
  last_print_ = now;
  const double wall = std::chrono::duration<double>(now - start_).count();
  const double sim = cosim::to_seconds(t_done_ - setup_->config->t_start);
  const double total = cosim::to_seconds(setup_->config->t_end - setup_->config->t_start);
  const double eta = sim > 0 ? wall / sim * (total - sim) : 0;
  std::fprintf(stderr, "\rt = %.4f / %.4f s (%3.0f%%)  step %lld/%lld  real-time factor %.3g  ETA %.0f s   ",
               cosim::to_seconds(t_done_), cosim::to_seconds(setup_->config->t_end), 100 * sim / total,
               static_cast<long long>(steps_done_), static_cast<long long>(setup_->steps),
               wall / sim, eta);
}

void Progress::on_finish(bool ok, const std::string& message) {
  if (!setup_) return;
  if (live_) std::fprintf(stderr, "\n");
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double sim = cosim::to_seconds(t_done_ - setup_->config->t_start);
  std::fprintf(stderr, "%s after %lld of %lld macro steps, t = %.6g s, wall %.3f s, real-time factor %.3g\n",
               ok ? "finished" : "STOPPED", static_cast<long long>(steps_done_),
               static_cast<long long>(setup_->steps), cosim::to_seconds(t_done_), wall,
               sim > 0 ? wall / sim : 0.0);
  std::fprintf(stderr, "%-28s %12s %8s\n", "where the wall time went", "seconds", "share");
  auto line = [&](const std::string& what, double s) {
    std::fprintf(stderr, "%-28s %12.4f %7.1f%%\n", what.c_str(), s, wall > 0 ? 100 * s / wall : 0);
  };
  for (const auto& [n, v] : compute_) {
    line("participant " + n + " compute", v);
    line("participant " + n + " bus+wait", round_trip_[n] - v);
  }
  line("master (predictors, records)", master_);
  line("outside steps (handshake...)", wall - wall_steps_);
}

}  // namespace master
