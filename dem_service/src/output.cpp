#include "dem/output.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
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

void write_vector_attribute(hid_t loc, const std::string& name, const std::vector<double>& v) {
  const hsize_t n = v.size();
  h5::Handle space(H5Screate_simple(1, &n, nullptr), H5Sclose);
  h5::Handle attr(H5Acreate2(loc, name.c_str(), H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, H5P_DEFAULT),
                  H5Aclose);
  if (!attr.ok() || H5Awrite(attr, H5T_NATIVE_DOUBLE, v.data()) < 0)
    throw std::runtime_error("HDF5: cannot write attribute '" + name + "'");
}

// The shortest text that reads back as exactly x (the time as written in the HDF5 file).
std::string shortest(double x) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}

// XML text and attribute values: tool and wall names are the user's.
std::string xml_escape(const std::string& in) {
  std::string out;
  for (const char c : in) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

// The rectangle a wall is drawn as: a box face, or the plane over the box lo..hi.
std::array<Vec3, 4> wall_quad(const Wall& w, Vec3 lo, Vec3 hi) {
  if (w.from_box) {
    // The face whose normal is w.normal (an axis): fixed coordinate from w.point, the other two
    // span the box.
    const double n[3] = {w.normal.x, w.normal.y, w.normal.z};
    int a = 0;
    for (int i = 1; i < 3; ++i)
      if (std::fabs(n[i]) > std::fabs(n[a])) a = i;
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    const double p[3] = {w.point.x, w.point.y, w.point.z};
    const double mn[3] = {w.box_min.x, w.box_min.y, w.box_min.z};
    const double mx[3] = {w.box_max.x, w.box_max.y, w.box_max.z};
    std::array<Vec3, 4> q;
    const double uv[4][2] = {{mn[b], mn[c]}, {mx[b], mn[c]}, {mx[b], mx[c]}, {mn[b], mx[c]}};
    for (int k = 0; k < 4; ++k) {
      double x[3];
      x[a] = p[a];
      x[b] = uv[k][0];
      x[c] = uv[k][1];
      q[k] = {x[0], x[1], x[2]};
    }
    return q;
  }
  // Tangent basis of the plane, then the box's corners projected onto it.
  const Vec3 n = w.normal;
  Vec3 e{1, 0, 0};
  if (std::fabs(n.y) <= std::fabs(n.x) && std::fabs(n.y) <= std::fabs(n.z)) e = {0, 1, 0};
  else if (std::fabs(n.z) <= std::fabs(n.x) && std::fabs(n.z) <= std::fabs(n.y)) e = {0, 0, 1};
  Vec3 u = cross(n, e);
  u = (1.0 / norm(u)) * u;
  const Vec3 v = cross(n, u);
  double a0 = 1e300, a1 = -1e300, b0 = 1e300, b1 = -1e300;
  for (int k = 0; k < 8; ++k) {
    const Vec3 c{k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z};
    const double a = dot(c - w.point, u), b = dot(c - w.point, v);
    a0 = std::min(a0, a);
    a1 = std::max(a1, a);
    b0 = std::min(b0, b);
    b1 = std::max(b1, b);
  }
  return {w.point + a0 * u + b0 * v, w.point + a1 * u + b0 * v, w.point + a1 * u + b1 * v,
          w.point + a0 * u + b1 * v};
}

// The part of a convex polygon on the inner side of wall o (where the particles are), within eps.
std::vector<Vec3> clip(const std::vector<Vec3>& poly, const Wall& o, double eps) {
  std::vector<Vec3> out;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Vec3 a = poly[i], b = poly[(i + 1) % poly.size()];
    const double da = dot(a - o.point, o.normal), db = dot(b - o.point, o.normal);
    const bool ina = da >= -eps, inb = db >= -eps;
    if (ina) out.push_back(a);
    if (ina != inb) out.push_back(a + (da / (da - db)) * (b - a));
  }
  return out;
}

}  // namespace

