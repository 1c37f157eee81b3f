// The bus in LCM's own event-log format (docs/replay.md): `cosim_master --record FILE` writes
// every message of its session as lcm-logger would (lcm-logplayer plays it back), and a strict
// reader gives the events of a log (the master's, or lcm-logger's) to the replay.
//
// The master's recordings carry two records of their own on COSIM_<session>_LOG (text, sealed
// with the run's key when the bus is keyed): a header first (session, bus, whether keyed, the
// effective config) and an end record last (the run's status, the number of events before it
// and their BLAKE2b-256 digest), so a replay can tell a complete, unchanged recording from one
// that was cut off or edited.
#pragma once

#include <cosim/auth.hpp>
#include <lcm/lcm-cpp.hpp>

#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace master {

// A log that cannot be used: the text names the file, the event and the byte offset.
class LogError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct LogEvent {
  int64_t index = 0;         // position in the file, from 0
  int64_t number = 0;        // the event number written in the log
  int64_t timestamp_us = 0;  // receive time, microseconds since the epoch
  std::string channel;
  std::vector<std::uint8_t> data;
  uint64_t offset = 0;       // byte offset of the event's header
};

// Reads an LCM event log (28-byte big-endian header: sync word 0xEDA1DA01, event number,
// timestamp, channel length, data length; then the channel and the data) and calls fn for each
// event in order. Strict where LCM's own reader skips ahead to the next sync word: an event
// that does not start where the previous one ended, impossible lengths and a file that ends
// inside an event raise LogError (truncated or corrupt, with the event and byte offset).
// Returns the number of events.
int64_t read_lcm_log(const std::string& path, const std::function<void(LogEvent&)>& fn);
// The same from an open stream (`name` in the errors); the caller closes it.
int64_t read_lcm_log(std::FILE* f, const std::string& name, const std::function<void(LogEvent&)>& fn);

// The channel of the master's own records in its recordings.
std::string log_record_channel(int64_t session);

// Text of the records: "cosim bus log 1\nrecord: start|end\nkey: value\n..." (for the end record
// also events: N and digest: 64 hex digits). parse_log_record gives the key-value lines (up to a
// line "config: |", whose indented block follows); nullopt if the text is not a record.
std::optional<std::vector<std::pair<std::string, std::string>>> parse_log_record(const std::string& text);

// Incremental digest of a log's events (channel and data, with their lengths), BLAKE2b-256.
class LogDigest {
 public:
  LogDigest();
  void add(const std::string& channel, const void* data, std::size_t size);
  std::string hex() const;  // of everything added so far (the state goes on)

 private:
  std::vector<unsigned char> state_;  // crypto_generichash_state, opaque
};

// Records the messages of one session in LCM's log format while the master runs: its own LCM
// endpoint on the run's bus, subscribed to COSIM_<session>_.* (heartbeats, configures of
// launched participants, ready, requests, replies, terminate) and to the configures of
// participants started by hand (COSIM_CFG_<instance> holding this session). The master calls
// poll() while it waits on the bus; nothing else runs in another thread.
class BusRecorder {
 public:
  // Opens `path` for writing (an existing file is replaced) and writes the header record;
  // raises std::runtime_error naming the path if it cannot.
  BusRecorder(const std::string& path, const std::string& url, int64_t session,
              const std::optional<cosim::auth::Key>& key, const std::string& effective_config);
  ~BusRecorder();
  BusRecorder(const BusRecorder&) = delete;
  BusRecorder& operator=(const BusRecorder&) = delete;

  // Writes what has arrived (does not wait).
  void poll();
  // Takes what arrives for another `drain_s` seconds (the terminate, the last heartbeats),
  // writes the end record with `status` and closes the file. Later calls do nothing.
  void finish(const std::string& status, double drain_s = 0.15);

  const std::string& path() const { return path_; }
  int64_t events() const { return events_; }  // written so far, records included
  int64_t session() const { return session_; }
  // Messages not written: datagrams whose size cannot be real (cosim::wire_size_ok: truncated),
  // and, on the session's channels, messages that are not the run's (with a key: not authentic,
  // of another session or replayed; without: not decodable as their channel's message). The end
  // record says how many ("dropped: N"), so that a replay of the log sees only the run.
  int64_t dropped() const { return truncated_ + refused_; }
  int64_t truncated() const { return truncated_; }
  // "T truncated, N not decodable / forged / replayed ..." ("" when none were dropped).
  std::string dropped_text() const;

  // The LCM handlers (public for tests and tests/fuzz/fuzz_datagrams.cpp): every received
  // buffer is checked before a byte of it is read or written. They never throw (they run inside
  // LCM's C code): a write that fails is kept and raised by the next poll() or finish().
  void on_message(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void on_configure(const lcm::ReceiveBuffer* rbuf, const std::string& channel);

 private:
  bool admit(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  bool genuine(const std::string& channel, const std::uint8_t* data, std::size_t size, int64_t sealed_for);
  void refuse(const std::string& channel, const std::string& why, int64_t nth);
  void write_received(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void raise_pending();
  void write(const std::string& channel, const void* data, std::size_t size, int64_t utime);
  void write_record(const std::string& text);

  std::string path_;
  int64_t session_;
  lcm::LCM lcm_;
  std::unique_ptr<lcm::LogFile> file_;
  std::optional<cosim::auth::Sealer> sealer_;
  LogDigest digest_;
  int64_t events_ = 0;
  int64_t last_flush_us_ = 0;
  int64_t truncated_ = 0, refused_ = 0;
  std::map<std::string, int64_t> refused_by_;  // why -> count
  std::optional<cosim::auth::Opener> opener_;  // with a key: what is written must be authentic
  std::optional<std::string> failed_;  // a write that failed inside a handler
  bool finished_ = false;
};

}  // namespace master
