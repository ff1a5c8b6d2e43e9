// core/wall_clock.h: the system wall clock is the time of day; a Stopwatch counts up from its start.
#include "core/wall_clock.h"

#include <gtest/gtest.h>

#include <chrono>

namespace driftlab {
namespace {

TEST(SystemWallClock, IsTheTimeOfDayInMicrosecondsSinceTheEpoch) {
  const auto before = std::chrono::system_clock::now();
  const Time now = SystemWallClock().now();
  const auto after = std::chrono::system_clock::now();
  auto us = [](std::chrono::system_clock::time_point t) {
    return std::chrono::duration_cast<std::chrono::microseconds>(t.time_since_epoch()).count();
  };
  // The same clock read between two reads of it (a step of the date between them is the only way this fails).
  EXPECT_LE(us(before), now.us());
  EXPECT_LE(now.us(), us(after) + 1);
}

TEST(Stopwatch, CountsElapsedSecondsFromItsStart) {
  Stopwatch watch;
  const double first = watch.seconds();
  EXPECT_GE(first, 0.0);
  EXPECT_GE(watch.seconds(), first);  // steady: never back
  watch.restart();
  EXPECT_GE(watch.seconds(), 0.0);
}

}  // namespace
}  // namespace driftlab