RunOutput::RunOutput(const std::string& path, const Scene& scene, const std::string& config_text)
    : path_(path), scene_(scene), staged_(std::make_unique<cosim::StagedFile>(path)) {
  xdmf_ = std::filesystem::path(path).replace_extension(".xdmf").string();
  {  // An earlier XDMF describes the earlier file of this name: kept (a second name, no copy)
     // until this output is complete, and put back with that file if this one fails.
    const std::filesystem::path x(xdmf_);
    std::string name = ".";
    name += x.filename().string();
    name += ".previous-run-" + std::to_string(static_cast<long>(::getpid()));  // not StagedFile's name
    xdmf_earlier_ = (x.parent_path() / name).string();
    std::remove(xdmf_earlier_.c_str());
    if (::link(xdmf_.c_str(), xdmf_earlier_.c_str()) != 0) xdmf_earlier_.clear();
  }
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // failures are reported with their cause
  file_ = H5Fcreate(staged_->current().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (file_ < 0)
    throw std::runtime_error("cannot create output '" + path + "' (" + cosim::h5::error_cause() +
                             "): check that the folder exists and is writable (--output FILE.h5)");
  checked([&] { start(config_text); });
}

void RunOutput::start(const std::string& config_text) {
  const Scene& scene = scene_;
  // 1 once write_summary closed the file after the run's last step (docs/dem.md#output).
  cosim::h5::set_int_attribute(file_, "complete", 0);
  h5::write_string_attribute(file_, "config", config_text);
  h5::Handle g1(H5Gcreate2(file_, "particles", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  h5::Handle g2(H5Gcreate2(file_, "tools", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  for (const Tool& t : scene.tools) {
    h5::Handle g(H5Gcreate2(g2, t.name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    tool_rows_.push_back(std::make_unique<h5::Table>(g, "samples", kToolCols, kChunkRows));
    h5::write_string_attribute(g, "columns",
                               "time, force xyz, torque xyz (about the reference point), "
                               "position xyz, orientation wxyz; ground frame, SI units");
    // The mesh once (tool frame, relative to the reference point), then its vertices in the
    // ground frame at every particle snapshot (snapshots/NNNNNN): what the XDMF points at.
    h5::write(g, "vertices", t.mesh.vertices);
    h5::write(g, "triangles", H5T_NATIVE_INT32, t.mesh.triangles.data(), t.mesh.triangles.size(), 3);
    h5::Handle snaps(H5Gcreate2(g, "snapshots", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    h5::write_string_attribute(snaps, "columns",
                               "vertex xyz in the ground frame: position + R(orientation) vertices; "
                               "attributes time, position xyz, orientation wxyz");
  }
  if (!scene.walls.empty()) {
    h5::Handle g(H5Gcreate2(file_, "wall_geometry", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    std::string names;
    for (const Wall& w : scene.walls) names += (names.empty() ? "" : ", ") + w.name;
    h5::write_string_attribute(g, "names", names);
    h5::write_string_attribute(g, "note",
                               "for pictures only: each wall as the part of its plane (a box face: "
                               "of that face; a plane: of a rectangle over everything the snapshots "
                               "saw) on the particles' side of every other wall, as triangles; "
                               "'wall' is each triangle's index into 'names'");
    wall_rows_ = std::make_unique<h5::Table>(file_, "walls", 1 + 3 * scene.walls.size(), kChunkRows);
    std::string cols = "time";
    for (const Wall& w : scene.walls) cols += ", " + w.name + " force xyz";
    wall_rows_->attribute("columns", cols + " (force on the wall)");
  }
}

RunOutput::~RunOutput() {
  if (file_ < 0) return;  // closed by write_summary, or abandoned after a failed write
  // The run stopped before its summary: what it wrote so far stays (complete: 0).
  try {
    flush();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dem: %s\n", e.what());  // flush() put the earlier file back
    return;
  }
  tool_rows_.clear();
  wall_rows_.reset();
  const hid_t f = file_;
  file_ = -1;
  if (H5Fclose(f) < 0) {
    std::fprintf(stderr, "dem: %s; %s\n", cosim::write_failure(path_, cosim::h5::error_cause()).c_str(),
                 staged_->restore().c_str());
    if (!xdmf_earlier_.empty()) std::rename(xdmf_earlier_.c_str(), xdmf_.c_str());
    else if (xdmf_written_) std::remove(xdmf_.c_str());
  } else if (!xdmf_earlier_.empty()) {
    std::remove(xdmf_earlier_.c_str());
  }
}

void RunOutput::abandon() {
  tool_rows_.clear();
  wall_rows_.reset();
  if (file_ >= 0) H5Fclose(file_);  // fails on a broken file; the process still exits cleanly
  file_ = -1;
}

template <class F>
void RunOutput::checked(F&& f) {
  if (!failure_.empty()) throw std::runtime_error(failure_);  // it failed before: say so again
  if (file_ < 0) throw std::logic_error("RunOutput: '" + path_ + "' is closed");
  try {
    f();
  } catch (const std::exception& e) {
    const std::string message = e.what();
    abandon();
    const std::string what = message.rfind("cannot write '", 0) == 0
                                 ? message
                                 : cosim::write_failure(path_, message);
    const std::string restored = staged_->restore();
    if (!xdmf_earlier_.empty()) std::rename(xdmf_earlier_.c_str(), xdmf_.c_str());
    else if (xdmf_written_) std::remove(xdmf_.c_str());
    xdmf_earlier_.clear();
    failure_ = restored.empty() ? what : what + "; " + restored;
    throw std::runtime_error(failure_);
  }
}

void RunOutput::snapshot(const State& s, double time, const std::vector<ToolPose>& poses) {
  if (poses.size() != scene_.tools.size())
    throw std::logic_error("RunOutput::snapshot: " + std::to_string(poses.size()) +
                           " poses for " + std::to_string(scene_.tools.size()) + " tools");
  checked([&] { write_snapshot(s, time, poses); });
  flush();
}

void RunOutput::write_snapshot(const State& s, double time, const std::vector<ToolPose>& poses) {
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
  if (s.w.size() == s.size()) {  // the rotating model (dem/rotation.hpp): spins, rad/s
    std::vector<Vec3> w(s.size());
    for (std::size_t k = 0; k < order.size(); ++k) w[k] = s.w[order[k]];
    h5::write(g, "angular_velocity", w);
  }
  auto grow = [&](Vec3 p) {
    if (!have_extent_) {
      extent_lo_ = extent_hi_ = p;
      have_extent_ = true;
    }
    extent_lo_ = {std::min(extent_lo_.x, p.x), std::min(extent_lo_.y, p.y), std::min(extent_lo_.z, p.z)};
    extent_hi_ = {std::max(extent_hi_.x, p.x), std::max(extent_hi_.y, p.y), std::max(extent_hi_.z, p.z)};
  };
  for (const Vec3& p : x) grow(p);
  for (std::size_t m = 0; m < scene_.tools.size(); ++m) {
    const Tool& tool = scene_.tools[m];
    const ToolPose& pose = poses[m];
    // The same transform as the engine's (Engine::update_tool_geometry).
    const Mat3 R = to_matrix(pose.orientation);
    std::vector<Vec3> world(tool.mesh.vertices.size());
    for (std::size_t v = 0; v < world.size(); ++v) {
      world[v] = pose.position + R * tool.mesh.vertices[v];
      grow(world[v]);
    }
    const std::string tname = "tools/" + tool.name + "/snapshots";
    h5::Handle tg(H5Gopen2(file_, tname.c_str(), H5P_DEFAULT), H5Gclose);
    const std::string ds = snapshot_name(snapshot_times_.size());
    h5::write(tg, ds, world);
    h5::Handle set(H5Dopen2(tg, ds.c_str(), H5P_DEFAULT), H5Dclose);
    h5::write_double_attribute(set, "time", time);
    write_vector_attribute(set, "position", {pose.position.x, pose.position.y, pose.position.z});
    write_vector_attribute(set, "orientation", {pose.orientation.w, pose.orientation.x,
                                                pose.orientation.y, pose.orientation.z});
  }
  for (const Wall& w : scene_.walls)
    if (w.from_box) {
      grow(w.box_min);
      grow(w.box_max);
    }
  write_wall_geometry();
  write_point_index(s.size());
  snapshot_times_.push_back(time);
  snapshot_sizes_.push_back(s.size());
}

void RunOutput::sample_wrenches(const State& s, const Engine& e, double time) {
  sample_wrenches(s, e.tool_wrenches(), e.wall_forces(), time);
}

void RunOutput::sample_wrenches(const State& s, const std::vector<Wrench>& tools,
                                const std::vector<Vec3>& walls, double time) {
  for (std::size_t m = 0; m < scene_.tools.size(); ++m) {
    const Wrench& w = tools[m];
    const ToolPose& p = s.tool_pose[m];
    const double row[kToolCols] = {time, w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y,
                                   w.torque.z, p.position.x, p.position.y, p.position.z,
                                   p.orientation.w, p.orientation.x, p.orientation.y,
                                   p.orientation.z};
    tool_rows_[m]->append(row);
  }
  if (wall_rows_) {
    std::vector<double> row{time};
    for (const Vec3& f : walls) row.insert(row.end(), {f.x, f.y, f.z});
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
  if (file_ < 0 && failure_.empty()) return;  // closed (write_summary)
  checked([&] {
    for (auto& rows : tool_rows_) rows->flush();
    if (wall_rows_) wall_rows_->flush();
    buffered_ = 0;
    since_flush_.restart();
    cosim::h5::flush(file_, path_);
    staged_->commit();  // the first flush puts the file in place (docs/output.md#file-safety)
    write_xdmf();
  });
}

void RunOutput::write_summary(const Timing& t, const State& s, double sim_time) {
  checked([&] {
    write_timing(t, s, sim_time);
    cosim::h5::set_int_attribute(file_, "complete", 1);
    for (auto& rows : tool_rows_) rows->flush();
    if (wall_rows_) wall_rows_->flush();
    buffered_ = 0;
    tool_rows_.clear();
    wall_rows_.reset();
    const hid_t f = file_;
    file_ = -1;
    cosim::h5::close(f, path_);
    staged_->commit();
    staged_->done();  // the earlier file of this name is dropped only now
    write_xdmf();
    if (!xdmf_earlier_.empty()) std::remove(xdmf_earlier_.c_str());
    xdmf_earlier_.clear();
  });
}

void RunOutput::write_timing(const Timing& t, const State& s, double sim_time) {
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

void RunOutput::write_wall_geometry() {
  if (scene_.walls.empty()) return;
  // Plane walls cover the box around everything seen so far, with a margin.
  Vec3 lo = extent_lo_, hi = extent_hi_;
  if (!have_extent_) lo = hi = scene_.walls.front().point;
  const Vec3 size = hi - lo;
  const double span = std::max({size.x, size.y, size.z});
  const double margin = std::max({0.1 * span, 4 * scene_.r_max(), 1e-3});
  lo -= Vec3{margin, margin, margin};
  hi += Vec3{margin, margin, margin};
  // Each wall's rectangle, cut to the particles' side of every other wall (the domain), as a fan
  // of triangles.
  const double eps = 1e-9 * std::max(1.0, span);
  std::vector<Vec3> vertices;
  std::vector<std::array<std::int32_t, 3>> triangles;
  std::vector<std::int32_t> owner;
  for (std::size_t w = 0; w < scene_.walls.size(); ++w) {
    const auto quad = wall_quad(scene_.walls[w], lo, hi);
    std::vector<Vec3> poly(quad.begin(), quad.end());
    for (std::size_t o = 0; o < scene_.walls.size() && poly.size() >= 3; ++o)
      if (o != w) poly = clip(poly, scene_.walls[o], eps);
    if (poly.size() < 3) continue;  // nothing of it borders the domain
    const auto base = static_cast<std::int32_t>(vertices.size());
    vertices.insert(vertices.end(), poly.begin(), poly.end());
    for (std::int32_t i = 1; i + 1 < static_cast<std::int32_t>(poly.size()); ++i) {
      triangles.push_back({base, base + i, base + i + 1});
      owner.push_back(static_cast<std::int32_t>(w));
    }
  }
  // Replaced at every snapshot (its size may change): the XDMF points every time step at it.
  h5::Handle g(H5Gopen2(file_, "wall_geometry", H5P_DEFAULT), H5Gclose);
  for (const char* name : {"vertices", "triangles", "wall"})
    if (H5Lexists(g, name, H5P_DEFAULT) > 0 && H5Ldelete(g, name, H5P_DEFAULT) < 0)
      throw std::runtime_error(std::string("HDF5: cannot replace 'wall_geometry/") + name +
                               "' in '" + path_ + "'");
  h5::write(g, "vertices", vertices);
  h5::write(g, "triangles", H5T_NATIVE_INT32, triangles.data(), triangles.size(), 3);
  h5::write(g, "wall", H5T_NATIVE_INT32, owner.data(), owner.size(), 0);
  wall_vertices_ = vertices.size();
  wall_triangles_ = triangles.size();
}

void RunOutput::write_point_index(std::size_t n) {
  if (n <= point_index_size_) return;
  const char* name = "xdmf_point_index";
  if (H5Lexists(file_, name, H5P_DEFAULT) > 0 && H5Ldelete(file_, name, H5P_DEFAULT) < 0)
    throw std::runtime_error(std::string("HDF5: cannot replace '") + name + "' in '" + path_ + "'");
  std::vector<std::int32_t> index(n);
  for (std::size_t i = 0; i < n; ++i) index[i] = static_cast<std::int32_t>(i);
  h5::write(file_, name, H5T_NATIVE_INT32, index.data(), n, 0);
  point_index_size_ = n;
}

void RunOutput::write_xdmf() const {
  // Under a temporary name, renamed over the last one when written whole.
  cosim::StagedFile staged(xdmf_);
  std::ofstream out(staged.current());
  const std::string h5 = xml_escape(std::filesystem::path(path_).filename().string());
  auto item = [&](std::size_t rows, std::size_t cols, const char* type, int precision,
                  const std::string& where) {
    out << "<DataItem Dimensions=\"" << rows;
    if (cols) out << " " << cols;
    out << "\" NumberType=\"" << type << "\" Precision=\"" << precision
        << "\" Format=\"HDF\">" << h5 << ":/" << where << "</DataItem>";
  };
  out << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n<Domain>\n"
      << "<Grid Name=\"run\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (std::size_t k = 0; k < snapshot_times_.size(); ++k) {
    const std::size_t n = snapshot_sizes_[k];
    const std::string snap = snapshot_name(k);
    const std::string base = "particles/" + snap;
    out << "<Grid Name=\"step" << k << "\" GridType=\"Collection\" CollectionType=\"Spatial\">\n"
        << " <Time Value=\"" << shortest(snapshot_times_[k]) << "\"/>\n"
        << " <Grid Name=\"particles\" GridType=\"Uniform\">\n"
        << "  <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n
        << "\" NodesPerElement=\"1\"";
    if (n == 0) {
      out << "/>\n";
    } else {
      // One cell (a vertex) per particle, so that every view shows them: its connectivity the
      // first n entries of xdmf_point_index (0, 1, 2, ...).
      out << "><DataItem ItemType=\"HyperSlab\" Dimensions=\"" << n
          << "\" Type=\"HyperSlab\"><DataItem Dimensions=\"3 1\" Format=\"XML\">0 1 " << n
          << "</DataItem>";
      item(point_index_size_, 0, "Int", 4, "xdmf_point_index");
      out << "</DataItem></Topology>\n";
    }
    out << "  <Geometry GeometryType=\"XYZ\">";
    item(n, 3, "Float", 8, base + "/position");
    out << "</Geometry>\n  <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">";
    item(n, 3, "Float", 8, base + "/velocity");
    out << "</Attribute>\n  <Attribute Name=\"radius\" AttributeType=\"Scalar\" Center=\"Node\">";
    item(n, 0, "Float", 8, base + "/radius");
    out << "</Attribute>\n  <Attribute Name=\"id\" AttributeType=\"Scalar\" Center=\"Node\">";
    item(n, 0, "Int", 8, base + "/id");
    out << "</Attribute>\n </Grid>\n";
    for (const Tool& t : scene_.tools) {
      const std::size_t nt = t.mesh.triangles.size(), nv = t.mesh.vertices.size();
      const std::string g = "tools/" + xml_escape(t.name);
      out << " <Grid Name=\"tool_" << xml_escape(t.name) << "\" GridType=\"Uniform\">\n"
          << "  <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << nt << "\">";
      item(nt, 3, "Int", 4, g + "/triangles");
      out << "</Topology>\n  <Geometry GeometryType=\"XYZ\">";
      item(nv, 3, "Float", 8, g + "/snapshots/" + snap);
      out << "</Geometry>\n </Grid>\n";
    }
    if (wall_triangles_ > 0) {
      out << " <Grid Name=\"walls\" GridType=\"Uniform\">\n"
          << "  <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << wall_triangles_ << "\">";
      item(wall_triangles_, 3, "Int", 4, "wall_geometry/triangles");
      out << "</Topology>\n  <Geometry GeometryType=\"XYZ\">";
      item(wall_vertices_, 3, "Float", 8, "wall_geometry/vertices");
      out << "</Geometry>\n  <Attribute Name=\"wall\" AttributeType=\"Scalar\" Center=\"Cell\">";
      item(wall_triangles_, 0, "Int", 4, "wall_geometry/wall");
      out << "</Attribute>\n </Grid>\n";
    }
    out << "</Grid>\n";
  }
  out << "</Grid>\n</Domain>\n</Xdmf>\n";
  out.close();
  if (!out) throw std::runtime_error(cosim::write_failure(xdmf_, std::strerror(errno)));
  staged.commit();
  xdmf_written_ = true;
}

}  // namespace dem
