// The wheeled robot in the simulator's loop (a scenario without `drone:`), beside the arm's and the drone's loops:
// the robot's dead reckoning, which the route follower steers by (advanced here when no odometry sensor publishes
// it); the pure-pursuit controller along the route with the reactive safety layer, fed by a bumper-height ring of
// range rays; the wheel rates it sets; and the velocity commands it publishes on the controller's channel (none
// while an arm holds the base still). Internal to sim/.
// Thread-safety: belongs to the simulation's thread.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "controller/pure_pursuit.h"
#include "sim/internal/output.h"
#include "sim/internal/sensors.h"
#include "sim/raycaster.h"
#include "sim/robot.h"
#include "sim/scenario.h"

namespace driftlab::sim {

class GroundLoop {
 public:
  /// `odometry` is the robot's dead reckoning; `odometry_sensor`: a sensor advances it (else this loop does, at
  /// odom_rate [Hz]). Registers the command stream on `out`.
  GroundLoop(const Scenario& sc, Robot& robot, const RayCaster& caster, Output& out, WheelOdometry& odometry,
             bool odometry_sensor, double odom_rate);

  /// Before the sensors at t_us [us since the start]: the dead reckoning, when due and no sensor advances it.
  void advance_odometry(int64_t t_us);
  /// After the static TF at now [us]: the controller's command when due, the wheels driven for dt [s]; `hold`: an
  /// arm holds the base (a zero command).
  void control(int64_t t_us, int64_t now, double dt, bool hold);

  /// Laps of the route completed, by the controller's estimate.
  size_t laps() const { return pursuit_.laps(); }
  /// The dead reckoning's position in the world frame (it starts at the robot's start pose) [m].
  Eigen::Vector2d odometry_position() const;

 private:
  const Scenario& sc_;
  Robot& robot_;
  const RayCaster& caster_;
  Output& out_;
  WheelOdometry& odometry_;
  bool odometry_sensor_;
  double odom_rate_;
  controller::PurePursuit pursuit_;
  controller::AvoidOptions avoid_;
  std::vector<controller::Point2> proximity_;
  int stream_;
  int64_t n_cmd_ = 0, n_odom_ = 0;
};

}  // namespace driftlab::sim
