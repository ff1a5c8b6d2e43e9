// A joint trajectory controller as ros2_control's joint_trajectory_controller does it, for a velocity command
// interface: it takes trajectories of timed points (driftlab.joint_trajectory_t), samples the one it follows at each
// update (cubic Hermite splines between points that carry velocities, linear between points that do not; from the
// desired state it was at when the trajectory arrived up to the first point; the last point held after the end),
// and commands each joint's velocity as the desired velocity (feed-forward) plus a PI on the position error,
// clamped to the joint's velocity limit. Desired positions are kept inside the joint limits.
// A trajectory starts when it arrives, or at its header stamp (`start: stamp`, ros2_control with a non-zero stamp);
// then one that ends before it arrives is rejected as stale, as ros2_control rejects it. Path tolerance (during the
// trajectory) and goal tolerance (within goal_time after its end) end it with a clear result: succeeded, or aborted
// naming the joint and its error; a trajectory replaced by the next one is not reported.
// Used in closed loop by the simulator (sim/internal/arm_loop.h).
// Thread-safety: one controller per thread.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/time.h"
#include "driftlab/joint_trajectory_result_t.hpp"
#include "driftlab/joint_trajectory_t.hpp"
#include "kinematics/robot_model.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::controller {

struct JointTrajectoryOptions {
  std::string start = "arrival";  ///< "arrival" or "stamp": when a trajectory's time starts
  double kp = 30;                 ///< position gain: velocity command per position error [1/s]
  double ki = 300;                ///< integral gain [1/s^2]
  double ff_velocity_scale = 1;   ///< share of the desired velocity fed forward
  double path_tolerance = 0.3;    ///< position error that aborts a trajectory during it [rad]; 0: none
  double goal_tolerance = 0.02;   ///< position error allowed at the end [rad]
  double goal_time = 1.0;         ///< time after the last point to come within goal_tolerance [s]
  double state_rate = 100;        ///< driftlab.joint_trajectory_state_t per second [Hz]
};

/// The controller's keys (core/config.h): the scenario's `arm.controller:`.
const config::Table<JointTrajectoryOptions>& joint_trajectory_table();

struct TrajectoryCounts {
  int64_t received = 0, stale = 0, invalid = 0, succeeded = 0, aborted = 0, preempted = 0;
};

class JointTrajectoryController {
 public:
  /// `joints` and their `limits` (position, velocity; from the URDF), in the order commands are given.
  JointTrajectoryController(std::vector<std::string> joints, std::vector<kinematics::JointLimits> limits,
                            JointTrajectoryOptions options);

  /// A trajectory arrives at `at` (the controller's clock). Returns the result when it is rejected.
  std::optional<driftlab::joint_trajectory_result_t> receive(const driftlab::joint_trajectory_t& msg, Time at);
  /// One control update at `at` with the measured positions [rad]: the velocity command of each joint [rad/s]
  /// in `command`. Returns a result when the trajectory ends in this update.
  std::optional<driftlab::joint_trajectory_result_t> update(Time at, const Eigen::VectorXd& position,
                                                            Eigen::VectorXd& command);

  const std::vector<std::string>& joints() const { return joints_; }
  const Eigen::VectorXd& desired_position() const { return desired_q_; }
  const Eigen::VectorXd& desired_velocity() const { return desired_v_; }
  bool following() const { return active_.has_value(); }
  const TrajectoryCounts& counts() const { return counts_; }
  const JointTrajectoryOptions& options() const { return o_; }

 private:
  struct Point {
    int64_t t;  // [us, controller clock]
    Eigen::VectorXd q, v;
    bool has_v = false;
  };
  struct Active {
    int64_t seq = 0, stamp = 0;
    std::vector<Point> points;  // the state it started from first
  };
  void sample(int64_t now);
  driftlab::joint_trajectory_result_t result(const Active& a, int64_t now, const std::string& status,
                                             const std::string& joint, double error, const std::string& message);

  std::vector<std::string> joints_;
  std::vector<kinematics::JointLimits> limits_;
  JointTrajectoryOptions o_;
  std::optional<Active> active_;
  bool initialised_ = false;
  int64_t last_update_ = 0;
  int64_t result_seq_ = 0;
  Eigen::VectorXd desired_q_, desired_v_, integral_;
  TrajectoryCounts counts_;
};

}  // namespace driftlab::controller
