// core/time.h: Time and Duration, their conversions to and from seconds (each rounding named), and arithmetic.
#include "core/time.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>

namespace driftlab {
namespace {

// The values are microsecond counts, usable in constant expressions.
static_assert(Duration::from_us(1500).us() == 1500);
static_assert(Time::from_us(10) - Time::from_us(4) == Duration::from_us(6));
static_assert(Time::from_us(10) + Duration::from_us(5) == Time::from_us(15));
static_assert(Time{} == Time::from_us(0) && Duration{} == Duration::from_us(0));

TEST(Duration, SecondsAreTheCountTimes1eMinus6) {
  // Not count / 1e6: the two differ in the last bit for 5 us, and every number driftlab writes in seconds was
  // computed as count * 1e-6, so the type computes it that way too.
  EXPECT_EQ(Duration::from_us(5).seconds(), static_cast<double>(5) * 1e-6);
  EXPECT_NE(Duration::from_us(5).seconds(), 5 / 1e6);
  EXPECT_EQ(Duration::from_us(1234567).seconds(), 1.234567);
  EXPECT_EQ(Duration::from_us(-250000).seconds(), -0.25);
  EXPECT_EQ(Time::from_us(1700000000123456).seconds(), static_cast<double>(1700000000123456) * 1e-6);
}

TEST(Duration, FromSecondsRoundsToTheNearestHalvesAwayFromZero) {
  EXPECT_EQ(Duration::from_seconds_rounded(0.1234567).us(), 123457);
  EXPECT_EQ(Duration::from_seconds_rounded(-0.1234567).us(), -123457);
  EXPECT_EQ(Duration::from_seconds_rounded(2.5e-6).us(), 3);  // 2.5e-6 * 1e6 is exactly 2.5
  EXPECT_EQ(Duration::from_seconds_rounded(-2.5e-6).us(), -3);
  EXPECT_EQ(Duration::from_seconds_rounded(0.02).us(), 20000);
  EXPECT_EQ(Time::from_seconds_rounded(1700000000.1234567).us(), 1700000000123457);
}

TEST(Duration, FromSecondsTruncatedDropsTheFractionTowardZero) {
  EXPECT_EQ(Duration::from_seconds_truncated(0.1234567).us(), 123456);
  EXPECT_EQ(Duration::from_seconds_truncated(-0.1234567).us(), -123456);
  EXPECT_EQ(Duration::from_seconds_truncated(2.5e-6).us(), 2);
  EXPECT_EQ(Duration::from_seconds_truncated(1.0).us(), 1000000);
}

TEST(Duration, PeriodsOfARate) {
  EXPECT_EQ(Duration::periods_rounded(20).us(), 50000);
  EXPECT_EQ(Duration::periods_rounded(3).us(), 333333);
  EXPECT_EQ(Duration::periods_rounded(3, 2).us(), 666667);  // the second sample, rounded once (not 2 * 333333)
  EXPECT_EQ(Duration::periods_rounded(7).us(), 142857);
  EXPECT_EQ(Duration::periods_rounded(200, 0).us(), 0);
}

TEST(Duration, Arithmetic) {
  const auto a = Duration::from_us(7), b = Duration::from_us(2);
  EXPECT_EQ(a + b, Duration::from_us(9));
  EXPECT_EQ(a - b, Duration::from_us(5));
  EXPECT_EQ(-a, Duration::from_us(-7));
  EXPECT_EQ(a * 3, Duration::from_us(21));
  EXPECT_EQ(3 * a, Duration::from_us(21));
  EXPECT_EQ(a / 2, Duration::from_us(3));
  EXPECT_EQ(-a / 2, Duration::from_us(-3));  // toward zero
  EXPECT_EQ(a / b, 3);
  EXPECT_LT(b, a);
  EXPECT_GE(a, a);
  Duration c = a;
  c += b;
  EXPECT_EQ(c, Duration::from_us(9));
  c -= a;
  EXPECT_EQ(c, b);
}

TEST(Time, InstantsAndDurations) {
  const auto t0 = Time::from_us(1700000000000000);
  const auto period = Duration::from_us(50000);
  const Time t1 = t0 + period * 3;
  EXPECT_EQ(t1 - t0, Duration::from_us(150000));
  EXPECT_EQ(t1 - period, t0 + 2 * period);
  EXPECT_EQ(period + t0, t0 + period);
  EXPECT_LT(t0, t1);
  EXPECT_EQ((t1 - t0).seconds(), 0.15);
  Time t = t0;
  t += period;
  t -= Duration::from_us(1);
  EXPECT_EQ(t.us(), 1700000000049999);
}

TEST(Time, PlusSecondsSaturatesAtTheEndOfTheClock) {
  const Time t = Time::from_us(1000);
  EXPECT_EQ(t.plus_seconds_saturated(1.5), Time::from_us(1501000));
  EXPECT_EQ(t.plus_seconds_saturated(0), t);
  // A --start or --end past any log is after it, not an overflow back before its start.
  EXPECT_EQ(t.plus_seconds_saturated(1e308), Time::max());
  EXPECT_EQ(Time::max().plus_seconds_saturated(1e-6), Time::max());
  // Before the clock's zero (a hostile log's first stamp), the room to the end is more than INT64_MAX.
  EXPECT_EQ(Time::from_us(-1'000'000).plus_seconds_saturated(2), Time::from_us(1'000'000));
  EXPECT_EQ(Time::min().plus_seconds_saturated(1e308), Time::max());
  EXPECT_EQ(Time::min().plus_seconds_saturated(std::nan("")), Time::max());
  EXPECT_EQ(Time::from_us(-5).plus_seconds_saturated(-1e308), Time::min());
  EXPECT_EQ(Time::min().plus_seconds_saturated(-1), Time::min());
  EXPECT_EQ(Time::min().us(), std::numeric_limits<int64_t>::min());
  EXPECT_LT(Time::min(), Time::from_us(std::numeric_limits<int64_t>::min() + 1));
}

TEST(Time, SecondsSinceIsDefinedForAnyTwoTimes) {
  const auto a = Time::from_us(1700000000250000), b = Time::from_us(1700000000000000);
  EXPECT_EQ(a.seconds_since(b), (a - b).seconds());  // exact below 2^53 us
  EXPECT_EQ(b.seconds_since(a), -0.25);
  // Hostile stamps: the int64_t difference would overflow; in doubles it is about 1.8e13 s.
  const auto lo = Time::from_us(std::numeric_limits<int64_t>::min());
  const auto hi = Time::from_us(std::numeric_limits<int64_t>::max());
  EXPECT_DOUBLE_EQ(hi.seconds_since(lo), 2 * 9.223372036854775807e12);
}

}  // namespace
}  // namespace driftlab
