// Run output: one HDF5 file with the config, particle snapshots, the tool meshes at every
// snapshot, tool/wall wrench series, and an XDMF file beside it so ParaView opens the scene
// (particles, tools and walls in one temporal collection). Layout in docs/dem.md, what ParaView
// shows in docs/visualise.md.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "cosim/files.hpp"
#include "cosim/h5.hpp"
#include "cosim/stopwatch.hpp"
#include "dem/engine.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

class RunOutput {
 public:
  // Throws std::runtime_error naming the file and the fix if it cannot be created. The file is
  // written under a temporary name beside `path` and renamed onto it at the first flush(), so
  // an existing file of that name is replaced only when the run starts writing (the XDMF file
  // is written at each flush, after that rename).
  RunOutput(const std::string& path, const Scene& scene, const std::string& config_text);
  ~RunOutput();
  RunOutput(const RunOutput&) = delete;
  RunOutput& operator=(const RunOutput&) = delete;

  // Particles (sorted by id) and every tool's mesh moved to `poses` (one per tool: the pose
  // at `time`, which the caller knows better than s.tool_pose, set for the force time of the
  // last step). The walls are drawn as the part of their plane on the particles' side of every
  // other wall; a plane's part grows to cover everything the snapshots have seen.
  void snapshot(const State& s, double time, const std::vector<ToolPose>& poses);
  // Buffers one sample of every tool's pose and wrench and every wall's force.
  void sample_wrenches(const State& s, const Engine& e, double time);
  // The same with the wrenches and wall forces given (an MPI run's sums over the ranks).
  void sample_wrenches(const State& s, const std::vector<Wrench>& tools,
                       const std::vector<Vec3>& walls, double time);
  void flush();  // appends buffered samples and rewrites the XDMF file
  // flush() if the last one was longer ago than `seconds` of wall-clock time.
  void flush_if_older_than(double seconds);
  // Buffered (not yet flushed) wrench samples, and dropping those after the first `keep`
  // (the samples of a macro step the co-simulation repeats).
  std::size_t buffered_rows() const { return buffered_; }
  void discard_rows_after(std::size_t keep);
  // The run's timing summary, then `complete` = 1, and the file closed (checked): the last
  // write; later flushes do nothing. Every write here is checked: a failure (a full disk)
  // raises std::runtime_error naming the file and the cause, and the earlier file of that name
  // is put back (cosim::StagedFile::restore).
  void write_summary(const Timing& t, const State& s, double sim_time);

  const std::string& xdmf_path() const { return xdmf_; }

 private:
  void start(const std::string& config_text);
  void write_snapshot(const State& s, double time, const std::vector<ToolPose>& poses);
  void write_timing(const Timing& t, const State& s, double sim_time);
  template <class F>
  void checked(F&& f);  // runs f; a failed write abandons the file and raises the message
  void abandon();
  void write_xdmf() const;
  void write_wall_geometry();
  std::string path_, xdmf_;
  std::string failure_;  // the message of a failed write; every later write raises it again
  std::string xdmf_earlier_;     // the XDMF of an earlier file of this name, kept until complete
  mutable bool xdmf_written_ = false;  // this run wrote the XDMF file
  const Scene& scene_;
  std::unique_ptr<cosim::StagedFile> staged_;
  long long file_ = -1;
  std::vector<double> snapshot_times_;
  std::vector<std::size_t> snapshot_sizes_;
  // xdmf_point_index: 0, 1, 2, ... as long as the largest snapshot, the particles' cells (one
  // vertex each) for the XDMF: every snapshot's Polyvertex topology takes its first n entries.
  std::size_t point_index_size_ = 0;
  void write_point_index(std::size_t n);
  // Box around every particle centre and tool vertex of the snapshots so far (plane walls are
  // drawn over it).
  bool have_extent_ = false;
  Vec3 extent_lo_, extent_hi_;
  std::size_t wall_vertices_ = 0, wall_triangles_ = 0;  // in wall_geometry/ now
  std::vector<std::unique_ptr<cosim::h5::Table>> tool_rows_;  // per tool: t, F, M, position, quaternion
  std::unique_ptr<cosim::h5::Table> wall_rows_;               // t, then F of every wall
  std::size_t buffered_ = 0;
  cosim::Stopwatch since_flush_;
};

}  // namespace dem
