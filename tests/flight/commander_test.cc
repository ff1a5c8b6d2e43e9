// The commander: offboard needs a setpoint stream first (PX4's rule), arming needs an estimate and the ground, a
// gap in the stream longer than the timeout falls back to hold and later to a landing, and the land detector
// disarms after touchdown.
#include "flight/commander.h"

#include <gtest/gtest.h>

namespace driftlab::flight {
namespace {

constexpr int64_t kS = 1000000;

TEST(Commander, OffboardNeedsAStreamAndArmingAnEstimate) {
  Commander c{CommanderOptions{}};
  EXPECT_FALSE(c.command("offboard", Time::from_us(0), true));
  EXPECT_NE(c.reason().find("setpoints must stream first"), std::string::npos) << c.reason();
  c.on_setpoint(Time::from_us(0));
  EXPECT_FALSE(c.command("offboard", Time::from_us(100000), true));  // one setpoint is no stream (2 per second needed)
  for (int i = 1; i <= 20; ++i) c.on_setpoint(Time::from_us(int64_t{i} * 50000));
  EXPECT_TRUE(c.command("offboard", Time::from_us(kS), true));
  EXPECT_EQ(c.mode(), Mode::kOffboard);
  EXPECT_FALSE(c.command("arm", Time::from_us(kS), false));
  EXPECT_NE(c.reason().find("no fresh estimate"), std::string::npos);
  EXPECT_TRUE(c.command("arm", Time::from_us(kS), true));
  EXPECT_TRUE(c.armed());
  EXPECT_FALSE(c.command("fly", Time::from_us(kS), true));
}

TEST(Commander, ASetpointGapFallsBackToHoldThenLands) {
  CommanderOptions o;
  o.failsafe_land_after_s = 3;
  Commander c{o};
  int64_t t = 0;
  for (; t <= kS; t += 50000) c.on_setpoint(Time::from_us(t));
  ASSERT_TRUE(c.command("offboard", Time::from_us(t), true));
  ASSERT_TRUE(c.command("arm", Time::from_us(t), true));
  c.update(Time::from_us(t), 1.5, 1.0, 0);  // climbing: airborne
  ASSERT_FALSE(c.landed());
  EXPECT_FALSE(c.command("disarm", Time::from_us(t), true));
  // 0.4 s without a setpoint: still offboard (timeout 0.5 s).
  c.update(Time::from_us(t + 400000), 1.0, 0, 0);
  EXPECT_EQ(c.mode(), Mode::kOffboard);
  c.update(Time::from_us(t + 600000), 1.0, 0, 0);
  EXPECT_EQ(c.mode(), Mode::kHold);
  EXPECT_EQ(c.offboard_losses(), 1);
  EXPECT_NE(c.reason().find("offboard lost"), std::string::npos) << c.reason();
  c.update(Time::from_us(t + 3 * kS), 1.0, 0, 0);
  EXPECT_EQ(c.mode(), Mode::kHold);
  c.update(Time::from_us(t + 4 * kS), 1.0, 0, 0);
  EXPECT_EQ(c.mode(), Mode::kLand);
  // Touchdown: low thrust and still for land_detect_s, then disarmed after disarm_after_landing_s.
  int64_t u = t + 5 * kS;
  for (; u < t + 6 * kS + 100000; u += 20000) c.update(Time::from_us(u), 0.3, 0, 0);
  EXPECT_TRUE(c.landed());
  EXPECT_TRUE(c.armed());
  for (; u < t + 8 * kS + 200000; u += 20000) c.update(Time::from_us(u), 0.3, 0, 0);
  EXPECT_FALSE(c.armed());
}

TEST(Commander, AStreamResumedInTimeKeepsOffboard) {
  Commander c{CommanderOptions{}};
  int64_t t = 0;
  for (; t <= kS; t += 100000) c.on_setpoint(Time::from_us(t));
  ASSERT_TRUE(c.command("offboard", Time::from_us(t), true));
  ASSERT_TRUE(c.command("arm", Time::from_us(t), true));
  for (int i = 0; i < 100; ++i, t += 20000) {
    if (i % 20 == 0) c.on_setpoint(Time::from_us(t));  // 2.5 Hz, gaps of 0.4 s
    c.update(Time::from_us(t), 1.2, 0.5, 0);
  }
  EXPECT_EQ(c.mode(), Mode::kOffboard);
  EXPECT_EQ(c.offboard_losses(), 0);
}

// The flight stack's clock is a log's on replay, and a log's times may be anything: before zero (an offset clock)
// or at int64_t's ends (a hostile peer). Before, a setpoint stamped before zero read as no setpoint at all (a
// sentinel of -1), so offboard was refused, and the times' differences overflowed int64_t (UBSan).
TEST(Commander, ClocksBeforeZeroAndAtTheEndsOfInt64) {
  Commander c{CommanderOptions{}};
  int64_t t = -3 * kS;
  for (; t <= -2 * kS; t += 100000) c.on_setpoint(Time::from_us(t));
  EXPECT_TRUE(c.command("offboard", Time::from_us(t), true)) << c.reason();
  EXPECT_NEAR(c.setpoint_age(Time::from_us(t)), 0.1, 1e-9);
  ASSERT_TRUE(c.command("arm", Time::from_us(t), true));
  c.update(Time::from_us(t), 1.2, 0.5, 0);  // took off
  // The next tick at the far end of int64_t: the stream is long gone.
  c.update(Time::from_us(INT64_MAX), 1.0, 0, 0);
  EXPECT_EQ(c.offboard_losses(), 1);
  EXPECT_EQ(c.mode(), Mode::kHold);
  EXPECT_GT(c.setpoint_age(Time::from_us(INT64_MAX)), 9e12);

  Commander d{CommanderOptions{}};
  d.on_setpoint(Time::from_us(INT64_MIN));
  d.on_setpoint(Time::from_us(INT64_MIN + 100000));
  d.on_setpoint(Time::from_us(INT64_MIN + 200000));
  EXPECT_TRUE(d.command("offboard", Time::from_us(INT64_MIN + 300000), true)) << d.reason();
  EXPECT_FALSE(d.command("offboard", Time::from_us(INT64_MAX), true));  // the stream is 2^64 us old
}

}  // namespace
}  // namespace driftlab::flight
