// Writes the seed corpus of the message fuzzer (tests/fuzz/corpus/messages): one valid
// datagram of every message type the processes exchange, each prefixed by the fuzzer's two
// selector bytes. Run once when a message changes: fuzz_seeds tests/fuzz/corpus/messages
#include <cosim/announce_t.hpp>
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

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_seeds DIR\n");
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
  return 0;
}
