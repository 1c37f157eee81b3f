#include "cosim/auth.hpp"

#include <sodium.h>
#include <sys/stat.h>

#include <cctype>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include "cosim/bus.hpp"

namespace cosim::auth {
namespace {

// Envelope: "CSA1" | session (8, big-endian) | sequence (8, big-endian) | sender length (1) |
// sender | payload | tag (32). The tag covers the channel (2-byte length + name) and every byte
// before it.
constexpr char kMagic[4] = {'C', 'S', 'A', '1'};
constexpr std::size_t kHeader = 4 + 8 + 8 + 1;

void ensure_sodium() {
  static const int ok = sodium_init();  // thread-safe once; 1 = already initialised
  if (ok < 0) throw AuthError("libsodium failed to initialise");
}

void put_be64(std::uint8_t* p, std::uint64_t v) {
  for (int i = 7; i >= 0; --i, v >>= 8) p[i] = static_cast<std::uint8_t>(v & 0xff);
}
std::uint64_t get_be64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return v;
}

void tag_of(const Key& key, const std::string& channel, const std::uint8_t* data, std::size_t n,
            std::uint8_t out[kTagBytes]) {
  crypto_generichash_state st;
  crypto_generichash_init(&st, key.bytes.data(), kKeyBytes, kTagBytes);
  const std::uint8_t len[2] = {static_cast<std::uint8_t>(channel.size() >> 8),
                               static_cast<std::uint8_t>(channel.size() & 0xff)};
  crypto_generichash_update(&st, len, 2);
  crypto_generichash_update(&st, reinterpret_cast<const unsigned char*>(channel.data()),
                            channel.size());
  crypto_generichash_update(&st, data, n);
  crypto_generichash_final(&st, out, kTagBytes);
}

}  // namespace

Key parse_key_hex(const std::string& text, const std::string& where) {
  std::string hex;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c))) hex += c;
  if (hex.size() != 2 * kKeyBytes)
    throw AuthError(where + ": a key is " + std::to_string(2 * kKeyBytes) +
                    " hex digits (32 random bytes), found " + std::to_string(hex.size()) +
                    " characters; make one with: cosim_master --new-key FILE");
  Key k;
  for (std::size_t i = 0; i < kKeyBytes; ++i) {
    unsigned v = 0;
    for (int h = 0; h < 2; ++h) {
      const char c = hex[2 * i + h];
      unsigned d;
      if (c >= '0' && c <= '9') d = c - '0';
      else if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
      else if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
      else
        throw AuthError(where + ": '" + std::string(1, c) + "' at position " +
                        std::to_string(2 * i + h + 1) + " is not a hex digit");
      v = v * 16 + d;
    }
    k.bytes[i] = static_cast<unsigned char>(v);
  }
  return k;
}

Key read_key_file(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0)
    throw AuthError("key file '" + path + "' not found (from $COSIM_KEY_FILE); make one with: "
                    "cosim_master --new-key " + path);
  if (!S_ISREG(st.st_mode)) throw AuthError("key file '" + path + "' is not a regular file");
  if (st.st_mode & (S_IRWXG | S_IRWXO)) {
    std::ostringstream msg;
    msg << "key file '" << path << "' can be read by others (mode " << std::oct
        << (st.st_mode & 0777) << "); restrict it: chmod 600 " << path;
    throw AuthError(msg.str());
  }
  std::ifstream f(path);
  if (!f) throw AuthError("key file '" + path + "' cannot be read");
  std::stringstream ss;
  ss << f.rdbuf();
  return parse_key_hex(ss.str(), "key file '" + path + "'");
}

std::optional<Key> key_from_environment() {
  if (const char* file = std::getenv("COSIM_KEY_FILE"); file && *file) return read_key_file(file);
  if (const char* hex = std::getenv("COSIM_KEY"); hex && *hex) return parse_key_hex(hex, "$COSIM_KEY");
  return std::nullopt;
}

std::string new_key_hex() {
  ensure_sodium();
  unsigned char b[kKeyBytes];
  randombytes_buf(b, sizeof b);
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (unsigned char c : b) out += digits[c >> 4], out += digits[c & 15];
  sodium_memzero(b, sizeof b);
  return out;
}

bool looks_sealed(const std::uint8_t* data, std::size_t size) {
  return data && size >= 4 && size <= kMaxMessageBytes && std::memcmp(data, kMagic, 4) == 0;
}

std::optional<std::pair<const std::uint8_t*, std::size_t>> unverified_payload(const std::uint8_t* data,
                                                                              std::size_t size) {
  if (!looks_sealed(data, size) || size < kHeader + 1 + kTagBytes) return std::nullopt;
  const std::size_t slen = data[20];
  if (slen == 0 || slen > kMaxSender || size < kHeader + slen + kTagBytes) return std::nullopt;
  return std::make_pair(data + kHeader + slen, size - kTagBytes - kHeader - slen);
}

