// One process's end of the bus with or without the shared key (docs/security.md): publishes a
// typed message as its LCM encoding, sealed in an envelope (cosim/auth.hpp) when the process
// has a key, and opens what it receives: with a key only authentic messages of the expected
// sessions pass; without one, the plain encoding (the wire format of a bus without keys).
// Every message refused is counted by verdict and logged, a few per channel and verdict.
//
// Thread-safe: a participant's heartbeat thread publishes while its LCM thread receives.
#pragma once

#include <lcm/lcm-cpp.hpp>

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cosim/auth.hpp"
#include "cosim/bus.hpp"

namespace cosim {

using AuthStats = auth::BusCounts;

std::string auth_summary(const AuthStats& s);

class SealedBus {
 public:
  // What became of a received message.
  // truncated: a datagram whose size cannot be real (cut inside LCM's header: see
  // cosim::wire_size_ok), dropped before a byte of it is read.
  enum class Heard { ok, malformed, forged, other_session, replayed, unreadable, truncated };

  // `sender` names this process in its envelopes (unique per process: the replay window is kept
  // per sender and channel; at most 32 characters); `who` prefixes its log lines.
  SealedBus(lcm::LCM& lcm, std::optional<auth::Key> key, const std::string& sender, std::string who);

  bool keyed() const { return sealer_.has_value(); }

  // Publishes m on `channel`, sealed for `session` (0 before a session exists) with a key.
  template <class M>
  int publish(const std::string& channel, std::int64_t session, const M& m) {
    const int n = m.getEncodedSize();
    std::vector<std::uint8_t> buf(static_cast<std::size_t>(n));
    if (m.encode(buf.data(), 0, n) != n) return -1;
    return publish_bytes(channel, session, buf.data(), buf.size());
  }

  // Opens a received message. Returns ok with `m` decoded when it is authentic (or, without a
  // key, when it decodes) and of one of `sessions`; anything else is counted and logged, and
  // `m` then holds what the message CLAIMS to carry if that decodes (for diagnostics such as
  // naming an unauthenticated participant: never act on it).
  // Every handler of every channel calls this first: it is the transport edge, where a
  // buffer whose size cannot be real is dropped and counted (truncated) before it is read.
  template <class M>
  Heard open(const lcm::ReceiveBuffer* rbuf, const std::string& channel,
             const std::vector<std::int64_t>& sessions, M& m) {
    if (!rbuf || !wire_size_ok(rbuf->data, rbuf->data_size))
      return truncated(channel, rbuf ? rbuf->data_size : 0);
    Payload p = open_bytes(static_cast<const std::uint8_t*>(rbuf->data), rbuf->data_size, channel,
                           sessions);
    const bool decoded = p.data && m.decode(p.data, 0, static_cast<int>(p.size)) == static_cast<int>(p.size);
    if (p.heard == Heard::ok && !decoded) return undecodable(channel, M::getTypeName());
    if (p.heard == Heard::ok) count_accepted();
    return p.heard;
  }

  AuthStats stats() const;
  std::string summary() const { return auth_summary(stats()); }

 private:
  struct Payload {
    Heard heard = Heard::malformed;
    const std::uint8_t* data = nullptr;  // the message (ok) or what a refused one claims
    std::size_t size = 0;
  };
  int publish_bytes(const std::string& channel, std::int64_t session, const std::uint8_t* data,
                    std::size_t size);
  Payload open_bytes(const std::uint8_t* data, std::size_t size, const std::string& channel,
                     const std::vector<std::int64_t>& sessions);
  Heard undecodable(const std::string& channel, const char* type);
  Heard truncated(const std::string& channel, std::uint64_t size);
  void count_accepted();
  void log(Heard heard, const std::string& channel, const std::string& detail);

  lcm::LCM& lcm_;
  std::string who_;
  std::optional<auth::Sealer> sealer_;
  std::optional<auth::Opener> opener_;
  mutable std::mutex mutex_;
  AuthStats stats_;
  std::map<std::pair<int, std::string>, int> logged_;  // (verdict, channel) -> lines written
  int lines_ = 0;
};

const char* to_string(SealedBus::Heard h);

// "authenticated bus: N message(s) accepted; dropped a malformed, b forged, ..." with a key;
// without one the sealed and undecodable messages ignored, or "" when there were none. Either
// way followed by "; t truncated datagram(s) among the malformed" when there were any.
std::string auth_summary(const AuthStats& s);

// The envelope's sender for a process: its name (cut to 15 characters) and its instance or
// session id, unique per process.
std::string envelope_sender(const std::string& name, std::int64_t id);

}  // namespace cosim
