#include "dem/checkpoint.hpp"

#include <stdexcept>

#include "dem/coupling.hpp"
#include "dem/h5_util.hpp"

namespace dem {
namespace {

// ToolPose rows in the layout of a kinematics value (cosim::Kinematics).
std::vector<double> flatten(const std::vector<ToolPose>& poses) {
  std::vector<double> out;
  for (const ToolPose& p : poses) {
    const cosim::Value v = to_kinematics(p).to_value();
    out.insert(out.end(), v.begin(), v.end());
  }
  return out;
}
std::vector<ToolPose> unflatten(const std::vector<double>& v) {
  constexpr std::size_t n = cosim::Kinematics::kSize;
  std::vector<ToolPose> out(v.size() / n);
  for (std::size_t k = 0; k < out.size(); ++k) {
    const cosim::Value row(v.begin() + n * k, v.begin() + n * (k + 1));
    out[k] = to_tool_pose(cosim::Kinematics::from_value(row));
  }
  return out;
}

}  // namespace

void save_checkpoint(const State& s, const std::string& path) {
  h5::Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  if (!file.ok())
    throw std::runtime_error("cannot create checkpoint '" + path +
                             "': check that the folder exists and is writable");
  h5::write_string_attribute(file, "format", "dem_state_v1");
  const std::vector<std::int64_t> counters{s.step, s.lists_valid ? 1 : 0, s.steps_since_rebuild,
                                           s.rebuilds, s.early_rebuilds};
  h5::write(file, "counters", counters);
  h5::write(file, "max_displacement", std::vector<double>{s.max_displacement});
  h5::write(file, "x", s.x);
  h5::write(file, "v", s.v);
  h5::write(file, "u", s.u);
  h5::write(file, "radius", s.radius);
  h5::write(file, "mass", s.mass);
  h5::write(file, "species", s.species);
  h5::write(file, "id", s.id);
  h5::write(file, "tool_pose", flatten(s.tool_pose));
  h5::write(file, "tool_pose_at_rebuild", flatten(s.tool_pose_at_rebuild));
  h5::write(file, "x_at_rebuild", s.x_at_rebuild);
  h5::write(file, "pair_offset", s.pair_offset);
  h5::write(file, "pair_j", s.pair_j);
  h5::write(file, "pair_spring", s.pair_spring);
  h5::write(file, "tri_offset", s.tri_offset);
  h5::write(file, "tri_tool", s.tri_tool);
  h5::write(file, "tri_index", s.tri_index);
  h5::write(file, "wall_mask", s.wall_mask);
  h5::write(file, "slot_key", s.slot_key);
  h5::write(file, "slot_spring", s.slot_spring);
  h5::write(file, "slot_count", s.slot_count);
}

State load_checkpoint(const std::string& path) {
  htri_t is_h5;  // HDF5's own error stack is silenced: the message below is ours
  H5E_BEGIN_TRY { is_h5 = H5Fis_hdf5(path.c_str()); }
  H5E_END_TRY;
  if (is_h5 <= 0)
    throw std::runtime_error("checkpoint '" + path + "' is missing or not an HDF5 file: give a "
                             "file written by dem_run (settle.checkpoint or output.checkpoint)");
  h5::Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  State s;
  try {
    const auto counters = h5::read<std::int64_t>(file, "counters");
    if (counters.size() != 5) throw std::runtime_error("counters has the wrong size");
    s.step = counters[0];
    s.lists_valid = counters[1] != 0;
    s.steps_since_rebuild = counters[2];
    s.rebuilds = counters[3];
    s.early_rebuilds = counters[4];
    s.max_displacement = h5::read<double>(file, "max_displacement").at(0);
    s.x = h5::read_vec3(file, "x");
    s.v = h5::read_vec3(file, "v");
    s.u = h5::read_vec3(file, "u");
    s.radius = h5::read<double>(file, "radius");
    s.mass = h5::read<double>(file, "mass");
    s.species = h5::read<std::int32_t>(file, "species");
    s.id = h5::read<std::int64_t>(file, "id");
    s.tool_pose = unflatten(h5::read<double>(file, "tool_pose"));
    s.tool_pose_at_rebuild = unflatten(h5::read<double>(file, "tool_pose_at_rebuild"));
    s.x_at_rebuild = h5::read_vec3(file, "x_at_rebuild");
    s.pair_offset = h5::read<std::int32_t>(file, "pair_offset");
    s.pair_j = h5::read<std::int32_t>(file, "pair_j");
    s.pair_spring = h5::read_vec3(file, "pair_spring");
    s.tri_offset = h5::read<std::int32_t>(file, "tri_offset");
    s.tri_tool = h5::read<std::int32_t>(file, "tri_tool");
    s.tri_index = h5::read<std::int32_t>(file, "tri_index");
    // Older checkpoints lack wall masks: the first step then rebuilds the lists.
    if (H5Lexists(file, "wall_mask", H5P_DEFAULT) > 0)
      s.wall_mask = h5::read<std::uint32_t>(file, "wall_mask");
    else
      s.lists_valid = false;
    s.slot_key = h5::read<std::uint64_t>(file, "slot_key");
    s.slot_spring = h5::read_vec3(file, "slot_spring");
    s.slot_count = h5::read<std::uint8_t>(file, "slot_count");
  } catch (const std::exception& e) {
    throw std::runtime_error("checkpoint '" + path + "' is incomplete (" + e.what() +
                             "): it was not written by this dem_run version; settle the bed again");
  }
  const std::size_t n = s.x.size();
  if (s.v.size() != n || s.u.size() != n || s.radius.size() != n || s.mass.size() != n ||
      s.species.size() != n || s.id.size() != n)
    throw std::runtime_error("checkpoint '" + path + "': per-particle arrays differ in length");
  return s;
}

}  // namespace dem