Sealer::Sealer(const Key& key, std::string sender) : key_(key), sender_(std::move(sender)) {
  ensure_sodium();
  if (sender_.empty() || sender_.size() > kMaxSender)
    throw AuthError("sender name '" + sender_ + "' must be 1 to " + std::to_string(kMaxSender) +
                    " characters");
  seq_ = static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                        std::chrono::system_clock::now().time_since_epoch())
                                        .count());
}

std::vector<std::uint8_t> Sealer::seal(const std::string& channel, std::int64_t session,
                                       const std::uint8_t* payload, std::size_t size) {
  if (size > kMaxMessageBytes - kHeader - sender_.size() - kTagBytes)
    throw AuthError("a message of " + std::to_string(size) + " bytes on " + channel +
                    " does not fit an envelope: a message has at most " +
                    std::to_string(kMaxMessageBytes) + " bytes on the wire");
  std::vector<std::uint8_t> out(kHeader + sender_.size() + size + kTagBytes);
  std::uint8_t* p = out.data();
  std::memcpy(p, kMagic, 4);
  put_be64(p + 4, static_cast<std::uint64_t>(session));
  put_be64(p + 12, seq_++);
  p[20] = static_cast<std::uint8_t>(sender_.size());
  std::memcpy(p + kHeader, sender_.data(), sender_.size());
  if (size) std::memcpy(p + kHeader + sender_.size(), payload, size);
  const std::size_t body = kHeader + sender_.size() + size;
  tag_of(key_, channel, p, body, p + body);
  return out;
}

const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::ok: return "ok";
    case Verdict::malformed: return "malformed";
    case Verdict::forged: return "forged";
    case Verdict::other_session: return "other session";
    case Verdict::replayed: return "replayed";
  }
  return "?";
}

Opener::Opener(const Key& key) : key_(key) { ensure_sodium(); }

Opened Opener::open(const std::string& channel, const std::vector<std::int64_t>& sessions,
                    const std::uint8_t* data, std::size_t size) {
  Opened o;
  auto reject = [&](Verdict v) {
    o.verdict = v;
    switch (v) {
      case Verdict::malformed: ++counts_.malformed; break;
      case Verdict::forged: ++counts_.forged; break;
      case Verdict::other_session: ++counts_.other_session; break;
      case Verdict::replayed: ++counts_.replayed; break;
      case Verdict::ok: break;
    }
    o.payload = nullptr;
    o.size = 0;
    return o;
  };
  if (!data || size < kHeader + 1 + kTagBytes || size > kMaxMessageBytes ||
      std::memcmp(data, kMagic, 4) != 0)
    return reject(Verdict::malformed);
  const std::size_t slen = data[20];
  if (slen == 0 || slen > kMaxSender || size < kHeader + slen + kTagBytes)
    return reject(Verdict::malformed);
  const std::size_t body = size - kTagBytes;
  std::uint8_t tag[kTagBytes];
  tag_of(key_, channel, data, body, tag);
  if (crypto_verify_32(tag, data + body) != 0) return reject(Verdict::forged);
  // Authentic from here on: the fields are the sender's.
  o.session = static_cast<std::int64_t>(get_be64(data + 4));
  o.sequence = get_be64(data + 12);
  o.sender.assign(reinterpret_cast<const char*>(data + kHeader), slen);
  bool session_ok = false;
  for (std::int64_t s : sessions) session_ok = session_ok || s == o.session;
  if (!session_ok) return reject(Verdict::other_session);
  if (!accept_sequence(o.sender, channel, o.sequence)) return reject(Verdict::replayed);
  o.verdict = Verdict::ok;
  o.payload = data + kHeader + slen;
  o.size = body - kHeader - slen;
  ++counts_.accepted;
  return o;
}

bool Opener::accept_sequence(const std::string& sender, const std::string& channel,
                             std::uint64_t seq) {
  auto [it, fresh] = windows_.try_emplace({sender, channel});
  Window& w = it->second;
  if (fresh) {
    w.newest = seq;
    w.seen = 1;
    return true;
  }
  if (seq > w.newest) {
    const std::uint64_t shift = seq - w.newest;
    w.seen = shift >= 64 ? 0 : w.seen << shift;
    w.seen |= 1;
    w.newest = seq;
    return true;
  }
  const std::uint64_t back = w.newest - seq;
  if (back >= 64) return false;  // older than the window: cannot tell, so refuse
  const std::uint64_t bit = std::uint64_t{1} << back;
  if (w.seen & bit) return false;
  w.seen |= bit;
  return true;
}

}  // namespace cosim::auth
