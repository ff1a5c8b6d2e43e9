// The arm in the simulator's loop (a scenario's `arm:`): the commander publishes its joint trajectories through the
// output's fault path, so a latency fault delays what the controller receives and a drifting clock stamps it in the
// past; the joint trajectory controller takes them at their arrival, reads the joints every physics step and drives
// their motors (velocity command interface, effort-limited); the robot state publisher puts every moving joint's
// transform on TF and the fixed ones on the static TF; a localization publishes map -> odom from the true pose and
// the odometry; the URDF goes out once as the robot description. Internal to sim/.
// Thread-safety: belongs to the simulation's thread.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <vector>

#include "controller/arm_commander.h"
#include "controller/joint_trajectory.h"
#include "driftlab/tf_t.hpp"
#include "kinematics/robot_model.h"
#include "sim/internal/output.h"
#include "sim/internal/sensors.h"
#include "sim/robot.h"
#include "sim/scenario.h"
#include "sim/simulator.h"

namespace driftlab::sim {

class ArmLoop {
 public:
  /// Checks the arm against the URDF and the scenario (the chain, its limits, the commander's plan, a joint_state
  /// sensor for the commander to read) and puts the arm at the commander's home. Errors name the file and element.
  static Result<std::unique_ptr<ArmLoop>> create(const Scenario& scenario, Robot& robot);

  /// The channels the arm publishes (faults may name them).
  std::vector<std::string> channels() const;
  bool holds_base() const { return c_.hold_base; }

  /// Registers the streams on `out` and listens to the command and joint state channels' arrivals. `odometry` is
  /// the robot's dead reckoning (for map -> odom). `corrections` (closed-loop replay) correct the commands'
  /// stamps as they arrive, or re-time them: each starts when it arrived less the delay given, on a controller
  /// that honours stamps.
  void attach(Output& out, const WheelOdometry& odometry, const ReceiveCorrections& corrections = {});
  /// Before the output is flushed at now [us]: the commander, the robot state publisher, the localization.
  void publish(int64_t now);
  /// After the flush: the controller takes what arrived and drives the joints for the next step of dt [s].
  void control(int64_t now, double dt);
  /// The URDF's fixed joints, for the static TF message.
  void add_static(driftlab::tf_t& tf, int64_t now) const;

 private:
  struct Arrival {
    int64_t utime;
    std::vector<uint8_t> bytes;
  };
  ArmLoop(const Scenario& sc, Robot& robot, kinematics::RobotModel model, controller::ArmCommander commander,
          controller::JointTrajectoryController jtc, std::vector<int> index);
  Eigen::VectorXd measured() const;

  ArmConfig c_;
  int64_t start_utime_;
  std::string joint_state_channel_;
  Robot& robot_;
  kinematics::RobotModel model_;
  controller::ArmCommander commander_;
  controller::JointTrajectoryController jtc_;
  std::vector<int> index_;  // the chain's joints in robot.joints()
  Output* out_ = nullptr;
  const WheelOdometry* odometry_ = nullptr;
  int cmd_stream_ = -1, state_stream_ = -1, result_stream_ = -1, description_stream_ = -1, joints_tf_stream_ = -1,
      map_stream_ = -1;
  int64_t n_cmd_ = 0, n_state_ = 0, n_tf_ = 0, n_map_ = 0;
  bool described_ = false;
  std::deque<Arrival> commands_;
  std::optional<ClockCorrection> command_clock_;
  std::optional<int64_t> retime_us_;                 // commands start at arrival less this [us]
  std::optional<Eigen::VectorXd> last_joint_state_;  // what the commander last received, chain order
  Eigen::VectorXd command_;
};

}  // namespace driftlab::sim
