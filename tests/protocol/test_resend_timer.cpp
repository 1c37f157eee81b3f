// The master's adaptive resend timeout (RFC 6298 style): estimates, floor, compute time kept
// apart from the network round trip, backoff and cap.
#include <cosim/resend_timer.hpp>
#include <gtest/gtest.h>

#include <limits>

using cosim::ResendTimer;

TEST(ResendTimer, StartsAtTheInitialTimeoutAndFollowsRfc6298) {
  ResendTimer t;
  EXPECT_FALSE(t.has_sample());
  EXPECT_DOUBLE_EQ(t.base(), ResendTimer::kInitial);
  t.sample(0.004, 0.0);  // first: SRTT = R, RTTVAR = R/2
  EXPECT_DOUBLE_EQ(t.srtt(), 0.004);
  EXPECT_DOUBLE_EQ(t.rttvar(), 0.002);
  EXPECT_DOUBLE_EQ(t.base(), 0.004 + 4 * 0.002);
  t.sample(0.002, 0.0);  // RTTVAR = 3/4 0.002 + 1/4 |0.004 - 0.002|, SRTT = 7/8 0.004 + 1/8 0.002
  EXPECT_DOUBLE_EQ(t.rttvar(), 0.75 * 0.002 + 0.25 * 0.002);
  EXPECT_DOUBLE_EQ(t.srtt(), 0.875 * 0.004 + 0.125 * 0.002);
}

TEST(ResendTimer, LoopbackRoundTripsAreFlooredAndComputeTimeIsWaitedForApart) {
  ResendTimer t;
  for (int i = 0; i < 50; ++i) t.sample(60e-6, 10e-6);
  EXPECT_NEAR(t.srtt(), 50e-6, 1e-12);
  EXPECT_DOUBLE_EQ(t.base(), ResendTimer::kFloor + t.expected_compute());
  // A participant whose steps take 0.2 s: the network part stays small, the wait covers the step.
  ResendTimer slow;
  for (int i = 0; i < 50; ++i) slow.sample(0.2 + 80e-6, 0.2);
  EXPECT_NEAR(slow.srtt(), 80e-6, 1e-9);
  EXPECT_GT(slow.base(), 0.2);
  EXPECT_LT(slow.base(), 0.2 + 2 * ResendTimer::kFloor);
}

TEST(ResendTimer, BacksOffByDoublingUpToTheCap) {
  ResendTimer t;
  for (int i = 0; i < 50; ++i) t.sample(0.003, 0.0);
  const double b = t.base();
  EXPECT_DOUBLE_EQ(t.timeout(0), b);
  EXPECT_DOUBLE_EQ(t.timeout(1), 2 * b);
  EXPECT_DOUBLE_EQ(t.timeout(3), 8 * b);
  EXPECT_DOUBLE_EQ(t.timeout(40), ResendTimer::kCap);
  for (int k = 1; k < 40; ++k) EXPECT_GE(t.timeout(k), t.timeout(k - 1));
}

TEST(ResendTimer, IgnoresNonFiniteSamples) {
  ResendTimer t;
  t.sample(std::numeric_limits<double>::quiet_NaN(), 0.0);
  t.sample(0.001, std::numeric_limits<double>::infinity());
  EXPECT_FALSE(t.has_sample());
}
