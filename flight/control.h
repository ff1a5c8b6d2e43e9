// PX4's multicopter control cascade: position -> velocity (mc_pos_control, at 50 Hz), attitude (mc_att_control)
// and body rate (mc_rate_control, on every new attitude and rate estimate, i.e. at the IMU rate); the mixer
// (vehicle.h) turns the rate controller's torques into motor commands. Every stage limits its output (speeds, tilt,
// thrust, body rates) and stops its integrators when the stage after it saturates (anti-windup), as PX4's do.
// Gains are per unit of the vehicle (accelerations and angular accelerations), so the same gains fly a heavier
// vehicle once its model (VehicleModel) says how heavy it is. Frames: local east-north-up, body x forward, y left,
// z up. Units: SI. Thread-safety: plain values; one thread.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::flight {

struct ControlOptions {
  // Position and velocity (PX4: MPC_XY_P, MPC_Z_P, MPC_XY_VEL_*_ACC, MPC_Z_VEL_*_ACC, MPC_*_VEL_MAX, MPC_TILTMAX_AIR).
  double position_gain_xy = 0.95;  ///< horizontal speed per metre of position error [1/s]
  double position_gain_z = 1.0;    ///< vertical speed per metre of position error [1/s]
  double velocity_p_xy = 1.8;      ///< [m/s^2 per m/s]
  double velocity_i_xy = 0.4;      ///< [m/s^2 per m]
  double velocity_d_xy = 0.2;      ///< [m/s^2 per m/s^2]
  double velocity_p_z = 4.0;       ///< [m/s^2 per m/s]
  double velocity_i_z = 2.0;       ///< [m/s^2 per m]
  double velocity_d_z = 0.0;       ///< [m/s^2 per m/s^2]
  double max_speed_xy = 5.0;       ///< [m/s]
  double max_speed_up = 3.0;       ///< [m/s]
  double max_speed_down = 1.5;     ///< [m/s]
  double max_tilt = 0.785;         ///< [rad]
  double min_thrust = 0.12;        ///< collective thrust floor in flight, of the vehicle's maximum [0..1]
  double max_thrust = 0.9;         ///< collective thrust ceiling, of the vehicle's maximum [0..1]
  // Attitude (MC_ROLL_P, MC_PITCH_P, MC_YAW_P, MC_*RATE_MAX).
  double attitude_gain_rp = 6.5;   ///< roll and pitch rate per radian of error [1/s]
  double attitude_gain_yaw = 2.8;  ///< yaw rate per radian of error [1/s]
  double max_rate_rp = 3.84;       ///< [rad/s] (220 deg/s)
  double max_rate_yaw = 3.49;      ///< [rad/s] (200 deg/s)
  // Body rates (MC_ROLLRATE_*, MC_YAWRATE_*), as angular accelerations.
  double rate_p_rp = 18;           ///< [rad/s^2 per rad/s]
  double rate_i_rp = 12;           ///< [rad/s^2 per rad]
  double rate_d_rp = 0.25;         ///< [rad/s^2 per rad/s^2]
  double rate_p_yaw = 8;           ///< [rad/s^2 per rad/s]
  double rate_i_yaw = 3;           ///< [rad/s^2 per rad]
  double rate_integral_limit = 8;  ///< [rad/s^2]
  double rate_d_cutoff = 30;       ///< low-pass of the rate derivative [Hz]
};

/// The keys of the control options (core/config.h).
const config::Table<ControlOptions>& control_options_table();

/// What the position controller wants: a thrust vector in the local frame as a specific force [m/s^2] (gravity
/// compensated), and where the body should point.
struct ThrustSetpoint {
  Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();  ///< specific force, local frame [m/s^2]
  double yaw = 0;                                          ///< [rad]
};

class PositionControl {
 public:
  /// max_specific_force: the vehicle's full collective thrust over its mass [m/s^2].
  PositionControl(const ControlOptions& o, double max_specific_force)
      : o_(o), max_specific_force_(max_specific_force) {}
  /// One step of dt [s]: the position setpoint with its feed-forward velocity, against the estimate.
  ThrustSetpoint update(const Eigen::Vector3d& position_sp, const Eigen::Vector3d& velocity_ff, double yaw_sp,
                        const Eigen::Vector3d& position, const Eigen::Vector3d& velocity, double dt,
                        const Eigen::Vector3d& acceleration_ff = Eigen::Vector3d::Zero());
  /// Velocity control only (a descent at a set speed): horizontal position still held at position_sp.
  ThrustSetpoint update_velocity_z(const Eigen::Vector3d& position_sp, double vz_sp, double yaw_sp,
                                   const Eigen::Vector3d& position, const Eigen::Vector3d& velocity, double dt);
  void reset();

 private:
  ThrustSetpoint velocity_step(const Eigen::Vector3d& velocity_sp, double yaw_sp, const Eigen::Vector3d& velocity,
                               double dt, const Eigen::Vector3d& acceleration_ff = Eigen::Vector3d::Zero());
  ControlOptions o_;
  double max_specific_force_;
  Eigen::Vector3d integral_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_velocity_ = Eigen::Vector3d::Zero();
  bool have_last_ = false;
};

/// The attitude that points the body's z along a specific force with the given heading, and the collective
/// specific force along the current body z [m/s^2] (PX4's bodyzToAttitude).
Eigen::Quaterniond attitude_for(const Eigen::Vector3d& acceleration, double yaw);

class AttitudeControl {
 public:
  explicit AttitudeControl(const ControlOptions& o) : o_(o) {}
  /// Body rate setpoint [rad/s] to turn `attitude` into `setpoint` (quaternion error, yaw weighted less).
  Eigen::Vector3d update(const Eigen::Quaterniond& q, const Eigen::Quaterniond& q_sp) const;

 private:
  ControlOptions o_;
};

class RateControl {
 public:
  explicit RateControl(const ControlOptions& o) : o_(o) {}
  /// Angular acceleration demand [rad/s^2] for body rate setpoint `rate_sp` and measured `rate` [rad/s], dt [s]
  /// since the last call; `saturated` (the mixer's last verdict, per axis) stops integration in its direction.
  Eigen::Vector3d update(const Eigen::Vector3d& rate_sp, const Eigen::Vector3d& rate, double dt,
                         const int saturated[3]);
  void reset();

 private:
  ControlOptions o_;
  Eigen::Vector3d integral_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_rate_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d derivative_ = Eigen::Vector3d::Zero();
  bool have_last_ = false;
};

}  // namespace driftlab::flight
