#include "cosim/sealed_bus.hpp"

#include <cstdio>
#include <sstream>

#include "cosim/bus.hpp"

namespace cosim {
namespace {

constexpr int kLinesPerKind = 3;  // per (verdict, channel)
constexpr int kLinesInAll = 40;

}  // namespace

const char* to_string(SealedBus::Heard h) {
  switch (h) {
    case SealedBus::Heard::ok: return "ok";
    case SealedBus::Heard::malformed: return "malformed";
    case SealedBus::Heard::forged: return "forged";
    case SealedBus::Heard::other_session: return "other session";
    case SealedBus::Heard::replayed: return "replayed";
    case SealedBus::Heard::unreadable: return "unreadable";
    case SealedBus::Heard::truncated: return "truncated";
  }
  return "?";
}

std::string envelope_sender(const std::string& name, std::int64_t id) {
  return name.substr(0, 15) + "/" + id_hex(id);
}

SealedBus::SealedBus(lcm::LCM& lcm, std::optional<auth::Key> key, const std::string& sender,
                     std::string who)
    : lcm_(lcm), who_(std::move(who)) {
  if (key) {
    sealer_.emplace(*key, sender);
    opener_.emplace(*key);
    stats_.keyed = true;
  }
}

int SealedBus::publish_bytes(const std::string& channel, std::int64_t session,
                             const std::uint8_t* data, std::size_t size) {
  // The envelope adds at most 1 + 8 + 8 + 4 + 32 + 32 bytes.
  if (size > kMaxMessageBytes - 128) {
    const std::string line = who_ + ": not sent: a message of " + std::to_string(size) +
                             " bytes on " + channel + " (a message has at most " +
                             std::to_string(kMaxMessageBytes) + " bytes on the wire)\n";
    std::fputs(line.c_str(), stderr);
    return -1;
  }
  if (!sealer_) return lcm_.publish(channel, data, static_cast<unsigned>(size));
  // One lock over sealing and sending: sequence numbers leave in order.
  std::lock_guard<std::mutex> lock(mutex_);
  const auto sealed = sealer_->seal(channel, session, data, size);
  return lcm_.publish(channel, sealed.data(), static_cast<unsigned>(sealed.size()));
}

SealedBus::Payload SealedBus::open_bytes(const std::uint8_t* data, std::size_t size,
                                         const std::string& channel,
                                         const std::vector<std::int64_t>& sessions) {
  std::lock_guard<std::mutex> lock(mutex_);
  Payload p;
  const auto claimed = auth::unverified_payload(data, size);
  if (!opener_) {
    if (auth::looks_sealed(data, size)) {
      ++stats_.unreadable;
      p.heard = Heard::unreadable;
      if (claimed) p.data = claimed->first, p.size = claimed->second;
      log(p.heard, channel,
          "a sealed message (sent by a process with a key) on " + channel +
              ", which this process cannot check: it has no key. Every process of a run needs the "
              "same key: set $COSIM_KEY_FILE (or $COSIM_KEY) as for the others (docs/security.md)");
      return p;
    }
    p.heard = Heard::ok;
    p.data = data;
    p.size = size;
    return p;
  }
  const auth::Opened o = opener_->open(channel, sessions, data, size);
  switch (o.verdict) {
    case auth::Verdict::ok:
      p.heard = Heard::ok;
      p.data = o.payload;
      p.size = o.size;
      return p;
    case auth::Verdict::malformed:
      ++stats_.counts.malformed;
      p.heard = Heard::malformed;
      if (!auth::looks_sealed(data, size)) {
        p.data = data;  // a plain message claims to be itself
        p.size = size;
        log(p.heard, channel,
            "an unsealed message on " + channel +
                ": this process has a key and takes sealed messages only (is the sender "
                "missing the key? docs/security.md)");
      } else {
        log(p.heard, channel, "a malformed envelope on " + channel);
      }
      return p;
    case auth::Verdict::forged:
      ++stats_.counts.forged;
      p.heard = Heard::forged;
      log(p.heard, channel,
          "a forged message on " + channel +
              ": its tag does not match the key (sealed with another key, or changed on the way)");
      break;
    case auth::Verdict::other_session: {
      ++stats_.counts.other_session;
      p.heard = Heard::other_session;
      log(p.heard, channel,
          "an authentic message of another session (" + id_hex(o.session) + ") on " + channel +
              " from " + o.sender);
      break;
    }
    case auth::Verdict::replayed: {
      ++stats_.counts.replayed;
      p.heard = Heard::replayed;
      log(p.heard, channel,
          "a replayed message on " + channel + " from " + o.sender + " (sequence number " +
              std::to_string(o.sequence) + " seen already, or older than the window)");
      break;
    }
  }
  if (claimed) p.data = claimed->first, p.size = claimed->second;
  return p;
}

SealedBus::Heard SealedBus::undecodable(const std::string& channel, const char* type) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++stats_.counts.malformed;
  log(Heard::malformed, channel,
      std::string(keyed() ? "an authentic message" : "a message") + " on " + channel +
          " that does not decode as " + type);
  return Heard::malformed;
}

SealedBus::Heard SealedBus::truncated(const std::string& channel, std::uint64_t size) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++stats_.counts.malformed;
  ++stats_.truncated;
  log(Heard::truncated, channel,
      "a truncated datagram on " + channel + " (LCM reports " + std::to_string(size) +
          " bytes: the datagram ended inside its header, or was damaged); nothing of it was read");
  return Heard::truncated;
}

void SealedBus::count_accepted() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++stats_.counts.accepted;
}

void SealedBus::log(Heard heard, const std::string& channel, const std::string& detail) {
  if (lines_ >= kLinesInAll) return;
  int& n = logged_[{static_cast<int>(heard), channel}];
  if (n >= kLinesPerKind) return;
  ++n;
  ++lines_;
  std::string line = who_ + ": dropped " + detail;
  if (n == kLinesPerKind) line += " [further ones of this kind on this channel are counted, not logged]";
  if (lines_ == kLinesInAll) line += " [no further dropped messages are logged; totals at the end]";
  std::fprintf(stderr, "%s\n", line.c_str());  // one write: several processes may share a log
}

AuthStats SealedBus::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

std::string auth_summary(const AuthStats& s) {
  std::ostringstream o;
  if (s.keyed) {
    o << "authenticated bus: " << s.counts.accepted << " message(s) accepted; dropped "
      << s.counts.malformed << " malformed, " << s.counts.forged << " forged, "
      << s.counts.other_session << " of another session, " << s.counts.replayed << " replayed";
  } else {
    if (s.unreadable == 0 && s.counts.malformed == 0) return "";
    o << "unauthenticated bus (no key): ignored " << s.unreadable
      << " sealed message(s) it cannot check and " << s.counts.malformed
      << " that did not decode";
  }
  if (s.truncated > 0) o << "; " << s.truncated << " truncated datagram(s) among the malformed";
  return o.str();
}

}  // namespace cosim
