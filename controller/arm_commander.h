// The arm's commander: the part a MATLAB or Python node plays in a real system. It plays a pick-and-place cycle
// planned in Cartesian space (the tool centre point moved between waypoints by minimum-jerk profiles, the gripper
// pointing down, turned about the vertical), solves it to joint positions by inverse kinematics
// (kinematics/arm_chain.h: damped least squares within the joint limits, each solution seeded by the one before), and
// every period sends a joint trajectory of the next `horizon` points of that plan, a period apart. It closes the loop
// as such nodes do: each command adds `feedback_gain` times the error between the plan and the last measured joint
// positions, so the arm catches up when it lags. With the commands late (a slow transport), that correction comes too
// late and overshoots: the loop oscillates. Thread-safety: one commander per thread.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "driftlab/joint_trajectory_t.hpp"
#include "kinematics/arm_chain.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::controller {

struct ArmWaypoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< of the tool centre point in the arm's base frame [m]
  double yaw = 0;                                      ///< about the vertical, the gripper pointing down [rad]
  double move_s = 2;                                   ///< time to get there from the previous waypoint [s]
  double dwell_s = 0.5;                                ///< time held there [s]
};

struct ArmCommanderOptions {
  double rate = 20;                         ///< commands per second [Hz]
  int horizon = 10;                         ///< points per command, a period apart
  double feedback_gain = 0.6;               ///< share of the measured joint error added to each command
  std::string base_link = "panda_link0";    ///< the frame of the waypoints
  std::string tip_link = "panda_hand_tcp";  ///< what is placed at them
  std::vector<double> home;                 ///< joint positions at the start [rad]; the arm's first pose
  std::vector<ArmWaypoint> waypoints;       ///< the cycle, played again and again from home's pose
};

/// The commander's keys (core/config.h): the scenario's `arm.commander:`.
const config::Table<ArmCommanderOptions>& arm_commander_table();

class ArmCommander {
 public:
  /// `chain` from the options' base link to their tip link. Errors: a waypoint the IK cannot reach (named), home
  /// of the wrong size or outside the limits.
  static Result<ArmCommander> create(kinematics::ArmChain chain, ArmCommanderOptions options);

  /// The command at t [us] (its first call is the plan's start), from the last measured joint positions (in
  /// chain order; none yet: no correction). Times are on the commander's clock.
  driftlab::joint_trajectory_t command(int64_t t, const std::optional<Eigen::VectorXd>& measured);

  /// The planned tool pose at `s` seconds into the plan, in the base link's frame.
  Eigen::Isometry3d plan(double s) const;
  /// The planned joint positions at plan step k (k periods after the start).
  const Eigen::VectorXd& joints_at(int64_t k);
  const kinematics::ArmChain& chain() const { return chain_; }
  const ArmCommanderOptions& options() const { return o_; }
  int64_t ik_failures() const { return ik_failures_; }

 private:
  ArmCommander(kinematics::ArmChain chain, ArmCommanderOptions options);
  kinematics::ArmChain chain_;
  ArmCommanderOptions o_;
  Eigen::Isometry3d start_pose_;
  std::vector<double> leg_start_;  // plan time at which each leg (move then dwell) starts [s]
  double cycle_s_ = 0;
  std::optional<int64_t> start_;
  std::map<int64_t, Eigen::VectorXd> solved_;  // joints by plan step
  int64_t ik_failures_ = 0;
};

/// The tool orientation of a waypoint: pointing down, turned by yaw.
Eigen::Matrix3d gripper_down(double yaw);

}  // namespace driftlab::controller
