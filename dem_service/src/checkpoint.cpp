#include "dem/checkpoint.hpp"

#include <stdexcept>
#include <string>
#include <string_view>

#include "cosim/files.hpp"
#include "dem/coupling.hpp"
#include "dem/h5_util.hpp"

namespace dem {
namespace {

// One array of State to and from its dataset. Tool poses are stored as rows in the layout of a
// kinematics value (cosim::Kinematics).
void write_array(hid_t file, const char* name, const std::vector<ToolPose>& poses) {
  std::vector<double> out;
  for (const ToolPose& p : poses) {
    const cosim::Value v = to_kinematics(p).to_value();
    out.insert(out.end(), v.begin(), v.end());
  }
  h5::write(file, name, out);
}
template <class T>
void write_array(hid_t file, const char* name, const std::vector<T>& v) {
  h5::write(file, name, v);
}

void read_array(hid_t file, const char* name, std::vector<ToolPose>& out) {
  const std::vector<double> v = h5::read<double>(file, name);
  constexpr std::size_t n = cosim::Kinematics::kSize;
  out.assign(v.size() / n, ToolPose{});
  for (std::size_t k = 0; k < out.size(); ++k) {
    const cosim::Value row(v.begin() + n * k, v.begin() + n * (k + 1));
    out[k] = to_tool_pose(cosim::Kinematics::from_value(row));
  }
}
void read_array(hid_t file, const char* name, std::vector<Vec3>& out) {
  out = h5::read_vec3(file, name);
}
template <class T>
void read_array(hid_t file, const char* name, std::vector<T>& out) {
  out = h5::read<T>(file, name);
}

}  // namespace

void save_checkpoint(const State& s, const std::string& path) {
  // Written under a temporary name and renamed onto `path` once closed: a checkpoint that cannot
  // be written (a full disk) leaves the previous one of that name whole.
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  cosim::StagedFile staged(path);
  hid_t file = H5Fcreate(staged.current().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (file < 0)
    throw std::runtime_error("cannot create checkpoint '" + path + "' (" + cosim::h5::error_cause() +
                             "): check that the folder exists and is writable");
  try {
    h5::write_string_attribute(file, "format", "dem_state_v1");
    const std::vector<std::int64_t> counters{s.step, s.lists_valid ? 1 : 0, s.steps_since_rebuild,
                                             s.rebuilds, s.early_rebuilds};
    h5::write(file, "counters", counters);
    h5::write(file, "max_displacement", std::vector<double>{s.max_displacement});
    h5::write(file, "second_displacement", std::vector<double>{s.second_displacement});
    h5::write(file, "removed_count", std::vector<std::int64_t>{s.removed_count});
    h5::write(file, "removed_mass", std::vector<double>{s.removed_mass});
    for_each_array(s, [&](const char* name, const auto& array, Field) {
      // The rotating model's arrays are left out when empty (the translating model): its
      // checkpoints stay those of the engine before rotation existed.
      const std::string_view key(name);
      if (array.empty() && (key == "w" || key == "wu" || key == "pair_roll" || key == "slot_roll"))
        return;
      write_array(file, name, array);
    });
  } catch (const std::exception& e) {
    H5Fclose(file);  // fails too on a full disk; the temporary file goes with `staged`
    throw std::runtime_error(cosim::write_failure(path, e.what()));
  }
  const hid_t f = file;
  cosim::h5::close(f, path);  // raises "cannot write '<path>': <cause>"
  staged.commit();
  staged.done();
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
    // Written since the guard uses the two largest displacements; an older checkpoint's guard
    // assumed both particles of a pair moved the largest.
    s.second_displacement = H5Lexists(file, "second_displacement", H5P_DEFAULT) > 0
                                ? h5::read<double>(file, "second_displacement").at(0)
                                : s.max_displacement;
    // Written since the region of interest exists; older checkpoints removed nothing.
    if (H5Lexists(file, "removed_count", H5P_DEFAULT) > 0) {
      s.removed_count = h5::read<std::int64_t>(file, "removed_count").at(0);
      s.removed_mass = h5::read<double>(file, "removed_mass").at(0);
    }
    for_each_array(s, [&](const char* name, auto& array, Field) {
      // Older checkpoints lack wall masks or slot blocks (they had a block per particle):
      // the first step then rebuilds the lists.
      const std::string_view key(name);
      if ((key == "wall_mask" || key == "slot_block" || key == "slot_particle" ||
           key == "pair_work") &&
          H5Lexists(file, name, H5P_DEFAULT) <= 0) {
        s.lists_valid = false;
        return;
      }
      // Older checkpoints lack the rest counters of sleeping: every particle starts awake.
      if (key == "rest_steps" && H5Lexists(file, name, H5P_DEFAULT) <= 0) return;
      // ... and the lists by partner: the first step with sleeping builds them.
      if ((key == "pair_row_offset" || key == "pair_row") && H5Lexists(file, name, H5P_DEFAULT) <= 0)
        return;
      // ... and the rotating model's arrays (dem/rotation.hpp): a bed settled without them starts
      // without spin and rolling springs.
      if ((key == "w" || key == "wu" || key == "pair_roll" || key == "slot_roll") &&
          H5Lexists(file, name, H5P_DEFAULT) <= 0)
        return;
      read_array(file, name, array);
    });
  } catch (const std::exception& e) {
    throw std::runtime_error("checkpoint '" + path + "' is incomplete (" + e.what() +
                             "): it was not written by this dem_run version; settle the bed again");
  }
  const std::size_t n = s.x.size();
  // A checkpoint of the older layout (a slot block per particle, no slot_block): block i was
  // particle i's, so the boundary history survives the rebuild that follows.
  if (s.slot_block.empty() && s.slot_key.size() == n * kBoundarySlots && s.slot_count.size() == n) {
    s.slot_block.resize(n);
    for (std::size_t i = 0; i < n; ++i) s.slot_block[i] = static_cast<std::int32_t>(i);
  }
  for_each_array(s, [&](const char* name, const auto& array, Field field) {
    const bool sized = field == Field::particle ||
                       ((field == Field::sorted || field == Field::model) && !array.empty());
    if (sized && array.size() != n)
      throw std::runtime_error("checkpoint '" + path + "': per-particle array '" + name +
                               "' has " + std::to_string(array.size()) + " entries for " +
                               std::to_string(n) + " particles; settle the bed again");
  });
  return s;
}

}  // namespace dem
