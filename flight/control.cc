#include "flight/control.h"

#include <algorithm>
#include <cmath>

#include "core/config.h"

namespace driftlab::flight {
namespace {

constexpr double kGravity = 9.81;  // [m/s^2]

double limit(double v, double lo, double hi) { return std::clamp(v, lo, hi); }

}  // namespace

const config::Table<ControlOptions>& control_options_table() {
  using C = ControlOptions;
  using config::above;
  using config::between;
  const auto gain = between(0, 1e4);
  static const auto t =
      config::Table<C>()
          .number("position_gain_xy", &C::position_gain_xy, gain, "1/s",
                  "horizontal speed per metre of error (MPC_XY_P)")
          .number("position_gain_z", &C::position_gain_z, gain, "1/s", "vertical speed per metre of error (MPC_Z_P)")
          .number("velocity_p_xy", &C::velocity_p_xy, gain, "1/s", "horizontal velocity P (MPC_XY_VEL_P_ACC)")
          .number("velocity_i_xy", &C::velocity_i_xy, gain, "1/s^2", "horizontal velocity I (MPC_XY_VEL_I_ACC)")
          .number("velocity_d_xy", &C::velocity_d_xy, gain, "", "horizontal velocity D (MPC_XY_VEL_D_ACC)")
          .number("velocity_p_z", &C::velocity_p_z, gain, "1/s", "vertical velocity P (MPC_Z_VEL_P_ACC)")
          .number("velocity_i_z", &C::velocity_i_z, gain, "1/s^2", "vertical velocity I (MPC_Z_VEL_I_ACC)")
          .number("velocity_d_z", &C::velocity_d_z, gain, "", "vertical velocity D (MPC_Z_VEL_D_ACC)")
          .number("max_speed_xy", &C::max_speed_xy, above(0, 100), "m/s", "horizontal speed limit (MPC_XY_VEL_MAX)")
          .number("max_speed_up", &C::max_speed_up, above(0, 100), "m/s", "climb rate limit (MPC_Z_VEL_MAX_UP)")
          .number("max_speed_down", &C::max_speed_down, above(0, 100), "m/s", "descent rate limit (MPC_Z_VEL_MAX_DN)")
          .number("max_tilt", &C::max_tilt, above(0, 1.5), "rad", "tilt limit (MPC_TILTMAX_AIR)")
          .number("min_thrust", &C::min_thrust, between(0, 1), "", "collective thrust floor in flight, of the maximum")
          .number("max_thrust", &C::max_thrust, above(0, 1), "", "collective thrust ceiling, of the maximum")
          .number("attitude_gain_rp", &C::attitude_gain_rp, gain, "1/s", "roll and pitch rate per radian (MC_ROLL_P)")
          .number("attitude_gain_yaw", &C::attitude_gain_yaw, gain, "1/s", "yaw rate per radian (MC_YAW_P)")
          .number("max_rate_rp", &C::max_rate_rp, above(0, 100), "rad/s", "roll and pitch rate limit")
          .number("max_rate_yaw", &C::max_rate_yaw, above(0, 100), "rad/s", "yaw rate limit")
          .number("rate_p_rp", &C::rate_p_rp, gain, "1/s", "roll and pitch rate P, as angular acceleration")
          .number("rate_i_rp", &C::rate_i_rp, gain, "1/s^2", "roll and pitch rate I")
          .number("rate_d_rp", &C::rate_d_rp, gain, "", "roll and pitch rate D (on the measured rate)")
          .number("rate_p_yaw", &C::rate_p_yaw, gain, "1/s", "yaw rate P")
          .number("rate_i_yaw", &C::rate_i_yaw, gain, "1/s^2", "yaw rate I")
          .number("rate_integral_limit", &C::rate_integral_limit, above(0, 1e4), "rad/s^2",
                  "the rate integrators' limit")
          .number("rate_d_cutoff", &C::rate_d_cutoff, above(0, 1e4), "Hz", "low-pass of the rate derivative")
          .check([](const config::Value& v, C& c) -> Status {
            if (c.min_thrust >= c.max_thrust) return v["max_thrust"].error("must exceed min_thrust");
            return {};
          });
  return t;
}

void PositionControl::reset() {
  integral_.setZero();
  have_last_ = false;
}

ThrustSetpoint PositionControl::velocity_step(const Eigen::Vector3d& velocity_sp, double yaw_sp,
                                              const Eigen::Vector3d& velocity, double dt,
                                              const Eigen::Vector3d& acceleration_ff) {
  const Eigen::Vector3d e = velocity_sp - velocity;
  Eigen::Vector3d dv = Eigen::Vector3d::Zero();
  if (have_last_ && dt > 0) dv = (velocity - last_velocity_) / dt;
  last_velocity_ = velocity;
  have_last_ = true;
  const Eigen::Vector3d p(o_.velocity_p_xy, o_.velocity_p_xy, o_.velocity_p_z);
  const Eigen::Vector3d i(o_.velocity_i_xy, o_.velocity_i_xy, o_.velocity_i_z);
  const Eigen::Vector3d d(o_.velocity_d_xy, o_.velocity_d_xy, o_.velocity_d_z);
  // As PX4's: the trajectory's acceleration fed forward, the PID on the velocity error taking up the rest.
  Eigen::Vector3d f =
      acceleration_ff + p.cwiseProduct(e) + integral_ - d.cwiseProduct(dv) + Eigen::Vector3d(0, 0, kGravity);

  // Thrust limits, vertical first (PX4's priority), then the tilt.
  const double lo = o_.min_thrust * max_specific_force_, hi = o_.max_thrust * max_specific_force_;
  const double fz = limit(f.z(), lo, hi);
  const bool z_high = f.z() > hi, z_low = f.z() < lo;
  f.z() = fz;
  const double xy_max = std::min(fz * std::tan(o_.max_tilt), std::sqrt(std::max(0.0, hi * hi - fz * fz)));
  const double xy = f.head<2>().norm();
  const bool xy_limited = xy > xy_max;
  if (xy_limited) f.head<2>() *= xy_max / xy;

  // Anti-windup: no integration towards a limit the output already sits at.
  if (!xy_limited) integral_.head<2>() += i.head<2>().cwiseProduct(e.head<2>()) * dt;
  if (!((z_high && e.z() > 0) || (z_low && e.z() < 0))) integral_.z() += i.z() * e.z() * dt;
  integral_.head<2>() = integral_.head<2>().cwiseMax(-3.0).cwiseMin(3.0);
  integral_.z() = limit(integral_.z(), -kGravity, kGravity);
  return {f, yaw_sp};
}

ThrustSetpoint PositionControl::update(const Eigen::Vector3d& position_sp, const Eigen::Vector3d& velocity_ff,
                                       double yaw_sp, const Eigen::Vector3d& position, const Eigen::Vector3d& velocity,
                                       double dt, const Eigen::Vector3d& acceleration_ff) {
  const Eigen::Vector3d e = position_sp - position;
  Eigen::Vector3d v =
      Eigen::Vector3d(o_.position_gain_xy * e.x(), o_.position_gain_xy * e.y(), o_.position_gain_z * e.z()) +
      velocity_ff;
  const double h = v.head<2>().norm();
  if (h > o_.max_speed_xy) v.head<2>() *= o_.max_speed_xy / h;
  v.z() = limit(v.z(), -o_.max_speed_down, o_.max_speed_up);
  return velocity_step(v, yaw_sp, velocity, dt, acceleration_ff);
}

ThrustSetpoint PositionControl::update_velocity_z(const Eigen::Vector3d& position_sp, double vz_sp, double yaw_sp,
                                                  const Eigen::Vector3d& position, const Eigen::Vector3d& velocity,
                                                  double dt) {
  Eigen::Vector3d v(o_.position_gain_xy * (position_sp.x() - position.x()),
                    o_.position_gain_xy * (position_sp.y() - position.y()), vz_sp);
  const double h = v.head<2>().norm();
  if (h > o_.max_speed_xy) v.head<2>() *= o_.max_speed_xy / h;
  v.z() = limit(v.z(), -o_.max_speed_down, o_.max_speed_up);
  return velocity_step(v, yaw_sp, velocity, dt);
}

Eigen::Quaterniond attitude_for(const Eigen::Vector3d& acceleration, double yaw) {
  // PX4's bodyzToAttitude: the body x axis stays in the vertical plane of the heading, so the attitude's heading
  // (heading_of, the ground projection of x) is `yaw` whatever the tilt.
  const Eigen::Vector3d z =
      acceleration.norm() > 1e-6 ? Eigen::Vector3d(acceleration.normalized()) : Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d y_c(-std::sin(yaw), std::cos(yaw), 0);
  Eigen::Vector3d x = y_c.cross(z);
  if (x.norm() < 1e-6) x = Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0).cross(z).cross(z) * -1;  // z along y_c
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R << x, y, z;
  return Eigen::Quaterniond(R).normalized();
}

