// The `drone:` section of a scenario (docs/simulator.md): the robot is a multirotor whose rotors the simulator
// spins with a motor model, and whose flight stack runs on board as the same modules `driftlab replay` hosts
// (estimator/drone_estimator_module.h, flight/flight_module.h, flight/offboard_module.h), closed loop on the
// physics: they receive the sensors' messages as the log does (faults applied) and their messages go through the
// same fault path into the log; the motor commands that arrive drive the rotors.
// Thread-safety: plain values.
#pragma once

#include <string>

#include "estimator/drone_estimator_module.h"
#include "flight/flight_module.h"
#include "flight/offboard_module.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::sim {

/// Each rotor's motor and propeller, as Gazebo's motor model (PX4 SITL's iris by default): thrust k_f w^2 along the
/// rotor axis, drag torque moment_ratio * thrust against the spin, the speed following its setpoint with a
/// first-order lag, faster up than down. A motor command c in [0, 1] sets the speed to max_speed * sqrt(c), so the
/// thrust is c times the maximum, as the flight stack's mixer assumes.
struct MotorModel {
  double thrust_coefficient = 5.84e-6;  ///< k_f [N/(rad/s)^2]
  double moment_ratio = 0.06;           ///< drag torque per thrust [m]
  double max_speed = 1100;              ///< [rad/s]
  double time_constant_up = 0.0125;     ///< [s]
  double time_constant_down = 0.025;    ///< [s]
};

struct DroneConfig {
  DroneConfig();
  bool enabled = false;  ///< the scenario has a `drone:` section
  MotorModel motors;
  double drag = 0.25;         ///< linear drag on the airframe [N per m/s]
  bool rotor_bodies = false;  ///< each rotor a Bullet body on a hinge (as Gazebo builds it) instead of one body
  std::string rotor_channel = "ROTOR_STATES";  ///< driftlab.joint_state_t of the rotor joints (speeds)
  double rotor_rate = 100;                     ///< [Hz]
  std::string tf_channel = "TF";               ///< odom -> base link from the estimate, as a ROS bridge broadcasts it
  std::string rotor_tf_channel = "TF_ROTORS";  ///< base link -> rotor links (a robot state publisher)
  double tf_rate = 50;                         ///< [Hz]
  std::string stats_channel = "MODULE_STATS";  ///< the on-board modules' statistics (driftlab.module_stats_t)
  /// The offboard script's clock: "simulation" (as the flight stack, in lockstep) or "wall" (a ROS node that trusts
  /// the wall clock: when the simulation runs slower than real time, physics_cost, its timers and its mission run
  /// faster than the vehicle can follow, and its stamps are wall time).
  std::string offboard_clock = "simulation";
  estimator::DroneEstimatorConfig estimator;  ///< the on-board estimator
  flight::FlightConfig flight;                ///< the flight stack
  flight::OffboardConfig offboard;            ///< the offboard script
  bool vehicle_given = false;                 ///< flight.vehicle was given (else: from the URDF and the motor model)
  bool declination_given = false;             ///< estimator.declination was given (else: the scenario's geo)
};

/// The keys of the `drone:` section (core/config.h).
const config::Table<DroneConfig>& drone_table();

}  // namespace driftlab::sim
