// Message authentication for the bus (docs/security.md): with a shared key every message travels
// in an envelope that carries the sender, the session, a sequence number and a keyed BLAKE2b tag
// (libsodium's crypto_generichash, 32 bytes) over the channel name, that header and the encoded
// message. A receiver drops what is malformed, forged (wrong tag), from another session or a
// replay (a sequence number it has seen, or older than its window), and counts each kind.
//
// Bus-free: it seals and opens byte buffers; the LCM transport and the participant loop publish
// and decode what it returns.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace cosim::auth {

constexpr std::size_t kKeyBytes = 32;
constexpr std::size_t kTagBytes = 32;
constexpr std::size_t kMaxSender = 32;

struct Key {
  std::array<unsigned char, kKeyBytes> bytes{};
};

class AuthError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// 64 hex digits (upper or lower case, surrounding white space ignored). `where` names the
// source in the error ("$COSIM_KEY", a file path).
Key parse_key_hex(const std::string& text, const std::string& where);

// A key file holds the 64 hex digits; it must be a regular file that only its owner can read
// (mode 0600 or 0400), like an ssh key.
Key read_key_file(const std::string& path);

// The key from the environment: $COSIM_KEY_FILE (a key file), else $COSIM_KEY (the hex digits),
// else none (the bus is unauthenticated). A key is never taken from the command line, where
// other users can read it in the process list.
std::optional<Key> key_from_environment();

// A new random key in hex, for `cosim_master --new-key FILE` and tests.
std::string new_key_hex();

// Whether a buffer starts like an envelope (its magic), so a process without a key can tell
// sealed traffic it cannot check from garbage. Every function here that takes a buffer takes
// one of at most cosim::kMaxMessageBytes (bus.hpp) and treats a larger size as malformed.
bool looks_sealed(const std::uint8_t* data, std::size_t size);

// The payload an envelope claims to carry, WITHOUT checking its tag: for diagnostics only
// (naming who sent a message that was refused), never to act on. nullopt when it is not
// shaped like an envelope.
std::optional<std::pair<const std::uint8_t*, std::size_t>> unverified_payload(const std::uint8_t* data,
                                                                              std::size_t size);

// Seals messages of one sender. Sequence numbers start at the wall clock in nanoseconds and
// grow by one per message, so they keep growing across restarts of the sender.
class Sealer {
 public:
  Sealer(const Key& key, std::string sender);
  // session 0: a message sent before a session exists (announce, configure of a free participant)
  std::vector<std::uint8_t> seal(const std::string& channel, std::int64_t session,
                                 const std::uint8_t* payload, std::size_t size);
  std::uint64_t next_sequence() const { return seq_; }

 private:
  Key key_;
  std::string sender_;
  std::uint64_t seq_;
};

enum class Verdict { ok, malformed, forged, other_session, replayed };
const char* to_string(Verdict v);

struct Opened {
  Verdict verdict = Verdict::malformed;
  std::string sender;
  std::int64_t session = 0;
  std::uint64_t sequence = 0;
  const std::uint8_t* payload = nullptr;  // inside the buffer given to open()
  std::size_t size = 0;
};

struct Counts {
  std::int64_t accepted = 0, malformed = 0, forged = 0, other_session = 0, replayed = 0;
  std::int64_t rejected() const { return malformed + forged + other_session + replayed; }
};

// What one process counted on the bus (cosim::SealedBus).
struct BusCounts {
  bool keyed = false;
  // Keyed: messages opened, by verdict (malformed: not an envelope, for example the plain
  // message of a process without the key, or an authentic payload that does not decode).
  // Without a key: accepted and malformed count the plain messages that did or did not decode.
  Counts counts;
  // Without a key: sealed messages heard, which this process cannot check (it ignores them).
  std::int64_t unreadable = 0;
  // With or without a key: datagrams whose size cannot be real (cosim::wire_size_ok: a datagram
  // cut inside LCM's header, which LCM 1.3.1 delivers with a size of about 4 GB), dropped before
  // a byte of them is read. Counted in counts.malformed too.
  std::int64_t truncated = 0;
};

// Opens messages for one receiver. A sequence number is accepted once per (sender, channel):
// newer than the newest seen, or among the 64 before it and not seen yet (the bus reorders).
class Opener {
 public:
  explicit Opener(const Key& key);
  // `sessions`: the sessions this receiver accepts on this channel (0 included where a message
  // may come before a session exists).
  Opened open(const std::string& channel, const std::vector<std::int64_t>& sessions,
              const std::uint8_t* data, std::size_t size);
  const Counts& counts() const { return counts_; }

 private:
  struct Window {
    std::uint64_t newest = 0;
    std::uint64_t seen = 0;  // bit k: newest - k was seen
  };
  bool accept_sequence(const std::string& sender, const std::string& channel, std::uint64_t seq);
  Key key_;
  std::map<std::pair<std::string, std::string>, Window> windows_;
  Counts counts_;
};

}  // namespace cosim::auth
