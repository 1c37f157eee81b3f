// Replay (docs/replay.md): `cosim_master CONFIG --replay LOG --replay-side NAME` reruns the
// side NAME live against the recorded messages of the others. The played sides are not started
// and nothing of the log goes onto the bus: the master answers their step requests itself with
// the replies recorded for the same (step, iteration), and compares, bit for bit, each request it
// would have sent them with the recorded one (the first that differs is where the replay
// diverged from the recording) and each live output with the recorded one.
#pragma once

#include <cosim/auth.hpp>
#include <cosim/configure_t.hpp>
#include <cosim/link.hpp>
#include <cosim/ready_t.hpp>
#include <cosim/step_reply_t.hpp>
#include <cosim/step_request_t.hpp>

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "config.hpp"
#include "cosimulation.hpp"

namespace master {
class BusRecorder;
}

namespace master::replay {

// A log that cannot be replayed with this config: the text says why and what to do.
class ReplayError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Options {
  std::string log;                // --replay
  std::vector<std::string> live;  // --replay-side (repeatable): rerun live; the others are played
  int64_t session = 0;            // --replay-session: the recorded run; 0: the log's
};

using StepKey = std::pair<int64_t, int32_t>;  // (step_index, iteration)

struct RecordedParticipant {
  std::optional<cosim::ready_t> ready;          // its first accepted ready (or a refusal)
  std::optional<cosim::configure_t> configure;  // what the master sent it
  std::map<StepKey, cosim::step_request_t> requests;  // the first copy of each
  std::map<StepKey, cosim::step_reply_t> replies;     // the first copy of each
};

struct Recording {
  std::string path;
  int64_t session = 0;
  bool keyed = false;        // the messages are sealed; opened (and checked) with the key
  bool from_master = false;  // written by cosim_master --record (header record present)
  bool complete = false;     // its end record is there and the digest matches
  std::string status;        // the recorded run's status from the end record
  int64_t events = 0;        // in the file
  std::map<std::string, RecordedParticipant> participants;
  std::vector<std::string> live, played;  // config order
  std::vector<std::string> notes;         // for the log at the start
  bool played_side(const std::string& name) const;
};

// Reads the log and checks it against the config: raises ReplayError for a log that is not
// an LCM log, truncated or corrupt, of another session (--replay-session), without a played
// participant or without enough of its replies, of a keyed run without the key (or with another
// one), or recorded with other times or other parameters of a played side.
Recording load(const Options& options, const Config& config, const std::optional<cosim::auth::Key>& key);

struct Difference {
  int64_t step = -1;
  int32_t iteration = 0;
  double t = 0;              // the step's start, s
  std::string participant;   // whose request or output
  std::string detail;
  bool found() const { return step >= 0; }
};

struct Report {
  Difference request;  // first request to a played side that differs from the recorded one
  Difference output;   // first output of a live side that differs from the recorded one
  int64_t requests_compared = 0, requests_missing = 0;  // missing: not in the log
  int64_t outputs_compared = 0, outputs_missing = 0;
};

// The live participants over `live` (an LCM transport with links for them only), the played
// ones from the recording.
class ReplayTransport final : public cosim::Transport {
 public:
  ReplayTransport(std::unique_ptr<cosim::Transport> live, const Recording& recording);
  int64_t session() const override { return live_->session(); }
  std::map<std::string, cosim::ParticipantInfo> connect(const std::vector<cosim::configure_t>& configs,
                                                        double timeout_s) override;
  std::vector<cosim::StepAnswer> exchange(const std::vector<cosim::step_request_t>& requests) override;
  void terminate(bool error, const std::string& reason) override;
  std::string describe() const override;
  const Report& report() const { return report_; }

 private:
  void compare_request(const cosim::step_request_t& q);
  void compare_outputs(const cosim::step_request_t& q, const cosim::StepAnswer& a);

  std::unique_ptr<cosim::Transport> live_;
  const Recording& rec_;
  std::map<std::string, cosim::ParticipantInfo> infos_;
  Report report_;
};

// One paragraph for people: what was played, whether and where the replay diverged.
std::string summary(const Recording& recording, const Report& report);

// At the end of a run (after the HDF5 recorder closed its file): closes the bus recording
// (--record) with the run's status, prints what was recorded and the replay's summary, and adds
// /bus/recording and /replay to the HDF5 file (docs/output.md).
class RunNotes final : public Observer {
 public:
  RunNotes(std::string h5_path, BusRecorder* recorder, const Recording* recording,
           const ReplayTransport* replay)
      : h5_(std::move(h5_path)), recorder_(recorder), recording_(recording), replay_(replay) {}
  // Raises std::runtime_error naming the HDF5 file and the cause when the notes cannot be
  // written (the record is then not "finished": cosim_master exits 1).
  void on_finish(bool ok, const std::string& message) override;

 private:
  void write_notes(std::int64_t file) const;  // an open hid_t
  std::string h5_;
  BusRecorder* recorder_;
  const Recording* recording_;
  const ReplayTransport* replay_;
};

}  // namespace master::replay
