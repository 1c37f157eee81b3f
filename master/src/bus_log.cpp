#include "bus_log.hpp"

#include <cosim/bus.hpp>
#include <cosim/configure_t.hpp>
#include <cosim/heartbeat_t.hpp>
#include <cosim/ready_t.hpp>
#include <cosim/step_reply_t.hpp>
#include <cosim/step_request_t.hpp>
#include <cosim/terminate_t.hpp>
#include <cosim/sealed_bus.hpp>
#include <sodium.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <sstream>
#include <thread>

namespace master {

namespace {

constexpr std::uint32_t kSync = 0xEDA1DA01u;
constexpr std::size_t kHeaderBytes = 28;
constexpr int32_t kMaxChannel = 63;                 // LCM's limit on channel names
constexpr int64_t kMaxData = static_cast<int64_t>(cosim::kMaxMessageBytes);  // the bus's own bound
constexpr int kDroppedLines = 3;                     // logged; the rest are counted
constexpr const char* kMagicLine = "cosim bus log 1";

std::uint32_t be32(const unsigned char* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3];
}
std::uint64_t be64(const unsigned char* p) { return (std::uint64_t(be32(p)) << 32) | be32(p + 4); }

int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

}  // namespace

int64_t read_lcm_log(const std::string& path, const std::function<void(LogEvent&)>& fn) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw LogError("cannot read the log '" + path + "': " + std::strerror(errno));
  struct Closer {
    std::FILE* f;
    ~Closer() { std::fclose(f); }
  } closer{f};
  return read_lcm_log(f, path, fn);
}

int64_t read_lcm_log(std::FILE* f, const std::string& path, const std::function<void(LogEvent&)>& fn) {
  if (std::fseek(f, 0, SEEK_END) != 0) throw LogError("cannot read the log '" + path + "': it cannot be sought");
  const long size_l = std::ftell(f);
  std::fseek(f, 0, SEEK_SET);
  const uint64_t size = size_l < 0 ? 0 : static_cast<uint64_t>(size_l);
  if (size == 0)
    throw LogError("the log '" + path + "' is empty: it holds no events (did the recording start?)");
  uint64_t offset = 0;
  int64_t index = 0;
  unsigned char h[kHeaderBytes];
  while (offset < size) {
    const std::size_t got = std::fread(h, 1, kHeaderBytes, f);
    const auto where = [&] {
      return "event " + std::to_string(index) + " at byte " + std::to_string(offset);
    };
    if (got >= 4 && be32(h) != kSync) {
      char found[16];
      std::snprintf(found, sizeof found, "0x%08X", be32(h));
      if (index == 0)
        throw LogError("'" + path + "' is not an LCM event log: it does not start with LCM's sync word "
                       "0xEDA1DA01 (found " + found + ")");
      throw LogError("the log '" + path + "' is corrupt: " + where() + " does not start with LCM's sync "
                     "word 0xEDA1DA01 (found " + found + ") where the previous event ended; the file "
                     "was changed or damaged after recording");
    }
    if (got < kHeaderBytes)
      throw LogError("the log '" + path + "' is truncated: " + where() + " is cut off after " +
                     std::to_string(got) + " of its " + std::to_string(kHeaderBytes) +
                     " header bytes (the file ends at byte " + std::to_string(size) +
                     "); the recording was cut off or the file copied incompletely");
    LogEvent e;
    e.index = index;
    e.offset = offset;
    e.number = static_cast<int64_t>(be64(h + 4));
    e.timestamp_us = static_cast<int64_t>(be64(h + 12));
    const auto channel_len = static_cast<int32_t>(be32(h + 20));
    const auto data_len = static_cast<int64_t>(static_cast<int32_t>(be32(h + 24)));
    if (channel_len <= 0 || channel_len > kMaxChannel || data_len < 0 || data_len > kMaxData)
      throw LogError("the log '" + path + "' is corrupt: " + where() + " has a channel length of " +
                     std::to_string(channel_len) + " and a data length of " + std::to_string(data_len) +
                     " bytes (LCM channels have 1 to 63 characters, messages at most " +
                     std::to_string(kMaxData) + " bytes); the file was changed or damaged");
    const uint64_t end = offset + kHeaderBytes + static_cast<uint64_t>(channel_len) + static_cast<uint64_t>(data_len);
    if (end > size)
      throw LogError("the log '" + path + "' is truncated: " + where() + " needs " +
                     std::to_string(end - offset) + " bytes but the file ends after " +
                     std::to_string(size - offset) + " of them (at byte " + std::to_string(size) +
                     "); the recording was cut off or the file copied incompletely");
    e.channel.resize(static_cast<std::size_t>(channel_len));
    e.data.resize(static_cast<std::size_t>(data_len));
    if (std::fread(e.channel.data(), 1, e.channel.size(), f) != e.channel.size() ||
        std::fread(e.data.data(), 1, e.data.size(), f) != e.data.size())
      throw LogError("cannot read the log '" + path + "' at " + where() + ": " + std::strerror(errno));
    for (const char c : e.channel)
      if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7e)
        throw LogError("the log '" + path + "' is corrupt: " + where() +
                       " has a channel name with unprintable characters; the file was changed or damaged");
    offset = end;
    fn(e);
    ++index;
  }
  return index;
}

