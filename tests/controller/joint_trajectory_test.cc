// JointTrajectoryController (controller/joint_trajectory.h) on a plant that moves each joint exactly at its
// commanded velocity: interpolation, feed-forward tracking, stale and invalid trajectories, path and goal tolerance.
#include "controller/joint_trajectory.h"

#include <gtest/gtest.h>

#include <cmath>

namespace driftlab::controller {
namespace {

constexpr int64_t kDtUs = 1000;  // a 1 kHz update

std::vector<kinematics::JointLimits> limits() {
  kinematics::JointLimits l;
  l.has_position = true;
  l.lower = -2;
  l.upper = 2;
  l.velocity = 2;
  l.effort = 10;
  return {l, l};
}

driftlab::joint_trajectory_t trajectory(int64_t stamp,
                                        const std::vector<std::pair<int64_t, std::vector<double>>>& points,
                                        bool velocities) {
  driftlab::joint_trajectory_t m{};
  m.header.utime = stamp;
  m.njoints = 2;
  m.joint_names = {"a", "b"};
  for (auto& [t, q] : points) {
    driftlab::joint_trajectory_point_t p{};
    p.time_from_start_us = t;
    p.npositions = 2;
    p.positions = q;
    if (velocities) {
      p.nvelocities = 2;
      p.velocities = {0, 0};
    }
    m.points.push_back(p);
  }
  m.npoints = static_cast<int32_t>(m.points.size());
  return m;
}

/// Runs the controller on an ideal velocity plant from `now` for `us`; returns the results it gave.
std::vector<driftlab::joint_trajectory_result_t> run(JointTrajectoryController& c, Eigen::VectorXd& q, int64_t& now,
                                                     int64_t us, double max_error_seen[2] = nullptr) {
  std::vector<driftlab::joint_trajectory_result_t> out;
  Eigen::VectorXd cmd(2);
  for (int64_t end = now + us; now < end; now += kDtUs) {
    if (auto r = c.update(Time::from_us(now), q, cmd)) out.push_back(*r);
    if (max_error_seen != nullptr && c.following()) {
      for (int j = 0; j < 2; ++j) {
        max_error_seen[j] = std::max(max_error_seen[j], std::abs(c.desired_position()[j] - q[j]));
      }
    }
    q += cmd * (static_cast<double>(kDtUs) * 1e-6);
  }
  return out;
}

TEST(JointTrajectory, FollowsASplineAndSucceedsAtTheGoal) {
  JointTrajectoryController c({"a", "b"}, limits(), {});
  Eigen::VectorXd q = Eigen::VectorXd::Zero(2);
  int64_t now = 1'000'000;
  run(c, q, now, 10'000);
  // Joint names in another order than the controller's: b is the first column.
  auto m = trajectory(0, {{500'000, {0.2, 0.5}}, {1'000'000, {0.4, 1.0}}}, true);
  m.joint_names = {"b", "a"};
  ASSERT_FALSE(c.receive(m, Time::from_us(now)).has_value());
  double worst[2] = {0, 0};
  const auto results = run(c, q, now, 1'500'000, worst);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].status, "succeeded");
  EXPECT_NEAR(q[0], 1.0, 0.02);  // a is the second column
  EXPECT_NEAR(q[1], 0.4, 0.02);
  // With feed-forward on an ideal plant the error stays far inside the path tolerance: the 1 kHz update lags
  // the desired motion by one step (at most 2 rad/s * 1 ms).
  EXPECT_LT(worst[0], 0.01);
  EXPECT_LT(worst[1], 0.01);
  EXPECT_FALSE(c.following());
  EXPECT_EQ(c.counts().succeeded, 1);
}

TEST(JointTrajectory, LinearBetweenPointsWithoutVelocitiesAndClampsToLimits) {
  JointTrajectoryController c({"a", "b"}, limits(), {});
  Eigen::VectorXd q = Eigen::VectorXd::Zero(2);
  int64_t now = 0;
  run(c, q, now, 1000);
  // b's target is past its upper limit (2 rad): the controller stops at the limit.
  ASSERT_FALSE(c.receive(trajectory(0, {{1'000'000, {1.0, 3.0}}}, false), Time::from_us(now)).has_value());
  run(c, q, now, 500'000);
  EXPECT_NEAR(c.desired_position()[0], 0.5, 0.01);  // half way, linearly
  EXPECT_NEAR(c.desired_velocity()[0], 1.0, 1e-9);
  run(c, q, now, 1'000'000);
  EXPECT_NEAR(c.desired_position()[1], 2.0, 1e-12);
  EXPECT_LE(q[1], 2.0 + 0.01);
}

TEST(JointTrajectory, RejectsStaleAndInvalidTrajectories) {
  JointTrajectoryOptions o;
  o.start = "stamp";
  JointTrajectoryController c({"a", "b"}, limits(), o);
  // Stamped 0.8 s before it arrives and lasting 0.5 s: it ended 0.3 s before it arrived.
  auto r = c.receive(trajectory(1'000'000, {{500'000, {0.1, 0.1}}}, false), Time::from_us(1'800'000));
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->status, "stale");
  EXPECT_NEAR(r->error, 0.3, 1e-9);
  auto bad = trajectory(1'800'000, {{500'000, {0.1, 0.1}}}, false);
  bad.joint_names[1] = "c";
  r = c.receive(bad, Time::from_us(1'800'000));
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->status, "invalid");
  EXPECT_NE(r->message.find("'c'"), std::string::npos);
  r = c.receive(trajectory(1'800'000, {{500'000, {0.1, 0.1}}, {400'000, {0.2, 0.2}}}, false), Time::from_us(1'800'000));
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->status, "invalid");
  EXPECT_EQ(c.counts().stale, 1);
  EXPECT_EQ(c.counts().invalid, 2);
  // The same trajectory on arrival time is followed.
  JointTrajectoryController on_arrival({"a", "b"}, limits(), {});
  EXPECT_FALSE(
      on_arrival.receive(trajectory(1'000'000, {{500'000, {0.1, 0.1}}}, false), Time::from_us(1'800'000)).has_value());
}

// Stamps are a peer's clock (start: stamp), and a clock gone wrong reaches the ends of int64_t: a point past the
// end is refused rather than wrapped into the past, and a trajectory from the far past is stale by the right amount
// (int64_t subtraction overflowed here: UBSan aborted, and a release build reported it late by a negative time).
TEST(JointTrajectory, StampsAtTheEndsOfTheClock) {
  JointTrajectoryOptions o;
  o.start = "stamp";
  JointTrajectoryController c({"a", "b"}, limits(), o);
  const int64_t now = 1'000'000'000;  // 1000 s
  auto r = c.receive(trajectory(INT64_MAX - 10, {{500'000, {0.1, 0.1}}}, false), Time::from_us(now));
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->status, "invalid");
  EXPECT_EQ(r->message, "a point's time is past the clock's end");
  r = c.receive(trajectory(INT64_MIN, {{0, {0.1, 0.1}}, {500'000, {0.2, 0.2}}}, false), Time::from_us(now));
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->status, "stale");
  // 2^63 us before zero, plus the 1000 s of now, minus the 0.5 s the trajectory lasts; within 0.01 s, since a double
  // holds a stamp near 2^63 us only to 2048 us.
  EXPECT_NEAR(r->error, 9223372036854.775808 + 1000 - 0.5, 0.01);
  EXPECT_EQ(c.counts().invalid, 1);
  EXPECT_EQ(c.counts().stale, 1);
}

TEST(JointTrajectory, AbortsNamingTheJointOffItsPath) {
  JointTrajectoryOptions o;
  o.path_tolerance = 0.1;
  JointTrajectoryController c({"a", "b"}, limits(), o);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(2), cmd(2);
  int64_t now = 0;
  c.update(Time::from_us(now), q, cmd);
  ASSERT_FALSE(c.receive(trajectory(0, {{1'000'000, {0.0, 1.0}}}, false), Time::from_us(now)).has_value());
  // Joint b is blocked: it never moves.
  std::optional<driftlab::joint_trajectory_result_t> r;
  for (now = kDtUs; now < 1'000'000 && !r; now += kDtUs) r = c.update(Time::from_us(now), q, cmd);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->status, "path_tolerance_violated");
  EXPECT_EQ(r->joint, "b");
  EXPECT_GT(r->error, 0.1);
  EXPECT_LT(r->error, 0.11);
  EXPECT_NE(r->message.find("joint b"), std::string::npos);
  EXPECT_FALSE(c.following());
}

TEST(JointTrajectory, GoalToleranceAfterTheGoalTime) {
  JointTrajectoryOptions o;
  o.path_tolerance = 0;
  o.goal_time = 0.2;
  JointTrajectoryController c({"a", "b"}, limits(), o);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(2), cmd(2);
  int64_t now = 0;
  c.update(Time::from_us(now), q, cmd);
  ASSERT_FALSE(c.receive(trajectory(0, {{100'000, {0.5, 0.0}}}, false), Time::from_us(now)).has_value());
  std::optional<driftlab::joint_trajectory_result_t> r;
  for (now = kDtUs; now < 1'000'000 && !r; now += kDtUs) r = c.update(Time::from_us(now), q, cmd);  // a never moves
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->status, "goal_tolerance_violated");
  EXPECT_EQ(r->joint, "a");
  EXPECT_NEAR(r->error, 0.5, 1e-9);
  EXPECT_GT(now, 300'000);  // only after the end (0.1 s) plus the goal time (0.2 s)
}

TEST(JointTrajectory, VelocityCommandsRespectTheLimit) {
  JointTrajectoryController c({"a", "b"}, limits(), {});
  Eigen::VectorXd q = Eigen::VectorXd::Zero(2), cmd(2);
  c.update(Time::from_us(0), q, cmd);
  // A jump far beyond what the joint can do in 0.1 s.
  ASSERT_FALSE(c.receive(trajectory(0, {{100'000, {1.9, -1.9}}}, false), Time::from_us(0)).has_value());
  for (int64_t now = kDtUs; now < 500'000; now += kDtUs) {
    c.update(Time::from_us(now), q, cmd);
    EXPECT_LE(cmd.cwiseAbs().maxCoeff(), 2.0 + 1e-12);
    q += cmd * 1e-3;
  }
}

}  // namespace
}  // namespace driftlab::controller
