// libFuzzer target: LCM message decoding and the validation that follows it, on both sides.
// The first byte picks the message type; the rest is the datagram as LCM delivers it
// (fingerprint + fields). Decoded messages go where the processes send them:
//   configure_t    -> ParticipantCore::configure (a fresh participant)
//   step_request_t -> ParticipantCore::handle (a participant bound to session 7)
//   ready_t        -> the master's acceptance of a ready (ports, initial outputs)
//   step_reply_t   -> the master's acceptance of a reply to a fixed request
//   heartbeat_t, terminate_t, announce_t -> decoding only
// Byte 1, bit 0 set: the harness writes the expected session and name into the decoded
// request or reply, so the fuzzer reaches the validation behind those checks.
#include <cosim/announce_t.hpp>
#include <cosim/heartbeat_t.hpp>
#include <cosim/terminate_t.hpp>

#include <cstddef>
#include <cstdint>

#include "cosim/link.hpp"
#include "cosim/participant.hpp"
#include "fuzz_model.hpp"

namespace {

using namespace cosim;

// Exposes the master's validation of replies (Transport::accept, accept_ready).
class Acceptor final : public Transport {
 public:
  int64_t session() const override { return fuzz::kSession; }
  std::map<std::string, ParticipantInfo> connect(const std::vector<configure_t>&, double) override { return {}; }
  std::vector<StepAnswer> exchange(const std::vector<step_request_t>&) override { return {}; }
  void terminate(bool, const std::string&) override {}
  std::string describe() const override { return "fuzz"; }
  using Transport::accept;
  using Transport::accept_ready;
};

template <class M>
bool decode(const uint8_t* data, size_t size, M& m) {
  return m.decode(data, 0, static_cast<int>(size)) >= 0;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const int which = data[0] % 7;
  const bool patch = data[1] & 1;
  data += 2;
  size -= 2;
  try {
    switch (which) {
      case 0: {
        configure_t m;
        if (!decode(data, size, m)) return 0;
        fuzz::Model model;
        ParticipantCore core(fuzz::kName, model);
        core.configure(m);
        core.configure(m);  // a resend gets the cached answer
        break;
      }
      case 1: {
        step_request_t q;
        if (!decode(data, size, q)) return 0;
        if (patch) {
          q.session_id = fuzz::kSession;
          q.participant = fuzz::kName;
        }
        fuzz::Model model;
        ParticipantCore core(fuzz::kName, model);
        if (!core.configure(fuzz::configure_message())->ok) __builtin_trap();
        if (auto r = core.handle(q)) {
          std::vector<uint8_t> buf(static_cast<size_t>(r->getEncodedSize()));
          if (r->encode(buf.data(), 0, static_cast<int>(buf.size())) < 0) __builtin_trap();
        }
        core.handle(q);  // a duplicate
        break;
      }
      case 2: {
        ready_t r;
        if (!decode(data, size, r)) return 0;
        Acceptor a;
        a.accept_ready(r);
        break;
      }
      case 3: {
        step_reply_t r;
        if (!decode(data, size, r)) return 0;
        if (patch) {
          r.session_id = fuzz::kSession;
          r.participant = fuzz::kName;
        }
        Acceptor a;
        const ParticipantInfo info = a.accept_ready(fuzz::ready_message());
        a.accept(fuzz::request_message(), r, info, 0.001);
        break;
      }
      case 4: {
        heartbeat_t h;
        decode(data, size, h);
        break;
      }
      case 5: {
        terminate_t t;
        decode(data, size, t);
        break;
      }
      default: {
        announce_t a;
        decode(data, size, a);
        break;
      }
    }
  } catch (const ProtocolError&) {
  } catch (const LinkError&) {
  }
  // Anything else escaping (std::length_error, std::bad_alloc, YAML exceptions) would end a
  // process: libFuzzer reports it as a crash.
  return 0;
}