Eigen::Vector3d AttitudeControl::update(const Eigen::Quaterniond& q, const Eigen::Quaterniond& q_sp) const {
  // PX4's: first the reduced attitude (tilt only, the shortest turn of the body z onto the setpoint's), then the
  // heading, weighted by the ratio of the yaw and tilt gains so that a large heading error does not spoil the tilt.
  const Eigen::Vector3d ez = q.toRotationMatrix().col(2), ez_sp = q_sp.toRotationMatrix().col(2);
  Eigen::Quaterniond reduced = Eigen::Quaterniond::FromTwoVectors(ez, ez_sp) * q;
  if (ez.dot(ez_sp) < -0.9999) reduced = q_sp;  // upside down: no unique shortest turn
  Eigen::Quaterniond mix = reduced.inverse() * q_sp;
  if (mix.w() < 0) mix.coeffs() = -mix.coeffs();
  const double w = o_.attitude_gain_rp > 0 ? std::clamp(o_.attitude_gain_yaw / o_.attitude_gain_rp, 0.0, 1.0) : 1.0;
  const double half = w * std::asin(std::clamp(mix.z(), -1.0, 1.0));
  const Eigen::Quaterniond target = reduced * Eigen::Quaterniond(std::cos(half), 0, 0, std::sin(half));
  Eigen::Quaterniond e = q.inverse() * target;
  if (e.w() < 0) e.coeffs() = -e.coeffs();
  const Eigen::Vector3d eq = 2 * e.vec();
  Eigen::Vector3d rate(o_.attitude_gain_rp * eq.x(), o_.attitude_gain_rp * eq.y(), o_.attitude_gain_yaw * eq.z());
  rate.x() = limit(rate.x(), -o_.max_rate_rp, o_.max_rate_rp);
  rate.y() = limit(rate.y(), -o_.max_rate_rp, o_.max_rate_rp);
  rate.z() = limit(rate.z(), -o_.max_rate_yaw, o_.max_rate_yaw);
  return rate;
}

