// Observers of the co-simulation: the HDF5 recorder (layout in docs/output.md), the CSV
// export of the signals, and the progress line with the closing timing table.
#pragma once

#include <hdf5.h>

#include <cstdio>
#include <memory>
#include <string>

#include "cosim/files.hpp"
#include "cosim/stopwatch.hpp"
#include "cosimulation.hpp"

namespace master {

// One number as a 1-element dataset `name` under `group` of an open HDF5 file, the group made
// if missing (run summaries: /bus, /bus/auth, /replay, ...). Does nothing if it cannot open it.
void write_number(hid_t file, const std::string& group, const std::string& name, double value);

// Every write, flush and close is checked: a failure raises std::runtime_error naming the file
// and the cause (e.g. "No space left on device"); the run then stops, and when the recorder is
// destroyed the earlier file of that name is back in place (docs/output.md). The root attribute
// `complete` is 1 only in a record of a finished run that was closed successfully.
class H5Recorder final : public Observer {
 public:
  // Creates the file under a temporary name beside `path` (cosim::StagedFile) and renames it
  // onto `path` in on_start, so an existing file is replaced only when the run starts; raises
  // std::runtime_error naming the path if it cannot.
  explicit H5Recorder(const std::string& path);
  // Resume (cosim_master --resume): opens the existing record at `path` for writing; on_start
  // then keeps its first RunSetup::first_step steps, drops what followed and continues there
  // (docs/output.md#checkpoints-and-resume). Raises std::runtime_error naming the path.
  struct Continue {};
  H5Recorder(Continue, const std::string& path);
  ~H5Recorder() override;
  void on_start(const RunSetup& setup) override;
  void on_step(const StepRecord& record) override;
  void on_finish(bool ok, const std::string& message) override;
  // The file is at its path (on_start ran) and every write so far succeeded.
  bool started() const;
  // Steps done at the last checkpoint the record holds (0: none; without checkpoints: 0).
  int64_t checkpoint_steps() const;

 private:
  void step(const StepRecord& record);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Written under a temporary name and renamed onto `path` in on_start, as the H5Recorder. Every
// write is checked: a failure raises std::runtime_error naming the file and the cause, and then,
// as when the HDF5 record of the same run fails, the earlier file of its name is put back when
// the writer is destroyed (docs/output.md#when-a-record-cannot-be-written).
class CsvWriter final : public Observer {
 public:
  explicit CsvWriter(const std::string& path);
  // Resume: on_start writes the first RunSetup::first_step rows from this record's outputs
  // (the text an uninterrupted run wrote) before the new ones.
  void continue_from(const std::string& h5_path) { continue_from_ = h5_path; }
  ~CsvWriter() override;
  void on_start(const RunSetup& setup) override;
  void on_step(const StepRecord& record) override;
  void on_finish(bool ok, const std::string& message) override;

 private:
  void row(TimePoint t, const std::map<std::string, cosim::Signals>& outputs);
  [[noreturn]] void fail();  // after a failed stdio call: raises the message naming the file
  void check_writable() const;
  struct Shared;
  std::string path_;
  std::unique_ptr<cosim::StagedFile> staged_;
  std::unique_ptr<Shared> shared_;
  std::FILE* file_ = nullptr;
  bool failed_ = false, closed_ = false;
  std::vector<std::pair<std::string, std::string>> columns_;  // participant, signal
  std::string continue_from_;
};

class Progress final : public Observer {
 public:
  explicit Progress(bool live) : live_(live) {}
  void on_start(const RunSetup& setup) override;
  void on_step(const StepRecord& record) override;
  void on_finish(bool ok, const std::string& message) override;

 private:
  bool live_;
  const RunSetup* setup_ = nullptr;
  cosim::Stopwatch run_wall_, since_print_;
  int64_t steps_done_ = 0;
  TimePoint t_begin_{}, t_done_{};
  double wall_steps_ = 0, master_ = 0;
  std::map<std::string, double> compute_, round_trip_;
  int64_t iterations_ = 0, steps_here_ = 0;  // coupling iterations and steps of this process
  int64_t rejected_ = 0;  // adaptive step: attempts rejected and redone
};

}  // namespace master
