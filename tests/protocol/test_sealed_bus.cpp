// cosim::SealedBus over LCM's in-process queue (memq://): without a key the bytes on the wire
// are LCM's plain encoding of the message; with one only authentic messages of the expected
// sessions open, and everything else is counted by verdict, with what it claims kept for
// diagnostics; the log is limited per verdict and channel.
#include <cosim/heartbeat_t.hpp>
#include <gtest/gtest.h>

#include <lcm/lcm-cpp.hpp>
#include <string>
#include <vector>

#include "cosim/sealed_bus.hpp"

namespace {

using cosim::SealedBus;
using Heard = SealedBus::Heard;

// Collects the raw bytes published on one LCM instance.
struct Tap {
  std::vector<std::vector<std::uint8_t>> messages;
  void on(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    const auto* d = static_cast<const std::uint8_t*>(rbuf->data);
    messages.emplace_back(d, d + rbuf->data_size);
  }
};

cosim::heartbeat_t beat(int64_t session, int64_t step) {
  cosim::heartbeat_t h{};
  h.session_id = session;
  h.sender = "mass1";
  h.host = "here";
  h.state = cosim::heartbeat_t::BUSY;
  h.step_index = step;
  return h;
}

lcm::ReceiveBuffer buffer(std::vector<std::uint8_t>& bytes) {
  lcm::ReceiveBuffer b{};
  b.data = bytes.data();
  b.data_size = static_cast<uint32_t>(bytes.size());
  return b;
}

// Publishes through `bus` and returns the bytes that went out.
template <class M>
std::vector<std::uint8_t> sent(lcm::LCM& lcm, Tap& tap, SealedBus& bus, const std::string& ch, int64_t session,
                               const M& m) {
  tap.messages.clear();
  bus.publish(ch, session, m);
  while (lcm.handleTimeout(0) > 0) {
  }
  return tap.messages.empty() ? std::vector<std::uint8_t>{} : tap.messages.back();
}

cosim::auth::Key key() { return cosim::auth::parse_key_hex(cosim::auth::new_key_hex(), "test"); }

TEST(SealedBus, WithoutAKeyTheWireFormatIsLcmsOwn) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Tap tap;
  lcm.subscribe("HB", &Tap::on, &tap);
  SealedBus plain(lcm, std::nullopt, "mass1/1", "test");
  EXPECT_FALSE(plain.keyed());
  const auto h = beat(7, 3);
  auto ours = sent(lcm, tap, plain, "HB", 7, h);
  tap.messages.clear();
  lcm.publish("HB", &h);  // LCM's typed publish
  while (lcm.handleTimeout(0) > 0) {
  }
  ASSERT_EQ(tap.messages.size(), 1u);
  EXPECT_EQ(ours, tap.messages[0]);
  cosim::heartbeat_t got;
  auto b = buffer(ours);
  ASSERT_EQ(plain.open(&b, "HB", {7}, got), Heard::ok);
  EXPECT_EQ(got.step_index, 3);
  EXPECT_EQ(plain.summary(), "");  // nothing dropped: nothing to say
}

TEST(SealedBus, OnlyAuthenticMessagesOfTheExpectedSessionOpen) {
  lcm::LCM lcm("memq://");
  Tap tap;
  lcm.subscribe(".*", &Tap::on, &tap);
  const auto k = key();
  SealedBus sender(lcm, k, cosim::envelope_sender("mass1", 1), "mass1");
  SealedBus receiver(lcm, k, cosim::envelope_sender("master", 7), "master");
  SealedBus stranger(lcm, key(), cosim::envelope_sender("mass1", 1), "stranger");
  SealedBus keyless(lcm, std::nullopt, "x", "keyless");

  cosim::heartbeat_t got;
  auto ok = sent(lcm, tap, sender, "HB", 7, beat(7, 1));
  EXPECT_TRUE(cosim::auth::looks_sealed(ok.data(), ok.size()));
  auto b = buffer(ok);
  ASSERT_EQ(receiver.open(&b, "HB", {7}, got), Heard::ok);
  EXPECT_EQ(got.step_index, 1);
  EXPECT_EQ(receiver.open(&b, "HB", {7}, got), Heard::replayed);  // the same bytes again

  auto other_session = sent(lcm, tap, sender, "HB", 8, beat(8, 2));
  b = buffer(other_session);
  EXPECT_EQ(receiver.open(&b, "HB", {7}, got), Heard::other_session);

  auto forged = sent(lcm, tap, stranger, "HB", 7, beat(7, 99));
  b = buffer(forged);
  got = {};
  EXPECT_EQ(receiver.open(&b, "HB", {7}, got), Heard::forged);
  EXPECT_EQ(got.step_index, 99);  // what it claims, for naming it: never acted upon

  auto plain = sent(lcm, tap, keyless, "HB", 7, beat(7, 5));
  b = buffer(plain);
  got = {};
  EXPECT_EQ(receiver.open(&b, "HB", {7}, got), Heard::malformed);
  EXPECT_EQ(got.step_index, 5);

  // a keyless receiver cannot check sealed messages: unreadable, claimed content kept
  b = buffer(ok);
  got = {};
  EXPECT_EQ(keyless.open(&b, "HB", {7}, got), Heard::unreadable);
  EXPECT_EQ(got.step_index, 1);

  // an authentic payload that is not a heartbeat
  std::vector<std::uint8_t> junk{1, 2, 3};
  cosim::auth::Sealer s(k, "mass1/2");
  auto sealed_junk = s.seal("HB", 7, junk.data(), junk.size());
  b = buffer(sealed_junk);
  EXPECT_EQ(receiver.open(&b, "HB", {7}, got), Heard::malformed);

  const auto st = receiver.stats();
  EXPECT_TRUE(st.keyed);
  EXPECT_EQ(st.counts.accepted, 1);
  EXPECT_EQ(st.counts.replayed, 1);
  EXPECT_EQ(st.counts.other_session, 1);
  EXPECT_EQ(st.counts.forged, 1);
  EXPECT_EQ(st.counts.malformed, 2);
  EXPECT_EQ(receiver.summary(),
            "authenticated bus: 1 message(s) accepted; dropped 2 malformed, 1 forged, 1 of another session, "
            "1 replayed");
  EXPECT_EQ(keyless.stats().unreadable, 1);
  EXPECT_EQ(keyless.summary(), "unauthenticated bus (no key): ignored 1 sealed message(s) it cannot check and 0 "
                               "that did not decode");
}

