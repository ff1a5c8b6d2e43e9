// PurePursuit::update and avoid_obstacles on an ideal unicycle: loops, open routes, limits, obstacles, recovery.
#include "controller/pure_pursuit.h"

#include <yaml-cpp/yaml.h>

#include "controller/controller_module.h"

#include <gtest/gtest.h>

#include <cmath>

namespace driftlab::controller {
namespace {

/// Integrates a unicycle for dt [s].
void move(Pose2& p, const Command& c, double dt) {
  p.yaw += c.angular * dt;
  p.x += c.linear * std::cos(p.yaw) * dt;
  p.y += c.linear * std::sin(p.yaw) * dt;
}

const std::vector<Point2> kSquare = {{0, 0}, {6, 0}, {6, 6}, {0, 6}};

TEST(PurePursuit, FollowsALoopLapAfterLap) {
  PurePursuit pp(kSquare, {});
  Pose2 p{0, 0, 0};
  double worst = 0;
  for (int i = 0; i < 20 * 150; ++i) {  // 150 s at 20 Hz
    const Command c = pp.update(p, 0.05);
    EXPECT_LE(c.linear, 0.6 + 1e-9);
    EXPECT_LE(std::abs(c.angular), 1.2 + 1e-9);
    move(p, c, 0.05);
    if (i > 40) worst = std::max(worst, pp.cross_track());
  }
  EXPECT_GE(pp.laps(), 3u);  // 24 m per lap at up to 0.6 m/s, slower in corners
  EXPECT_LT(worst, 0.5);     // corners are cut by about the lookahead
  EXPECT_FALSE(pp.finished());
  EXPECT_EQ(pp.skips(), 0u);
}

TEST(PurePursuit, OpenRouteEndsAtItsLastPoint) {
  PurePursuitOptions o;
  o.loop = false;
  PurePursuit pp({{0, 0}, {5, 0}, {5, 3}}, o);
  Pose2 p{0, 0, 0};
  for (int i = 0; i < 20 * 60 && !pp.finished(); ++i) move(p, pp.update(p, 0.05), 0.05);
  EXPECT_TRUE(pp.finished());
  EXPECT_NEAR(p.x, 5, o.goal_tolerance);
  EXPECT_NEAR(p.y, 3, o.goal_tolerance);
  const Command stop = pp.update(p, 0.05);
  EXPECT_EQ(stop.linear, 0);
  EXPECT_EQ(stop.angular, 0);
}

TEST(PurePursuit, AccelerationLimitsAndTurningOnTheSpot) {
  PurePursuit pp(kSquare, {});
  // Facing away from the route: turn on the spot first, the yaw rate ramping up.
  Pose2 p{0, 0, M_PI};
  Command c = pp.update(p, 0.05);
  EXPECT_EQ(c.linear, 0);
  EXPECT_NEAR(std::abs(c.angular), 3.0 * 0.05, 1e-9);  // max_angular_accel * dt
  // Forward speed ramps at max_accel.
  PurePursuit straight({{0, 0}, {100, 0}}, {.loop = false});
  Pose2 q{0, 0, 0};
  c = straight.update(q, 0.1);
  EXPECT_NEAR(c.linear, 0.1, 1e-9);
  c = straight.update(q, 0.1);
  EXPECT_NEAR(c.linear, 0.2, 1e-9);
}

TEST(PurePursuit, RejectsRoutesWithoutLength) {
  EXPECT_THROW(PurePursuit({{1, 1}}, {}), std::invalid_argument);
  EXPECT_THROW(PurePursuit({{1, 1}, {1, 1}}, {}), std::invalid_argument);
}

TEST(PurePursuit, SkipsAheadWhenStuck) {
  PurePursuit pp(kSquare, {});
  Pose2 p{0, 0, 0};
  for (int i = 0; i < 20 * 9; ++i) pp.update(p, 0.05);  // the robot never moves: 9 s
  EXPECT_EQ(pp.skips(), 1u);
}

TEST(AvoidObstacles, SlowsForObstaclesAheadAndSteersAway) {
  const Command go{0.5, 0};
  EXPECT_EQ(avoid_obstacles(go, {}, {}).linear, 0.5);
  // Far obstacles change nothing.
  const Command far = avoid_obstacles(go, {{2, 0}, {0, 2}}, {});
  EXPECT_EQ(far.linear, 0.5);
  EXPECT_EQ(far.angular, 0);
  // A wall close on the left: steer right, keep going.
  const Command left = avoid_obstacles(go, {{0.1, 0.3}, {0.3, 0.3}}, {});
  EXPECT_EQ(left.linear, 0.5);
  EXPECT_LT(left.angular, 0);
  // Something 0.3 m ahead of the footprint: slow down.
  const Command ahead = avoid_obstacles(go, {{0.5, 0.0}}, {});
  EXPECT_GT(ahead.linear, 0);
  EXPECT_LT(ahead.linear, 0.5);
  // Touching ahead: stop and turn on the spot, away from the side it leans to.
  const Command blocked = avoid_obstacles(go, {{0.22, 0.05}}, {});
  EXPECT_EQ(blocked.linear, 0);
  EXPECT_LT(blocked.angular, 0);
}


TEST(CompareCommands, FindsTheDelayBetweenTwoCommandSeries) {
  // Logged commands are the recomputed ones 60 ms later (a slow transport, say), sampled at 20 Hz.
  std::vector<CommandSample> recomputed, logged;
  const int64_t t0 = 1763776800000000;
  for (int i = 0; i < 400; ++i) {
    const int64_t t = t0 + i * 10000;
    const double w = std::sin(i * 0.02);
    if (i % 5 == 0) recomputed.push_back({t, 0.4, w});
    logged.push_back({t + 60000, 0.4, w});
  }
  const auto c = compare_commands(recomputed, logged, 0.5);
  ASSERT_TRUE(c);
  EXPECT_NEAR(c->delay_s, 0.06, 1e-9);
  EXPECT_LT(c->angular_rmse_at_delay, 1e-12);
  EXPECT_GT(c->angular_rmse, 0.01);  // at zero lag the series differ
  EXPECT_NEAR(c->linear_rmse, 0, 1e-12);
  EXPECT_EQ(c->matched, 78);  // recomputed commands from the first logged one on (60 ms in): 2 of 80 miss
}

TEST(CompareCommands, SeriesThatNeverOverlapAreNotCompared) {
  // Every recomputed command comes before the first logged one, by more than the search reaches: no lag compares
  // anything. modules_fuzz found the old answer, an RMSE at the best delay of inf, published on CMD_COMPARISON.
  const int64_t t0 = 1763776800000000;
  const std::vector<CommandSample> recomputed = {{t0, 0.4, 0.1}, {t0 + 50000, 0.4, 0.2}};
  const std::vector<CommandSample> logged = {{t0 + 1500000, 0.4, 0.1}};
  EXPECT_FALSE(compare_commands(recomputed, logged, 0.5));
  EXPECT_FALSE(compare_commands(recomputed, {}, 0.5));
  // Searched over 2 s they are compared: from 1.5 s on both recomputed commands meet the logged one held.
  const auto late = compare_commands(recomputed, logged, 2);
  ASSERT_TRUE(late);
  EXPECT_NEAR(late->delay_s, 1.5, 1e-9);
  EXPECT_TRUE(std::isfinite(late->angular_rmse_at_delay));
}

TEST(ControllerConfig, NamesTheFileLineAndKey) {
  const YAML::Node node = YAML::Load("route: [[0, 0], [1, 0]]\nlookahed: 0.5\n");
  auto c = parse_controller_config(node, "c.yaml");
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().message.rfind("c.yaml:2: unknown key 'controller.lookahed'", 0), 0u) << c.error().message;
  auto none = parse_controller_config(YAML::Load("speed: 0.3\n"), "c.yaml");
  ASSERT_FALSE(none);
  EXPECT_NE(none.error().message.find("no route"), std::string::npos);
}

}  // namespace
}  // namespace driftlab::controller
