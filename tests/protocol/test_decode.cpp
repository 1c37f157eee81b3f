// Damaged or forged datagrams are decoding errors, never exceptions or huge allocations
// (lcmtypes/harden.cmake; found by tests/fuzz/fuzz_messages, whose corpus replays the input).
#include <cosim/ready_t.hpp>
#include <cosim/step_request_t.hpp>
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

namespace {

template <class M>
std::vector<char> encoded(const M& m) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  return buf;
}

void put_int32(std::vector<char>& buf, std::size_t at, int32_t v) {
  const unsigned char b[4] = {static_cast<unsigned char>(v >> 24), static_cast<unsigned char>(v >> 16),
                              static_cast<unsigned char>(v >> 8), static_cast<unsigned char>(v)};
  std::memcpy(buf.data() + at, b, 4);
}

}  // namespace

TEST(Decode, AStringLengthBelowOneIsADecodingError) {
  cosim::ready_t r{};
  r.participant = "p";
  r.error = "e";
  std::vector<char> buf = encoded(r);
  cosim::ready_t out;
  ASSERT_GT(out.decode(buf.data(), 0, static_cast<int>(buf.size())), 0);
  // fingerprint 8, protocol_version 4, session_id 8: the participant's length follows
  for (const int32_t bad : {0, -1, -2147483647}) {
    put_int32(buf, 20, bad);
    EXPECT_EQ(out.decode(buf.data(), 0, static_cast<int>(buf.size())), -1) << bad;
  }
}

TEST(Decode, AnArrayCountTheBytesCannotHoldIsADecodingError) {
  cosim::step_request_t q{};
  q.participant = "p";
  std::vector<char> buf = encoded(q);
  cosim::step_request_t out;
  ASSERT_GT(out.decode(buf.data(), 0, static_cast<int>(buf.size())), 0);
  // the inputs' n_scalars is the first field after the fixed part of the request (its last
  // three fields: want_average, checkpoint, no_redo)
  const std::size_t at = 8 + 8 + (4 + 2) + 8 + 4 + 4 + 8 + 8 + 1 + 1 + 1;
  ASSERT_EQ(buf.size(), at + 3 * 4) << "the request's layout changed: fix the offset";  // 3 empty counts
  for (const int32_t bad : {-1, 100000, 2147483647}) {
    put_int32(buf, at, bad);
    EXPECT_EQ(out.decode(buf.data(), 0, static_cast<int>(buf.size())), -1) << bad;
  }
}
