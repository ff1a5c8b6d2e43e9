// The `arm:` section of a scenario (docs/simulator.md): an arm on the robot, driven by a joint trajectory controller
// (controller/joint_trajectory.h) in the simulator's loop, commanded over the log's fault path by a commander
// (controller/arm_commander.h), with a robot state publisher and a localization on TF.
// Thread-safety: plain values.
#pragma once

#include <string>

#include "controller/arm_commander.h"
#include "controller/joint_trajectory.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::sim {

struct ArmConfig {
  bool enabled = false;                                   ///< the scenario has an `arm:` section
  std::string command_channel = "ARM_CMD";                ///< joint_trajectory_t from the commander (faults apply)
  std::string state_channel = "ARM_STATE";                ///< joint_trajectory_state_t of the controller
  std::string result_channel = "ARM_RESULT";              ///< joint_trajectory_result_t of the controller
  std::string description_channel = "ROBOT_DESCRIPTION";  ///< robot_description_t, once at the start
  std::string joints_tf_channel = "TF_JOINTS";            ///< the robot state publisher: every moving joint's transform
  double joints_tf_rate = 50;                             ///< [Hz]
  std::string map_channel = "TF_MAP";                     ///< the localization's map -> odom ("" for none)
  double map_rate = 10;                                   ///< [Hz]
  bool hold_base = false;                                 ///< the base holds still (the route is not driven)
  controller::JointTrajectoryOptions controller;
  controller::ArmCommanderOptions commander;
};

/// The keys of the `arm:` section (core/config.h).
const config::Table<ArmConfig>& arm_table();

}  // namespace driftlab::sim
