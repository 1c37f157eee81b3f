#include "dem/output.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <stdexcept>

#include "dem/h5_util.hpp"

namespace dem {
namespace {

std::string snapshot_name(std::size_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06zu", k);
  return buf;
}

constexpr std::size_t kToolCols = 1 + 3 + 3 + 3 + 4;
constexpr std::size_t kChunkRows = 1024;

}  // namespace

RunOutput::RunOutput(const std::string& path, const Scene& scene, const std::string& config_text)
    : path_(path), scene_(scene), staged_(std::make_unique<cosim::StagedFile>(path)) {
  xdmf_ = std::filesystem::path(path).replace_extension(".xdmf").string();
  file_ = H5Fcreate(staged_->current().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (file_ < 0)
    throw std::runtime_error("cannot create output '" + path +
                             "': check that the folder exists and is writable (--output FILE.h5)");
  h5::write_string_attribute(file_, "config", config_text);
  h5::Handle g1(H5Gcreate2(file_, "particles", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  h5::Handle g2(H5Gcreate2(file_, "tools", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  for (const Tool& t : scene.tools) {
    h5::Handle g(H5Gcreate2(g2, t.name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    tool_rows_.push_back(std::make_unique<h5::Table>(g, "samples", kToolCols, kChunkRows));
    h5::write_string_attribute(g, "columns",
                               "time, force xyz, torque xyz (about the reference point), "
                               "position xyz, orientation wxyz; ground frame, SI units");
  }
  if (!scene.walls.empty()) {
    wall_rows_ = std::make_unique<h5::Table>(file_, "walls", 1 + 3 * scene.walls.size(), kChunkRows);
    std::string cols = "time";
    for (const Wall& w : scene.walls) cols += ", " + w.name + " force xyz";
    wall_rows_->attribute("columns", cols + " (force on the wall)");
  }
}

RunOutput::~RunOutput() {
  try {
    flush();
  } catch (...) {
  }
  tool_rows_.clear();
  wall_rows_.reset();
  if (file_ >= 0) H5Fclose(file_);
}

void RunOutput::snapshot(const State& s, double time) {
  // Sorted by id so ParaView sees the same particle at the same index in every snapshot.
  std::vector<std::size_t> order(s.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](auto a, auto b) { return s.id[a] < s.id[b]; });
  std::vector<Vec3> x(s.size()), v(s.size());
  std::vector<double> r(s.size());
  std::vector<std::int64_t> id(s.size());
  for (std::size_t k = 0; k < order.size(); ++k) {
    x[k] = s.x[order[k]];
    v[k] = s.v[order[k]];
    r[k] = s.radius[order[k]];
    id[k] = s.id[order[k]];
  }
  const std::string name = "particles/" + snapshot_name(snapshot_times_.size());
  h5::Handle g(H5Gcreate2(file_, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  h5::write_double_attribute(g, "time", time);
  h5::write(g, "position", x);
  h5::write(g, "velocity", v);
  h5::write(g, "radius", r);
  h5::write(g, "id", id);
  snapshot_times_.push_back(time);
  snapshot_sizes_.push_back(s.size());
  flush();
}

void RunOutput::sample_wrenches(const State& s, const Engine& e, double time) {
  for (std::size_t m = 0; m < scene_.tools.size(); ++m) {
    const Wrench& w = e.tool_wrenches()[m];
    const ToolPose& p = s.tool_pose[m];
    const double row[kToolCols] = {time, w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y,
                                   w.torque.z, p.position.x, p.position.y, p.position.z,
                                   p.orientation.w, p.orientation.x, p.orientation.y,
                                   p.orientation.z};
    tool_rows_[m]->append(row);
  }
  if (wall_rows_) {
    std::vector<double> row{time};
    for (const Vec3& f : e.wall_forces()) row.insert(row.end(), {f.x, f.y, f.z});
    wall_rows_->append(row.data());
  }
  ++buffered_;
}

void RunOutput::flush_if_older_than(double seconds) {
  if (since_flush_.seconds() >= seconds) flush();
}

void RunOutput::discard_rows_after(std::size_t keep) {
  if (keep >= buffered_) return;
  for (auto& rows : tool_rows_) rows->discard_rows_after(keep);
  if (wall_rows_) wall_rows_->discard_rows_after(keep);
  buffered_ = keep;
}

void RunOutput::flush() {
  for (auto& rows : tool_rows_) rows->flush();
  if (wall_rows_) wall_rows_->flush();
  buffered_ = 0;
  since_flush_.restart();
  H5Fflush(file_, H5F_SCOPE_LOCAL);
  staged_->commit();  // the first flush puts the file in place (docs/output.md#file-safety)
  write_xdmf();
}

void RunOutput::write_summary(const Timing& t, const State& s, double sim_time) {
  h5::Handle g(H5Gcreate2(file_, "timing", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  for (std::size_t i = 0; i < t.size(); ++i) h5::write_double_attribute(g, t.name(i), t.seconds(i));
  h5::write_double_attribute(g, "total", t.sum());
  h5::write_double_attribute(g, "simulated_time", sim_time);
  h5::write_double_attribute(g, "rebuilds", static_cast<double>(s.rebuilds));
  h5::write_double_attribute(g, "early_rebuilds", static_cast<double>(s.early_rebuilds));
  // Region of interest (scene.region): particles removed so far and their mass; sleeping.
  h5::write_double_attribute(g, "removed_count", static_cast<double>(s.removed_count));
  h5::write_double_attribute(g, "removed_mass", s.removed_mass);
  std::int64_t asleep = 0;
  if (scene_.sleep.enabled)
    for (const std::int32_t r : s.rest_steps) asleep += r >= scene_.sleep.steps;
  h5::write_double_attribute(g, "sleeping", static_cast<double>(asleep));
}

void RunOutput::write_xdmf() const {
  std::ofstream out(xdmf_);
  const std::string h5 = std::filesystem::path(path_).filename().string();
  out << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n<Domain>\n"
      << "<Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (std::size_t k = 0; k < snapshot_times_.size(); ++k) {
    const std::size_t n = snapshot_sizes_[k];
    const std::string base = h5 + ":/particles/" + snapshot_name(k);
    out << "<Grid Name=\"step" << k << "\" GridType=\"Uniform\">\n"
        << "  <Time Value=\"" << snapshot_times_[k] << "\"/>\n"
        << "  <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n << "\"/>\n"
        << "  <Geometry GeometryType=\"XYZ\"><DataItem Dimensions=\"" << n
        << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << base
        << "/position</DataItem></Geometry>\n"
        << "  <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\"><DataItem "
        << "Dimensions=\"" << n << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">"
        << base << "/velocity</DataItem></Attribute>\n"
        << "  <Attribute Name=\"radius\" AttributeType=\"Scalar\" Center=\"Node\"><DataItem "
        << "Dimensions=\"" << n << "\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << base
        << "/radius</DataItem></Attribute>\n"
        << "  <Attribute Name=\"id\" AttributeType=\"Scalar\" Center=\"Node\"><DataItem "
        << "Dimensions=\"" << n << "\" NumberType=\"Int\" Precision=\"8\" Format=\"HDF\">" << base
        << "/id</DataItem></Attribute>\n</Grid>\n";
  }
  out << "</Grid>\n</Domain>\n</Xdmf>\n";
}

}  // namespace dem