std::string log_record_channel(int64_t session) {
  // COSIM_<session>_LOG: within the session's channels, used by no participant.
  return "COSIM_" + cosim::id_hex(session) + "_LOG";
}

std::optional<std::vector<std::pair<std::string, std::string>>> parse_log_record(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line != kMagicLine) return std::nullopt;
  std::vector<std::pair<std::string, std::string>> out;
  while (std::getline(in, line)) {
    const auto colon = line.find(": ");
    if (line.empty() || line[0] == ' ') continue;
    if (colon == std::string::npos) return std::nullopt;
    std::string key = line.substr(0, colon), value = line.substr(colon + 2);
    if (key == "config" && value == "|") {  // the indented block to the end
      std::string block, l;
      while (std::getline(in, l)) block += (l.size() >= 2 ? l.substr(2) : std::string()) + "\n";
      out.emplace_back(key, block);
      break;
    }
    out.emplace_back(std::move(key), std::move(value));
  }
  return out;
}

LogDigest::LogDigest() : state_(crypto_generichash_statebytes()) {
  if (sodium_init() < 0) throw std::runtime_error("libsodium failed to initialise");
  crypto_generichash_init(reinterpret_cast<crypto_generichash_state*>(state_.data()), nullptr, 0,
                          crypto_generichash_BYTES);
}

void LogDigest::add(const std::string& channel, const void* data, std::size_t size) {
  auto* st = reinterpret_cast<crypto_generichash_state*>(state_.data());
  auto put32 = [&](std::uint32_t v) {
    const unsigned char b[4] = {static_cast<unsigned char>(v >> 24), static_cast<unsigned char>(v >> 16),
                                static_cast<unsigned char>(v >> 8), static_cast<unsigned char>(v)};
    crypto_generichash_update(st, b, 4);
  };
  put32(static_cast<std::uint32_t>(channel.size()));
  crypto_generichash_update(st, reinterpret_cast<const unsigned char*>(channel.data()), channel.size());
  put32(static_cast<std::uint32_t>(size));
  crypto_generichash_update(st, static_cast<const unsigned char*>(data), size);
}

std::string LogDigest::hex() const {
  std::vector<unsigned char> copy = state_;  // finalising consumes the state
  unsigned char out[crypto_generichash_BYTES];
  crypto_generichash_final(reinterpret_cast<crypto_generichash_state*>(copy.data()), out, sizeof out);
  static const char* digits = "0123456789abcdef";
  std::string s;
  for (unsigned char c : out) s += digits[c >> 4], s += digits[c & 15];
  return s;
}

// ---------------------------------------------------------------------------------------------

namespace {
// The recorder listens and cannot ask again: a datagram its socket buffer has no room for (its
// receive thread starved on a loaded host, a burst of redundant copies) is lost from the log. A
// multicast URL without recv_buf_size gets 4 MiB (the kernel caps it at net.core.rmem_max).
std::string recorder_url(const std::string& url) {
  if (url.rfind("udpm://", 0) != 0 || url.find("recv_buf_size=") != std::string::npos) return url;
  return url + (url.find('?') == std::string::npos ? "?" : "&") + "recv_buf_size=4194304";
}
}  // namespace

