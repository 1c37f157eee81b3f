// Writes the seed corpus of the message fuzzer (tests/fuzz/corpus/messages): one valid
// datagram of every message type the processes exchange, each prefixed by the fuzzer's two
// selector bytes. Run once when a message changes: fuzz_seeds tests/fuzz/corpus/messages
// With a second folder, also the seeds of fuzz_datagrams: each message as a whole LCM datagram
// on its channel, plain and sealed with the fuzzer's key, the same cut right after its channel
// name (a truncated datagram), and a small LCM log with a record (scripts/fuzz.sh).
#include <cosim/announce_t.hpp>
#include <cosim/auth.hpp>
#include <cosim/bus.hpp>
#include <cosim/heartbeat_t.hpp>
#include <cosim/terminate_t.hpp>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "fuzz_model.hpp"

namespace {

template <class M>
void write(const std::string& dir, const std::string& name, uint8_t which, uint8_t patch, const M& m) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  std::ofstream out(dir + "/" + name, std::ios::binary);
  out.put(static_cast<char>(which)).put(static_cast<char>(patch));
  out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
}

template <class M>
std::vector<std::uint8_t> encoded(const M& m) {
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  return buf;
}

void write_bytes(const std::string& path, const std::vector<std::uint8_t>& b) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

// fuzz_datagrams' key (the same bytes as in fuzz_datagrams.cpp).
cosim::auth::Key fuzz_key() {
  cosim::auth::Key k;
  for (std::size_t i = 0; i < k.bytes.size(); ++i) k.bytes[i] = static_cast<unsigned char>(i * 7 + 1);
  return k;
}

// Selector bytes, then "LC02", a sequence number, the channel, NUL and the payload (plain or
// sealed for `session`); and the same datagram cut right after the channel name.
void write_datagram(const std::string& dir, const std::string& name, int receiver, const std::string& channel,
                    std::int64_t session, const std::vector<std::uint8_t>& payload) {
  for (int keyed = 0; keyed < 2; ++keyed) {
    std::vector<std::uint8_t> body = payload;
    if (keyed) {
      cosim::auth::Sealer sealer(fuzz_key(), "seeds/1");
      body = sealer.seal(channel, session, payload.data(), payload.size());
    }
    std::vector<std::uint8_t> d{static_cast<std::uint8_t>(receiver << 1 | keyed), 0, 'L', 'C', '0', '2', 0, 0, 0, 1};
    d.insert(d.end(), channel.begin(), channel.end());
    const std::size_t cut = d.size();
    d.push_back(0);
    d.insert(d.end(), body.begin(), body.end());
    const std::string tag = name + (keyed ? "_sealed" : "_plain");
    write_bytes(dir + "/" + tag, d);
    d.resize(cut);
    write_bytes(dir + "/" + tag + "_truncated", d);
  }
}

void put32(std::vector<std::uint8_t>& b, std::uint32_t v) {
  for (int i = 3; i >= 0; --i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

void write_datagram_seeds(const std::string& dir, const cosim::configure_t& configure, const cosim::ready_t& ready,
                          const cosim::step_request_t& request, const cosim::step_reply_t& reply,
                          const cosim::heartbeat_t& h, const cosim::terminate_t& t, const cosim::announce_t& a) {
  using namespace cosim;
  const std::int64_t s = fuzz::kSession;
  const std::string p = fuzz::kName;
  write_datagram(dir, "announce", 0, channel::announce(), 0, encoded(a));
  write_datagram(dir, "configure", 1, channel::configure(s, p), s, encoded(configure));
  write_datagram(dir, "ready", 2, channel::ready(s, p), s, encoded(ready));
  write_datagram(dir, "request", 3, channel::request(s, p), s, encoded(request));
  write_datagram(dir, "reply", 4, channel::reply(s, p), s, encoded(reply));
  write_datagram(dir, "heartbeat", 5, channel::heartbeat(s), s, encoded(h));
  write_datagram(dir, "terminate", 6, channel::terminate(s), s, encoded(t));
  write_datagram(dir, "recorder_reply", 7, channel::reply(s, p), s, encoded(reply));
  cosim::configure_t to_instance = configure;
  to_instance.instance_id = 5;
  write_datagram(dir, "recorder_configure", 8, channel::configure(5), 0, encoded(to_instance));
  // An LCM log of one record: sync word, event number, timestamp, channel and data lengths.
  const std::string channel = "COSIM_" + id_hex(s) + "_LOG";
  const std::string record = "cosim bus log 1\nrecord: start\nsession: " + id_hex(s) + "\nconfig: |\n  a: 1\n";
  std::vector<std::uint8_t> log{9 << 1, 0};
  put32(log, 0xEDA1DA01u);
  put32(log, 0);
  put32(log, 0);
  put32(log, 0);
  put32(log, 1);
  put32(log, static_cast<std::uint32_t>(channel.size()));
  put32(log, static_cast<std::uint32_t>(record.size()));
  log.insert(log.end(), channel.begin(), channel.end());
  log.insert(log.end(), record.begin(), record.end());
  write_bytes(dir + "/log_record", log);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2 && argc != 3) {
    std::fprintf(stderr, "usage: fuzz_seeds DIR [DATAGRAM_DIR]\n");
    return 2;
  }
  const std::string dir = argv[1];
  fuzz::Model model;
  cosim::ParticipantCore core(fuzz::kName, model);
  const cosim::ready_t ready = *core.configure(fuzz::configure_message());
  const cosim::step_request_t request = fuzz::request_message();
  const cosim::step_reply_t reply = *core.handle(request);
  write(dir, "configure", 0, 0, fuzz::configure_message());
  write(dir, "request", 1, 0, request);
  write(dir, "ready", 2, 0, ready);
  write(dir, "reply", 3, 0, reply);
  cosim::heartbeat_t h{};
  h.session_id = fuzz::kSession;
  h.sender = "master";
  write(dir, "heartbeat", 4, 0, h);
  cosim::terminate_t t{};
  t.session_id = fuzz::kSession;
  t.reason = "done";
  write(dir, "terminate", 5, 0, t);
  cosim::announce_t a{};
  a.protocol_version = cosim::kProtocolVersion;
  a.participant = fuzz::kName;
  a.host = "localhost";
  write(dir, "announce", 6, 0, a);
  if (argc == 3) write_datagram_seeds(argv[2], fuzz::configure_message(), ready, request, reply, h, t, a);
  return 0;
}
