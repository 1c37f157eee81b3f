// Time as types: durations and time points in integer nanoseconds that cannot be mixed up,
// the arithmetic between them, and seconds only through the edge conversions.
#include <cosim/time.hpp>
#include <cosim/yaml_config.hpp>
#include <gtest/gtest.h>

#include <functional>
#include <type_traits>

using namespace cosim;

// A time point is not a duration, and neither is a plain integer.
static_assert(!std::is_convertible_v<Duration, TimePoint>);
static_assert(!std::is_convertible_v<TimePoint, Duration>);
static_assert(!std::is_convertible_v<std::int64_t, Duration>);
static_assert(!std::is_convertible_v<std::int64_t, TimePoint>);
// Adding two instants means nothing; their difference is a duration.
static_assert(!std::is_invocable_v<std::plus<>, TimePoint, TimePoint>);
static_assert(std::is_same_v<decltype(TimePoint{} - TimePoint{}), Duration>);
static_assert(std::is_same_v<decltype(TimePoint{} + Duration{}), TimePoint>);
static_assert(std::is_same_v<decltype(Duration{} * std::int64_t{3}), Duration>);

TEST(Time, ArithmeticInNanoseconds) {
  const TimePoint t0 = time_point_ns(2'000'000), t1 = time_point_ns(5'000'000);
  const Duration h = nanoseconds(1'000'000);
  EXPECT_EQ(t1 - t0, nanoseconds(3'000'000));
  EXPECT_EQ(t0 + 3 * h, t1);
  EXPECT_EQ(t1 - h * 3, t0);
  EXPECT_EQ((t1 - t0) / h, 3);
  EXPECT_EQ(nanoseconds(3'500'000) % h, nanoseconds(500'000));
  EXPECT_LT(t0, t1);
  EXPECT_GT(h, Duration::zero());
  EXPECT_EQ(to_ns(t1), 5'000'000);
  EXPECT_EQ(to_ns(h), 1'000'000);
  TimePoint t = t0;
  t += h;
  EXPECT_EQ(t, time_point_ns(3'000'000));
}

TEST(Time, SecondsAtTheEdges) {
  // to_seconds is ns * 1e-9 as a double, for time points and durations alike
  EXPECT_EQ(to_seconds(time_point_ns(123'456'789)), static_cast<double>(123'456'789) * 1e-9);
  EXPECT_EQ(to_seconds(nanoseconds(2'500'000)), static_cast<double>(2'500'000) * 1e-9);
  EXPECT_EQ(seconds_to_duration(2.5e-3, "step"), nanoseconds(2'500'000));
  EXPECT_EQ(seconds_to_time_point(1.0, "time.end"), time_point_ns(1'000'000'000));
  try {
    seconds_to_duration(1e-10, "time.macro_step");
    ADD_FAILURE() << "a tenth of a nanosecond accepted";
  } catch (const config::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("time.macro_step"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("whole number of nanoseconds"), std::string::npos);
  }
  EXPECT_THROW(seconds_to_time_point(-0.5, "time.start"), config::ConfigError);
  EXPECT_THROW(seconds_to_duration(std::nan(""), "t"), config::ConfigError);
}