BusRecorder::BusRecorder(const std::string& path, const std::string& url, int64_t session,
                         const std::optional<cosim::auth::Key>& key, const std::string& effective_config)
    : path_(path), session_(session), lcm_(recorder_url(url)) {
  if (!lcm_.good()) throw std::runtime_error("--record: cannot open the bus '" + url + "'");
  file_ = std::make_unique<lcm::LogFile>(path, "w");
  if (!file_->good())
    throw std::runtime_error("--record: cannot create the log '" + path + "': " + std::strerror(errno) +
                             " (check that its folder exists and is writable)");
  if (key) {
    sealer_.emplace(*key, cosim::envelope_sender("recorder", session));
    opener_.emplace(*key);
  }
  // Everything of the session; the configures of participants started by hand travel on their
  // instance's channel (checked for this session in on_configure).
  lcm_.subscribe("COSIM_" + cosim::id_hex(session) + "_.*", &BusRecorder::on_message, this)
      ->setQueueCapacity(100000);
  lcm_.subscribe("COSIM_CFG_[0-9a-f]{16}", &BusRecorder::on_configure, this)->setQueueCapacity(1000);
  char host[256] = {0};
  gethostname(host, sizeof host - 1);
  std::string indented;
  {
    std::istringstream in(effective_config);
    std::string l;
    while (std::getline(in, l)) indented += "  " + l + "\n";
  }
  write_record(std::string(kMagicLine) + "\nrecord: start\nsession: " + cosim::id_hex(session) +
               "\nbus: " + url + "\nkeyed: " + (key ? "yes" : "no") + "\nhost: " + host +
               "\npid: " + std::to_string(getpid()) + "\nstarted: " + utc_now() + "\nconfig: |\n" +
               indented);
}

BusRecorder::~BusRecorder() {
  try {
    finish("stopped: the master ended without closing the recording", 0.0);
  } catch (...) {
  }
}

void BusRecorder::write(const std::string& channel, const void* data, std::size_t size, int64_t utime) {
  if (!file_) return;
  lcm::LogEvent e{};
  e.timestamp = utime;
  e.channel = channel;
  e.datalen = static_cast<int32_t>(size);
  e.data = const_cast<void*>(data);
  if (file_->writeEvent(&e) != 0)
    throw std::runtime_error("--record: cannot write to the log '" + path_ + "': " + std::strerror(errno));
  digest_.add(channel, data, size);
  ++events_;
  if (utime - last_flush_us_ > 500000) {  // a crash loses at most half a second
    if (std::fflush(file_->getFilePtr()) != 0)
      throw std::runtime_error("--record: cannot write to the log '" + path_ + "': " + std::strerror(errno));
    last_flush_us_ = utime;
  }
}

void BusRecorder::write_record(const std::string& text) {
  const std::string channel = log_record_channel(session_);
  if (sealer_) {
    const auto sealed = sealer_->seal(channel, session_, reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
    write(channel, sealed.data(), sealed.size(), now_us());
  } else {
    write(channel, text.data(), text.size(), now_us());
  }
}

// The transport edge of the recording: a buffer whose size cannot be real is counted and never
// written (its bytes are made up; LCM 1.3.1 reports about 4 GB for a truncated datagram).
bool BusRecorder::admit(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  if (!file_ || failed_) return false;
  if (rbuf && cosim::wire_size_ok(rbuf->data, rbuf->data_size)) return true;
  ++truncated_;
  refuse(channel, "a truncated datagram (LCM reports " + std::to_string(rbuf ? rbuf->data_size : 0) +
                      " bytes: it ended inside its header)", truncated_);
  return false;
}

// A few lines per kind (truncated, refused); the rest are counted.
void BusRecorder::refuse(const std::string& channel, const std::string& why, int64_t nth) {
  if (nth > kDroppedLines) return;
  const std::string line = "cosim_master: --record: dropped " + why + " on " + channel +
                           "; not written to the log" +
                           (nth == kDroppedLines ? " [further ones of this kind are counted, not logged]" : "") + "\n";
  std::fputs(line.c_str(), stderr);  // one write: participants may share the master's log
}

namespace {
template <class M>
bool decodes(const std::uint8_t* data, std::size_t size) {
  M m;
  return m.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size);
}
bool ends_with(const std::string& s, const char* tail) {
  const std::size_t n = std::strlen(tail);
  return s.size() >= n && s.compare(s.size() - n, n, tail) == 0;
}
}  // namespace

