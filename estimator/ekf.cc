#include "estimator/ekf.h"

#include <Eigen/Dense>

#include <cmath>

#include "lcmtypes/validate.h"

namespace driftlab::estimator {

namespace {

/// Whether a measurement can be applied: its values plausible (within kMaxMagnitude: so bounded, the state cannot
/// overflow, the motion model's terms staying below 1e22 with the longest step int64_t stamps allow, 9.2e12 s),
/// its variances finite (yaw wraps: any finite one).
bool usable(const Measurement& m) {
  if (const auto* g = std::get_if<GyroZ>(&m)) return plausible(g->w) && std::isfinite(g->var);
  if (const auto* t = std::get_if<Twist>(&m)) {
    return plausible(t->v) && plausible(t->w) && std::isfinite(t->var_v) && std::isfinite(t->var_w);
  }
  const auto& p = std::get<PoseFix>(m);
  return plausible(p.pose.x) && plausible(p.pose.y) && std::isfinite(p.pose.yaw) && std::isfinite(p.var_xy) &&
         std::isfinite(p.var_yaw);
}

}  // namespace

bool Ekf::init(Time at, const PoseFix& fix, double v, double w) {
  if (!usable(Measurement(fix)) || !plausible(v) || !plausible(w)) return false;
  initialized_ = true;
  t_ = at;
  x_ << fix.pose.x, fix.pose.y, wrap_angle(fix.pose.yaw), v, w, 0;
  P_.setZero();
  P_(kX, kX) = P_(kY, kY) = fix.var_xy > 0 ? fix.var_xy : noise_.pose_xy * noise_.pose_xy;
  P_(kYaw, kYaw) = fix.var_yaw > 0 ? fix.var_yaw : noise_.pose_yaw * noise_.pose_yaw;
  P_(kV, kV) = P_(kW, kW) = 0.01;
  P_(kBias, kBias) = noise_.initial_bias * noise_.initial_bias;
  return true;
}

void Ekf::predict(Time at) {
  if (at <= t_) return;
  // In doubles: hostile stamps far apart would overflow int64_t (exact for stamps below 2^53 us, 285 years).
  const double dt = at.seconds_since(t_);
  t_ = at;
  const double v = x_(kV), w = x_(kW);
  const double heading = x_(kYaw) + 0.5 * w * dt;  // midpoint heading
  const double c = std::cos(heading), s = std::sin(heading);
  x_(kX) += v * c * dt;
  x_(kY) += v * s * dt;
  x_(kYaw) = wrap_angle(x_(kYaw) + w * dt);
  Cov F = Cov::Identity();
  F(kX, kYaw) = -v * s * dt;
  F(kX, kV) = c * dt;
  F(kX, kW) = -v * s * 0.5 * dt * dt;
  F(kY, kYaw) = v * c * dt;
  F(kY, kV) = s * dt;
  F(kY, kW) = v * c * 0.5 * dt * dt;
  F(kYaw, kW) = dt;
  P_ = F * P_ * F.transpose();
  P_(kV, kV) += noise_.accel * noise_.accel * dt;
  P_(kW, kW) += noise_.angular_accel * noise_.angular_accel * dt;
  P_(kBias, kBias) += noise_.gyro_bias_walk * noise_.gyro_bias_walk * dt;
}

template <int N>
void Ekf::correct(const Eigen::Matrix<double, N, 1>& innovation, const Eigen::Matrix<double, N, 6>& H,
                  const Eigen::Matrix<double, N, N>& R) {
  const Eigen::Matrix<double, N, N> S = H * P_ * H.transpose() + R;
  const Eigen::Matrix<double, 6, N> K = P_ * H.transpose() * S.inverse();
  x_ += K * innovation;
  x_(kYaw) = wrap_angle(x_(kYaw));
  // Joseph form: stays symmetric and positive with large gains.
  const Cov I_KH = Cov::Identity() - K * H;
  P_ = I_KH * P_ * I_KH.transpose() + K * R * K.transpose();
  // Correlations between states no measurement couples decay geometrically, into subnormal numbers after some
  // million updates, where arithmetic is tens of times slower: flush them to zero.
  P_ = (P_.array().abs() < 1e-150).select(0.0, P_);
}

bool Ekf::update(Time at, const Measurement& m) {
  if (!usable(m)) return false;
  // Whatever slips past the bounds (an innovation that overflows, a variance of 1e308): the state before is kept
  // and restored unless every number stays finite, so no NaN ever enters the filter.
  const Time t = t_;
  const State x = x_;
  const Cov P = P_;
  apply(at, m);
  if (x_.allFinite() && P_.allFinite()) return true;
  t_ = t;
  x_ = x;
  P_ = P;
  return false;
}

void Ekf::apply(Time at, const Measurement& m) {
  predict(at);
  if (const auto* g = std::get_if<GyroZ>(&m)) {
    Eigen::Matrix<double, 1, 6> H = Eigen::Matrix<double, 1, 6>::Zero();
    H(0, kW) = 1;
    H(0, kBias) = 1;
    Eigen::Matrix<double, 1, 1> z(g->w - x_(kW) - x_(kBias));
    Eigen::Matrix<double, 1, 1> R(g->var > 0 ? g->var : noise_.gyro * noise_.gyro);
    correct<1>(z, H, R);
  } else if (const auto* t = std::get_if<Twist>(&m)) {
    Eigen::Matrix<double, 2, 6> H = Eigen::Matrix<double, 2, 6>::Zero();
    H(0, kV) = 1;
    H(1, kW) = 1;
    const Eigen::Vector2d z(t->v - x_(kV), t->w - x_(kW));
    Eigen::Matrix2d R = Eigen::Matrix2d::Zero();
    R(0, 0) = t->var_v > 0 ? t->var_v : noise_.odom_v * noise_.odom_v;
    R(1, 1) = t->var_w > 0 ? t->var_w : noise_.odom_w * noise_.odom_w;
    correct<2>(z, H, R);
  } else if (const auto* p = std::get_if<PoseFix>(&m)) {
    Eigen::Matrix<double, 3, 6> H = Eigen::Matrix<double, 3, 6>::Zero();
    H(0, kX) = H(1, kY) = H(2, kYaw) = 1;
    const Eigen::Vector3d z(p->pose.x - x_(kX), p->pose.y - x_(kY), wrap_angle(p->pose.yaw - x_(kYaw)));
    Eigen::Matrix3d R = Eigen::Matrix3d::Zero();
    R(0, 0) = R(1, 1) = p->var_xy > 0 ? p->var_xy : noise_.pose_xy * noise_.pose_xy;
    R(2, 2) = p->var_yaw > 0 ? p->var_yaw : noise_.pose_yaw * noise_.pose_yaw;
    correct<3>(z, H, R);
  }
}

}  // namespace driftlab::estimator