void RateControl::reset() {
  integral_.setZero();
  derivative_.setZero();
  have_last_ = false;
}

Eigen::Vector3d RateControl::update(const Eigen::Vector3d& rate_sp, const Eigen::Vector3d& rate, double dt,
                                    const int saturated[3]) {
  const Eigen::Vector3d e = rate_sp - rate;
  if (have_last_ && dt > 0) {
    const Eigen::Vector3d raw = (rate - last_rate_) / dt;
    const double a = dt / (dt + 1 / (2 * M_PI * o_.rate_d_cutoff));
    derivative_ += a * (raw - derivative_);
  }
  last_rate_ = rate;
  have_last_ = true;
  const Eigen::Vector3d p(o_.rate_p_rp, o_.rate_p_rp, o_.rate_p_yaw);
  const Eigen::Vector3d i(o_.rate_i_rp, o_.rate_i_rp, o_.rate_i_yaw);
  const Eigen::Vector3d d(o_.rate_d_rp, o_.rate_d_rp, 0);
  Eigen::Vector3d out = p.cwiseProduct(e) + integral_ - d.cwiseProduct(derivative_);
  for (int k = 0; k < 3; ++k) {
    if (saturated[k] * e(k) > 0) continue;  // the mixer already gives all it can that way
    integral_(k) = limit(integral_(k) + i(k) * e(k) * dt, -o_.rate_integral_limit, o_.rate_integral_limit);
  }
  return out;
}

}  // namespace driftlab::flight
