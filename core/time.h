// Time on driftlab's clocks: an instant (Time) and a span (Duration), each a whole number of microseconds in an
// int64_t, as LCM's `utime` fields and log event times are. Messages and logs keep their int64_t fields; code
// converts at that boundary with from_us() and us(). In seconds: seconds() is the count times 1e-6 (the
// conversion the code has always made, so every number computed from it stays the same); from seconds, the
// rounding is in the name (from_seconds_rounded, from_seconds_truncated).
// Arithmetic is int64_t arithmetic on the counts: like the numbers it wraps it does not saturate; code that meets
// hostile times checks on us() (__builtin_add_overflow) or compares in doubles (Time::seconds_since).
// Thread-safety: plain values.
#pragma once

#include <cmath>
#include <compare>
#include <cstdint>
#include <limits>

namespace driftlab {

/// A span of time [us]: the difference of two Times, a period, a delay.
class Duration {
 public:
  constexpr Duration() = default;
  static constexpr Duration from_us(int64_t us) { return Duration(us); }
  /// `s` seconds to the nearest microsecond, halves away from zero (std::llround of s * 1e6). s * 1e6 must fit
  /// int64_t (else the count is unspecified, as llround's).
  static Duration from_seconds_rounded(double s) { return Duration(static_cast<int64_t>(std::llround(s * 1e6))); }
  /// `s` seconds truncated toward zero to whole microseconds (a cast of s * 1e6, which must fit int64_t).
  static Duration from_seconds_truncated(double s) { return Duration(static_cast<int64_t>(s * 1e6)); }
  /// `n` periods of a `rate_hz` stream: n * 1e6 / rate_hz microseconds, to the nearest (std::llround). With n = 1,
  /// a timer's period (a controller at 20 Hz: 50000 us); with n counting samples, when the n-th one is due.
  static Duration periods_rounded(double rate_hz, int64_t n = 1) {
    return Duration(static_cast<int64_t>(std::llround(static_cast<double>(n) * 1e6 / rate_hz)));
  }

  constexpr int64_t us() const { return us_; }
  /// [s]: us() * 1e-6.
  constexpr double seconds() const { return static_cast<double>(us_) * 1e-6; }

  constexpr Duration operator-() const { return Duration(-us_); }
  constexpr Duration& operator+=(Duration d) {
    us_ += d.us_;
    return *this;
  }
  constexpr Duration& operator-=(Duration d) {
    us_ -= d.us_;
    return *this;
  }
  friend constexpr Duration operator+(Duration a, Duration b) { return Duration(a.us_ + b.us_); }
  friend constexpr Duration operator-(Duration a, Duration b) { return Duration(a.us_ - b.us_); }
  friend constexpr Duration operator*(Duration d, int64_t k) { return Duration(d.us_ * k); }
  friend constexpr Duration operator*(int64_t k, Duration d) { return Duration(k * d.us_); }
  /// Truncated toward zero to whole microseconds, as int64_t division.
  friend constexpr Duration operator/(Duration d, int64_t k) { return Duration(d.us_ / k); }
  /// How many whole `b` fit in `a` (truncated toward zero).
  friend constexpr int64_t operator/(Duration a, Duration b) { return a.us_ / b.us_; }
  friend constexpr auto operator<=>(const Duration&, const Duration&) = default;

 private:
  constexpr explicit Duration(int64_t us) : us_(us) {}
  int64_t us_ = 0;
};

/// The microseconds from `earlier` to `later`, 0 when later is not after earlier: exact for any two int64_t, whose
/// gap fits in uint64_t where later - earlier may overflow (hostile stamps). The one checked difference of raw
/// counts; Time::us_past is the same on Times.
constexpr uint64_t us_after(int64_t earlier, int64_t later) {
  return later > earlier ? static_cast<uint64_t>(later) - static_cast<uint64_t>(earlier) : 0;
}

/// An instant on some clock [us since its zero]: the Unix epoch for wall time and for the simulator's true time,
/// whatever a source counts from for its stamps.
class Time {
 public:
  constexpr Time() = default;
  static constexpr Time from_us(int64_t us) { return Time(us); }
  /// `s` seconds after the clock's zero, to the nearest microsecond, halves away from zero (std::llround).
  static Time from_seconds_rounded(double s) { return Time(Duration::from_seconds_rounded(s).us()); }
  /// The ends of the clock: before and after every time a log can hold.
  static constexpr Time min() { return Time(std::numeric_limits<int64_t>::min()); }
  static constexpr Time max() { return Time(std::numeric_limits<int64_t>::max()); }
  /// This time plus `s` seconds to the nearest microsecond, saturated at the clock's ends: a --start or --end of
  /// 1e308 s is after any log (max()), not an overflow back before it; NaN is max() too.
  Time plus_seconds_saturated(double s) const {
    const double us = s * 1e6;
    if (!(us < 9.2e18)) return max();
    if (us <= -9.2e18) return min();
    // The sum is checked rather than the room (INT64_MAX - us_), which overflows for a time before the clock's zero.
    int64_t sum = 0;
    if (__builtin_add_overflow(us_, static_cast<int64_t>(std::llround(us)), &sum)) return us > 0 ? max() : min();
    return Time(sum);
  }

  constexpr int64_t us() const { return us_; }
  /// [s since the clock's zero]: us() * 1e-6.
  constexpr double seconds() const { return static_cast<double>(us_) * 1e-6; }
  /// The seconds from `earlier` to this one, subtracted in doubles: defined for any two times, where (*this -
  /// earlier) would overflow int64_t on hostile stamps; exact to the microsecond while both are within 2^53 us
  /// (285 years) of zero, where it equals (*this - earlier).seconds().
  constexpr double seconds_since(Time earlier) const {
    return (static_cast<double>(us_) - static_cast<double>(earlier.us_)) * 1e-6;
  }

  /// How far this is past `earlier` [us], 0 when it is not after it: us_after, exact for any two times.
  constexpr uint64_t us_past(Time earlier) const { return us_after(earlier.us_, us_); }

  constexpr Time& operator+=(Duration d) {
    us_ += d.us();
    return *this;
  }
  constexpr Time& operator-=(Duration d) {
    us_ -= d.us();
    return *this;
  }
  friend constexpr Time operator+(Time t, Duration d) { return Time(t.us_ + d.us()); }
  friend constexpr Time operator+(Duration d, Time t) { return Time(d.us() + t.us_); }
  friend constexpr Time operator-(Time t, Duration d) { return Time(t.us_ - d.us()); }
  friend constexpr Duration operator-(Time a, Time b) { return Duration::from_us(a.us_ - b.us_); }
  friend constexpr auto operator<=>(const Time&, const Time&) = default;

 private:
  constexpr explicit Time(int64_t us) : us_(us) {}
  int64_t us_ = 0;
};

/// The seconds from `earlier` to `later`, both [us] on one clock (message stamps, a bus's times):
/// Time::seconds_since on raw counts, defined for any two int64_t.
constexpr double seconds_between(int64_t earlier, int64_t later) {
  return Time::from_us(later).seconds_since(Time::from_us(earlier));
}

}  // namespace driftlab
