// Message authentication (cosim/auth.hpp): a sealed message opens with the same key, channel and
// session; every change of a byte, the channel, the key or the session is refused; a replayed
// message is refused, reordered ones within the window are not; keys load from hex and files
// with clear errors.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include "cosim/auth.hpp"

namespace {

using namespace cosim::auth;

const std::string kHex = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";

std::vector<std::uint8_t> bytes(const std::string& s) { return {s.begin(), s.end()}; }

TEST(Auth, SealedMessageOpensWithTheSameKeyChannelAndSession) {
  const Key k = parse_key_hex(kHex, "test");
  Sealer s(k, "mass1");
  Opener o(k);
  const auto payload = bytes("an encoded step reply");
  const auto env = s.seal("COSIM_REPLY_1_mass1", 42, payload.data(), payload.size());
  const Opened r = o.open("COSIM_REPLY_1_mass1", {42}, env.data(), env.size());
  ASSERT_EQ(r.verdict, Verdict::ok);
  EXPECT_EQ(r.sender, "mass1");
  EXPECT_EQ(r.session, 42);
  ASSERT_EQ(r.size, payload.size());
  EXPECT_EQ(std::string(r.payload, r.payload + r.size), "an encoded step reply");
  EXPECT_EQ(o.counts().accepted, 1);
  EXPECT_EQ(o.counts().rejected(), 0);
}

TEST(Auth, EveryFlippedByteIsForgedOrMalformed) {
  const Key k = parse_key_hex(kHex, "test");
  Sealer s(k, "master");
  const auto payload = bytes("request");
  const auto env = s.seal("CH", 7, payload.data(), payload.size());
  for (std::size_t i = 0; i < env.size(); ++i) {
    Opener o(k);
    auto bad = env;
    bad[i] ^= 0x01;
    const Opened r = o.open("CH", {7}, bad.data(), bad.size());
    EXPECT_TRUE(r.verdict == Verdict::forged || r.verdict == Verdict::malformed) << "byte " << i;
    EXPECT_EQ(r.payload, nullptr);
    EXPECT_EQ(o.counts().rejected(), 1);
  }
  // truncated, empty, too long
  Opener o(k);
  EXPECT_EQ(o.open("CH", {7}, env.data(), env.size() - 1).verdict, Verdict::forged);
  EXPECT_EQ(o.open("CH", {7}, env.data(), 10).verdict, Verdict::malformed);
  EXPECT_EQ(o.open("CH", {7}, nullptr, 0).verdict, Verdict::malformed);
  auto longer = env;
  longer.push_back(0);
  EXPECT_EQ(o.open("CH", {7}, longer.data(), longer.size()).verdict, Verdict::forged);
}

TEST(Auth, OtherChannelKeyOrSessionIsRefused) {
  const Key k = parse_key_hex(kHex, "test");
  std::string other_hex = kHex;
  other_hex[0] = '1';
  const Key other = parse_key_hex(other_hex, "test");
  Sealer s(k, "master");
  const auto payload = bytes("terminate");
  const auto env = s.seal("COSIM_TERM_5", 5, payload.data(), payload.size());
  Opener o(k);
  EXPECT_EQ(o.open("COSIM_TERM_6", {5}, env.data(), env.size()).verdict, Verdict::forged);
  Opener wrong(other);
  EXPECT_EQ(wrong.open("COSIM_TERM_5", {5}, env.data(), env.size()).verdict, Verdict::forged);
  EXPECT_EQ(o.open("COSIM_TERM_5", {6}, env.data(), env.size()).verdict, Verdict::other_session);
  EXPECT_EQ(o.counts().forged, 1);
  EXPECT_EQ(o.counts().other_session, 1);
  // session 0 is accepted only where the receiver lists it
  const auto free = s.seal("COSIM_CONFIGURE", 0, payload.data(), payload.size());
  EXPECT_EQ(o.open("COSIM_CONFIGURE", {5}, free.data(), free.size()).verdict, Verdict::other_session);
  EXPECT_EQ(o.open("COSIM_CONFIGURE", {0, 5}, free.data(), free.size()).verdict, Verdict::ok);
}

TEST(Auth, ReplayIsRefusedAndReorderingWithinTheWindowIsNot) {
  const Key k = parse_key_hex(kHex, "test");
  Sealer s(k, "mass2");
  const auto payload = bytes("x");
  std::vector<std::vector<std::uint8_t>> m;
  for (int i = 0; i < 80; ++i) m.push_back(s.seal("R", 1, payload.data(), payload.size()));
  Opener o(k);
  EXPECT_EQ(o.open("R", {1}, m[10].data(), m[10].size()).verdict, Verdict::ok);
  EXPECT_EQ(o.open("R", {1}, m[10].data(), m[10].size()).verdict, Verdict::replayed);
  EXPECT_EQ(o.open("R", {1}, m[12].data(), m[12].size()).verdict, Verdict::ok);
  EXPECT_EQ(o.open("R", {1}, m[11].data(), m[11].size()).verdict, Verdict::ok);  // late, not seen
  EXPECT_EQ(o.open("R", {1}, m[11].data(), m[11].size()).verdict, Verdict::replayed);
  EXPECT_EQ(o.open("R", {1}, m[75].data(), m[75].size()).verdict, Verdict::ok);
  EXPECT_EQ(o.open("R", {1}, m[12].data(), m[12].size()).verdict, Verdict::replayed);  // 63 back, seen
  EXPECT_EQ(o.open("R", {1}, m[20].data(), m[20].size()).verdict, Verdict::ok);  // 55 back, unseen
  EXPECT_EQ(o.open("R", {1}, m[5].data(), m[5].size()).verdict, Verdict::replayed);  // 70 back: too old
  EXPECT_EQ(o.counts().replayed, 4);
  // windows are per (sender, channel): the same sequence on another channel is not a replay
  Sealer t(k, "mass2");
  const auto a = t.seal("A", 1, payload.data(), payload.size());
  Opener p(k);
  EXPECT_EQ(p.open("A", {1}, a.data(), a.size()).verdict, Verdict::ok);
  EXPECT_EQ(p.open("B", {1}, a.data(), a.size()).verdict, Verdict::forged);  // channel in the tag
  // a restarted sender continues above its old numbers (they start at the wall clock)
  Sealer restarted(k, "mass2");
  const auto after = restarted.seal("R", 1, payload.data(), payload.size());
  EXPECT_EQ(o.open("R", {1}, after.data(), after.size()).verdict, Verdict::ok);
}

TEST(Auth, KeysLoadFromHexAndPrivateFilesWithClearErrors) {
  EXPECT_EQ(parse_key_hex("  " + kHex + "\n", "x").bytes[31], 0x1f);
  auto error = [](auto f) {
    try {
      f();
    } catch (const AuthError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error([] { parse_key_hex("abc", "$COSIM_KEY"); }).find("$COSIM_KEY: a key is 64 hex digits"),
            std::string::npos);
  std::string bad = kHex;
  bad[5] = 'g';
  EXPECT_NE(error([&] { parse_key_hex(bad, "k"); }).find("'g' at position 6 is not a hex digit"),
            std::string::npos);
  const std::string path = ::testing::TempDir() + "/cosim_test_key";
  std::remove(path.c_str());
  EXPECT_NE(error([&] { read_key_file(path); }).find("not found"), std::string::npos);
  {
    std::ofstream f(path);
    f << new_key_hex() << "\n";
  }
  chmod(path.c_str(), 0644);
  EXPECT_NE(error([&] { read_key_file(path); }).find("can be read by others (mode 644); restrict it: chmod 600"),
            std::string::npos);
  chmod(path.c_str(), 0600);
  EXPECT_EQ(error([&] { read_key_file(path); }), "");
  setenv("COSIM_KEY_FILE", path.c_str(), 1);
  ASSERT_TRUE(key_from_environment().has_value());
  EXPECT_EQ(key_from_environment()->bytes, read_key_file(path).bytes);
  unsetenv("COSIM_KEY_FILE");
  setenv("COSIM_KEY", kHex.c_str(), 1);
  EXPECT_EQ(key_from_environment()->bytes[1], 0x01);
  unsetenv("COSIM_KEY");
  EXPECT_FALSE(key_from_environment().has_value());
  std::remove(path.c_str());
  // two new keys differ
  EXPECT_NE(new_key_hex(), new_key_hex());
}

}  // namespace
