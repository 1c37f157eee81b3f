// ParticipantCore: the participant side's protocol logic (configure, step identity, cached
// replies, validation, checkpoints) on the wire messages, independent of the transport. Used by
// run_participant, the in-process link and tests; models see only participant.hpp.
#pragma once

#include <cosim/configure_t.hpp>
#include <cosim/ready_t.hpp>
#include <cosim/step_reply_t.hpp>
#include <cosim/step_request_t.hpp>

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cosim/participant.hpp"
#include "cosim/polynomial_wire.hpp"
#include "cosim/signal_wire.hpp"

namespace cosim {

class ParticipantCore {
 public:
  ParticipantCore(std::string name, Model& model);

  const std::string& name() const { return name_; }
  bool bound() const { return session_ != 0; }
  int64_t session() const { return session_; }
  int64_t busy_step() const { return busy_step_.load(); }   // -1 when idle
  int32_t busy_iteration() const { return busy_iteration_.load(); }
  // The last completed step and its iteration; safe to read from another thread (heartbeats).
  int64_t last_step() const { return done_step_.load(); }
  int32_t last_iteration() const { return done_iteration_.load(); }
  TimePoint time() const { return t_now_; }
  uint64_t ignored_messages() const { return ignored_; }

  // Who this process is (announce_t, ready_t, replies); the instance id 0 takes any configure.
  void set_identity(int64_t instance, std::string host, int32_t pid);
  // Started for one session (--session): a configure of any other session is refused.
  void reserve_for(int64_t session) { reserved_ = session; }
  int64_t instance() const { return instance_; }
  int64_t reserved_session() const { return reserved_; }
  const std::string& host() const { return host_; }
  int32_t pid() const { return pid_; }

  // Binds to the session on success. A repeated configure of the bound session gets the same
  // answer; a configure of another session while bound, or of a session other than the one
  // reserved, is refused (ok = false, bound_session_id set while bound). A configure for
  // another participant or instance is not for us (nullopt).
  std::optional<ready_t> configure(const configure_t& message);
  // nullopt for messages that are not for us (other session or participant) or stale.
  std::optional<step_reply_t> handle(const step_request_t& request);
  // The session is over. finished: the run completed, so its checkpoints are of no further use
  // and the ones this process wrote or restored are deleted (and their folder, if empty).
  void end_session(bool finished);
  // The file of the checkpoint after `steps_done` steps of run `run_id`:
  // <folder>/<participant>_<run id, 16 hex digits>_<steps_done>.ckpt
  static std::string checkpoint_path(const std::string& folder, const std::string& participant,
                                     int64_t run_id, int64_t steps_done);

 private:
  step_reply_t run_step(const step_request_t& request);
  // Restores the checkpoint a resuming configure names; raises ProtocolError naming the file.
  void restore_checkpoint(const configure_t& m);
  // Writes the checkpoint after the step just done (a temporary file renamed into place) and
  // deletes this process's checkpoints older than the previous one; raises on failure.
  void write_checkpoint();
  step_reply_t refuse(const step_request_t& request, int8_t status, const std::string& message);

  ready_t refusal(const configure_t& m, const std::string& error) const;

  std::string name_;
  Model& model_;
  int64_t instance_ = 0, reserved_ = 0;
  std::string host_;
  int32_t pid_ = 0;
  int64_t session_ = 0;
  RunInfo run_;
  Ports inputs_, outputs_;
  std::optional<ready_t> ready_;
  int64_t last_step_ = -1;     // last completed step index
  int32_t last_iteration_ = -1;
  TimePoint t_now_{};          // end of the last completed step
  TimePoint t_before_last_{};  // its start, for repeats
  // Whether the model holds a snapshot of t_before_last_ (a redo of last_step_ is possible),
  // and if not, why (for the refusal of a redo).
  bool start_kept_ = false;
  std::string start_note_;
  std::optional<step_reply_t> cached_;
  std::atomic<int64_t> busy_step_{-1};
  std::atomic<int32_t> busy_iteration_{-1};
  std::atomic<int64_t> done_step_{-1};      // copies of last_step_, last_iteration_ for
  std::atomic<int32_t> done_iteration_{-1};  // the heartbeat thread
  uint64_t ignored_ = 0;
  std::string checkpoint_folder_;  // "" : no checkpoints asked
  int64_t run_id_ = 0;
  std::vector<std::string> checkpoints_;  // written or restored by this process, oldest first
  // The checkpoint this session resumed from: kept until the session finishes, so that the
  // record of the run, put back as it was when the resumed run cannot write it, can be resumed
  // again (docs/output.md#when-a-record-cannot-be-written).
  std::string resumed_from_;
};

}  // namespace cosim
