// libFuzzer target: the transport edge (docs/protocol.md#bounds-at-the-transport-edge) driven with
// raw UDP datagrams, keyed and unkeyed, as LCM 1.3.1 hands them to the processes' handlers.
//
// Input: byte 0 selects (bit 0: keyed; (byte 0 >> 1) % 10: the receiver), byte 1 is what LCM's
// receive buffer holds past the datagram (0: a fresh, zeroed buffer; else stale bytes of that
// value), the rest is the datagram exactly as it travels ("LC02", sequence number, channel, NUL,
// message). The harness parses it as LCM 1.3.1 does (lcm_udpm.c, _recv_short_message): the
// channel is read up to the first NUL in the 64 KiB buffer, even past the datagram's end, and the
// message size is the datagram's length minus the header's, as a uint32, so a datagram cut inside
// its header arrives with a size of about 4 GB and a pointer into the buffer. Receivers:
//   0-6  SealedBus::open of announce_t, configure_t, ready_t, step_request_t, step_reply_t,
//        heartbeat_t, terminate_t (every handler of the master and the participants starts there)
//   7    the recorder's handler of the session's channels (BusRecorder::on_message, --record)
//   8    the recorder's handler of configures to instances (BusRecorder::on_configure)
//   9    the rest of the input as an LCM log file for replay's reader (read_lcm_log) and the
//        master's records in it (parse_log_record)
// A buffer the edge lets through is read only within the datagram: AddressSanitizer reports a read
// of a made-up size past the 64 KiB buffer. Keyed seeds are sealed with kKey (fuzz_seeds).
#include <cosim/announce_t.hpp>
#include <cosim/bus.hpp>
#include <cosim/heartbeat_t.hpp>
#include <cosim/sealed_bus.hpp>
#include <cosim/terminate_t.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

#include "bus_log.hpp"
#include "fuzz_model.hpp"

namespace {

using namespace cosim;

constexpr std::size_t kBuffer = 65536;  // LCM 1.3.1's receive buffer; byte 65536 stays 0

auth::Key fuzz_key() {
  auth::Key k;
  for (std::size_t i = 0; i < k.bytes.size(); ++i) k.bytes[i] = static_cast<unsigned char>(i * 7 + 1);
  return k;
}

struct Receivers {
  lcm::LCM lcm{"memq://"};
  SealedBus plain{lcm, std::nullopt, "fuzz/1", "fuzz"};
  SealedBus keyed{lcm, fuzz_key(), "fuzz/2", "fuzz"};
  master::BusRecorder plain_recorder{"/dev/null", "memq://", fuzz::kSession, std::nullopt, ""};
  master::BusRecorder keyed_recorder{"/dev/null", "memq://", fuzz::kSession, fuzz_key(), ""};
};

Receivers& receivers() {
  static Receivers* r = new Receivers();  // (their drop lines are few: each logs a bounded number)
  return *r;
}

template <class M>
void open_as(SealedBus& bus, const lcm::ReceiveBuffer& rbuf, const std::string& channel) {
  M m;
  bus.open(&rbuf, channel, {0, fuzz::kSession}, m);
}

void read_log(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return;
  std::FILE* f = fmemopen(const_cast<std::uint8_t*>(data), size, "rb");
  if (!f) return;
  try {
    master::read_lcm_log(f, "fuzz", [](master::LogEvent& e) {
      master::parse_log_record(std::string(e.data.begin(), e.data.end()));
    });
  } catch (const master::LogError&) {
  }
  std::fclose(f);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const bool keyed = data[0] & 1;
  const int which = (data[0] >> 1) % 10;
  const std::uint8_t stale = data[1];
  data += 2;
  size -= 2;
  Receivers& r = receivers();
  if (which == 9) {
    read_log(data, size);
    return 0;
  }
  // LCM 1.3.1: recvmsg into a 65535-byte window of its buffer; shorter than its 8-byte header or
  // another magic than "LC02" (a fragment, "LC03", is reassembled to its real size) is dropped.
  if (size < 8 || size > kBuffer - 1 || std::memcmp(data, "LC02", 4) != 0) return 0;
  std::vector<std::uint8_t> buf(kBuffer + 1, stale);
  buf[kBuffer] = 0;
  std::memcpy(buf.data(), data, size);
  const char* channel_start = reinterpret_cast<const char*>(buf.data() + 8);
  const std::size_t channel_len = std::strlen(channel_start);
  if (channel_len > 63) return 0;  // LCM_MAX_CHANNEL_NAME_LENGTH
  const std::string channel(channel_start, channel_len);
  const std::size_t data_offset = 8 + channel_len + 1;
  lcm::ReceiveBuffer rbuf{};
  rbuf.data = buf.data() + data_offset;
  rbuf.data_size = static_cast<std::uint32_t>(static_cast<int>(size) - static_cast<int>(data_offset));
  rbuf.recv_utime = 1;
  SealedBus& bus = keyed ? r.keyed : r.plain;
  switch (which) {
    case 0: open_as<announce_t>(bus, rbuf, channel); break;
    case 1: open_as<configure_t>(bus, rbuf, channel); break;
    case 2: open_as<ready_t>(bus, rbuf, channel); break;
    case 3: open_as<step_request_t>(bus, rbuf, channel); break;
    case 4: open_as<step_reply_t>(bus, rbuf, channel); break;
    case 5: open_as<heartbeat_t>(bus, rbuf, channel); break;
    case 6: open_as<terminate_t>(bus, rbuf, channel); break;
    case 7: (keyed ? r.keyed_recorder : r.plain_recorder).on_message(&rbuf, channel); break;
    case 8: (keyed ? r.keyed_recorder : r.plain_recorder).on_configure(&rbuf, channel); break;
  }
  return 0;
}