// With a key: authentic, of the session, not seen before (what a replay checks of every
// message). Without: decodes as the message its channel carries (what a replay decodes).
bool BusRecorder::genuine(const std::string& channel, const std::uint8_t* data, std::size_t size,
                          int64_t sealed_for) {
  if (opener_) {
    const auto o = opener_->open(channel, {sealed_for}, data, size);
    if (o.verdict == cosim::auth::Verdict::ok) return true;
    ++refused_;
    ++refused_by_[cosim::auth::to_string(o.verdict)];
    refuse(channel, std::string("a message that is ") + cosim::auth::to_string(o.verdict), refused_);
    return false;
  }
  bool ok = false;
  if (ends_with(channel, "_REQ")) ok = decodes<cosim::step_request_t>(data, size);
  else if (ends_with(channel, "_REP")) ok = decodes<cosim::step_reply_t>(data, size);
  else if (ends_with(channel, "_RDY")) ok = decodes<cosim::ready_t>(data, size);
  else if (ends_with(channel, "_CFG")) ok = decodes<cosim::configure_t>(data, size);
  else if (ends_with(channel, "_HB")) ok = decodes<cosim::heartbeat_t>(data, size);
  else if (ends_with(channel, "_END")) ok = decodes<cosim::terminate_t>(data, size);
  if (ok) return true;
  ++refused_;
  ++refused_by_["not decodable"];
  refuse(channel, "a message that does not decode as this channel's", refused_);
  return false;
}

void BusRecorder::write_received(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  try {
    write(channel, rbuf->data, rbuf->data_size, rbuf->recv_utime);
  } catch (const std::exception& e) {
    failed_ = e.what();  // raised outside LCM's C code, by poll() or finish()
  }
}

void BusRecorder::raise_pending() {
  if (!failed_) return;
  const std::string what = *failed_;
  file_.reset();
  finished_ = true;
  throw std::runtime_error(what);
}

void BusRecorder::on_message(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  if (!admit(rbuf, channel)) return;
  if (channel == log_record_channel(session_)) return;  // a played-back recording: not this run's
  if (!genuine(channel, static_cast<const std::uint8_t*>(rbuf->data), rbuf->data_size, session_)) return;
  write_received(rbuf, channel);
}

void BusRecorder::on_configure(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  if (!admit(rbuf, channel)) return;
  // Only the configures of this session (the payload says; sealed ones carry it in clear).
  const auto* bytes = static_cast<const std::uint8_t*>(rbuf->data);
  const std::uint8_t* payload = bytes;
  std::size_t size = rbuf->data_size;
  if (cosim::auth::looks_sealed(bytes, size)) {
    const auto p = cosim::auth::unverified_payload(bytes, size);
    if (!p) return;
    payload = p->first;
    size = p->second;
  }
  cosim::configure_t c;
  if (c.decode(payload, 0, static_cast<int>(size)) != static_cast<int>(size) || c.session_id != session_)
    return;
  // Sealed before a session exists (session 0), as the participant opens it.
  if (!genuine(channel, static_cast<const std::uint8_t*>(rbuf->data), rbuf->data_size, 0)) return;
  write_received(rbuf, channel);
}

std::string BusRecorder::dropped_text() const {
  if (dropped() == 0) return "";
  std::string s = std::to_string(truncated_) + " truncated";
  for (const auto& [why, n] : refused_by_) s += ", " + std::to_string(n) + " " + why;
  return s;
}

void BusRecorder::poll() {
  if (!file_) return;
  while (lcm_.handleTimeout(0) > 0 && !failed_) {
  }
  raise_pending();
}

void BusRecorder::finish(const std::string& status, double drain_s) {
  if (!file_ || finished_) return;
  finished_ = true;
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(drain_s);
  while (std::chrono::steady_clock::now() < until && !failed_) lcm_.handleTimeout(10);
  poll();  // raises a write that failed in a handler
  std::string one_line = status;
  for (auto& c : one_line)
    if (c == '\n') c = ' ';
  const int64_t before = events_;
  const std::string digest = digest_.hex();
  write_record(std::string(kMagicLine) + "\nrecord: end\nsession: " + cosim::id_hex(session_) +
               "\nstatus: " + one_line + "\nevents: " + std::to_string(before) + "\ndigest: " + digest +
               "\ndropped: " + std::to_string(dropped()) +
               "\nended: " + utc_now() + "\n");
  std::FILE* fp = file_->getFilePtr();
  const bool flushed = std::fflush(fp) == 0 && !std::ferror(fp);
  const int err = errno;
  file_.reset();
  if (!flushed)
    throw std::runtime_error("--record: cannot write to the log '" + path_ + "': " + std::strerror(err) +
                             "; the recording is incomplete");
}

}  // namespace master