TEST(SealedBus, DroppedMessagesAreLoggedAFewPerVerdictAndChannel) {
  lcm::LCM lcm("memq://");
  SealedBus receiver(lcm, key(), "master/1", "cosim_master");
  SealedBus stranger(lcm, key(), "mass1/1", "stranger");
  Tap tap;
  lcm.subscribe(".*", &Tap::on, &tap);
  std::vector<std::vector<std::uint8_t>> a, c;
  for (int i = 0; i < 10; ++i) a.push_back(sent(lcm, tap, stranger, "A", 7, beat(7, i)));
  for (int i = 0; i < 10; ++i) c.push_back(sent(lcm, tap, stranger, "C", 7, beat(7, i)));
  testing::internal::CaptureStderr();
  cosim::heartbeat_t got;
  for (auto& m : a) {
    auto b = buffer(m);
    receiver.open(&b, "A", {7}, got);
  }
  for (auto& m : c) {
    auto b = buffer(m);
    receiver.open(&b, "C", {7}, got);
  }
  const std::string log = testing::internal::GetCapturedStderr();
  auto count = [&](const std::string& s) {
    std::size_t n = 0;
    for (auto p = log.find(s); p != std::string::npos; p = log.find(s, p + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count("cosim_master: dropped a forged message on A: "), 3u) << log;
  EXPECT_EQ(count("cosim_master: dropped a forged message on C: "), 3u) << log;
  EXPECT_EQ(count("[further ones of this kind on this channel are counted, not logged]"), 2u) << log;
  EXPECT_EQ(receiver.stats().counts.forged, 20);
}

}  // namespace

// The transport edge: a buffer as LCM 1.3.1 delivers a datagram cut inside its header (a size of
// about 4 GB, a pointer into a small buffer) is dropped before a byte of it is read, keyed or
// not, and counted as truncated within malformed; a sealed message that does open next to it
// is unaffected. (AddressSanitizer builds would report any read past `bytes`.)
TEST(SealedBus, ASizeThatCannotBeRealIsDroppedUnreadAndCounted) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  const auto k = key();
  SealedBus keyed(lcm, k, "test/1", "keyed"), plain(lcm, std::nullopt, "test/2", "plain");
  std::vector<std::uint8_t> bytes{'C', 'S', 'A', '1', 0, 0, 0, 0};
  for (const uint32_t size : {0xFFFFFFFFu, 0xFFFFFFE9u, static_cast<uint32_t>(cosim::kMaxMessageBytes) + 1}) {
    lcm::ReceiveBuffer b = buffer(bytes);
    b.data_size = size;
    cosim::heartbeat_t h;
    EXPECT_EQ(keyed.open(&b, "HB", {7}, h), Heard::truncated) << size;
    EXPECT_EQ(plain.open(&b, "HB", {7}, h), Heard::truncated) << size;
  }
  // A size within the bound is read as before.
  cosim::auth::Sealer sealer(k, "mass1/1");
  std::vector<std::uint8_t> payload(static_cast<std::size_t>(beat(7, 3).getEncodedSize()));
  beat(7, 3).encode(payload.data(), 0, static_cast<int>(payload.size()));
  auto env = sealer.seal("HB", 7, payload.data(), payload.size());
  lcm::ReceiveBuffer ok = buffer(env);
  cosim::heartbeat_t h;
  EXPECT_EQ(keyed.open(&ok, "HB", {7}, h), Heard::ok);
  EXPECT_EQ(h.step_index, 3);
  for (SealedBus* bus : {&keyed, &plain}) {
    const auto st = bus->stats();
    EXPECT_EQ(st.truncated, 3);
    EXPECT_EQ(st.counts.malformed, 3);
    EXPECT_NE(bus->summary().find("; 3 truncated datagram(s) among the malformed"), std::string::npos)
        << bus->summary();
  }
  EXPECT_EQ(keyed.stats().counts.accepted, 1);
  EXPECT_TRUE(cosim::wire_size_ok(bytes.data(), cosim::kMaxMessageBytes));
  EXPECT_FALSE(cosim::wire_size_ok(nullptr, 1));
  EXPECT_TRUE(cosim::wire_size_ok(nullptr, 0));
}
