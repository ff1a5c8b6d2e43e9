#include "estimator/drone_ekf.h"

#include <Eigen/Dense>
#include <cmath>
#include <type_traits>
#include <variant>

#include "core/time.h"
#include "lcmtypes/planar.h"

namespace driftlab::estimator {
namespace {

constexpr double kGravity = 9.81;  // [m/s^2], as the simulator's world

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Eigen::Quaterniond exp_map(const Eigen::Vector3d& theta) {
  const double a = theta.norm();
  if (a < 1e-12) return Eigen::Quaterniond(1, 0.5 * theta.x(), 0.5 * theta.y(), 0.5 * theta.z()).normalized();
  return Eigen::Quaterniond(Eigen::AngleAxisd(a, theta / a));
}

}  // namespace

double heading_of(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d R = q.toRotationMatrix();
  return std::atan2(R(1, 0), R(0, 0));
}

double magnetic_heading(const Eigen::Vector3d& field_body, const Eigen::Quaterniond& q, double declination) {
  // Level the reading: the attitude without its heading (roll and pitch) takes it to a frame that only differs
  // from the local one by the heading. Magnetic north lies `declination` east of true north (+y).
  const Eigen::Matrix3d level = Eigen::AngleAxisd(-heading_of(q), Eigen::Vector3d::UnitZ()) * q.toRotationMatrix();
  const Eigen::Vector3d m = level * field_body;
  return wrap_angle(M_PI / 2 - declination - std::atan2(m.y(), m.x()));
}

Eigen::Quaterniond align(const Eigen::Vector3d& accel, const Eigen::Vector3d& field_body, double declination) {
  const double roll = std::atan2(accel.y(), accel.z());
  const double pitch = std::atan2(-accel.x(), std::hypot(accel.y(), accel.z()));
  const Eigen::Quaterniond tilt(Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()));
  const double heading = magnetic_heading(field_body, tilt, declination);
  return (Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()) * tilt).normalized();
}

void DroneEkf::init(Time at, const ImuSample& imu, const MagField& mag, const GnssFix& gnss, const BaroAltitude& baro) {
  initialized_ = true;
  t_ = at;
  last_fix_ = last_baro_ = at;
  last_ = imu;
  q_ = align(imu.accel, mag.field, declination_);
  p_ = gnss.position;
  v_.setZero();
  bg_.setZero();
  ba_.setZero();
  baro_ = baro.altitude - origin_alt_ - p_.z();
  const double eph = gnss.eph > 0 ? gnss.eph : noise_.gnss_position;
  const double epv = gnss.epv > 0 ? gnss.epv : noise_.gnss_height;
  const double baro_std = baro.std > 0 ? baro.std : noise_.baro;
  P_.setZero();
  P_.diagonal().segment<3>(kP) << eph * eph, eph * eph, epv * epv;
  P_.diagonal().segment<3>(kV).setConstant(noise_.initial_velocity * noise_.initial_velocity);
  P_.diagonal().segment<3>(kTheta) << noise_.initial_tilt * noise_.initial_tilt,
      noise_.initial_tilt * noise_.initial_tilt, noise_.initial_heading * noise_.initial_heading;
  P_.diagonal().segment<3>(kBg).setConstant(noise_.initial_gyro_bias * noise_.initial_gyro_bias);
  P_.diagonal().segment<3>(kBa).setConstant(noise_.initial_accel_bias * noise_.initial_accel_bias);
  P_(kBaro, kBaro) = epv * epv + baro_std * baro_std;
}

void DroneEkf::propagate(const ImuSample& s, double dt) {
  const Eigen::Vector3d w = s.gyro - bg_, a = s.accel - ba_;
  const Eigen::Matrix3d R = q_.toRotationMatrix();
  const Eigen::Vector3d acc = R * a - Eigen::Vector3d(0, 0, kGravity);
  p_ += v_ * dt + 0.5 * acc * dt * dt;
  v_ += acc * dt;
  const Eigen::Quaterniond dq = exp_map(w * dt);
  q_ = (q_ * dq).normalized();

  // Error-state transition (attitude error in the body frame), first order in dt.
  Cov F = Cov::Identity();
  F.block<3, 3>(kP, kV) = Eigen::Matrix3d::Identity() * dt;
  F.block<3, 3>(kV, kTheta) = -R * skew(a) * dt;
  F.block<3, 3>(kV, kBa) = -R * dt;
  F.block<3, 3>(kTheta, kTheta) = dq.toRotationMatrix().transpose();
  F.block<3, 3>(kTheta, kBg) = -Eigen::Matrix3d::Identity() * dt;
  P_ = F * P_ * F.transpose();
  P_.diagonal().segment<3>(kV).array() += noise_.accel * noise_.accel * dt;
  P_.diagonal().segment<3>(kTheta).array() += noise_.gyro * noise_.gyro * dt;
  P_.diagonal().segment<3>(kBg).array() += noise_.gyro_bias_walk * noise_.gyro_bias_walk * dt;
  P_.diagonal().segment<3>(kBa).array() += noise_.accel_bias_walk * noise_.accel_bias_walk * dt;
  P_(kBaro, kBaro) += noise_.baro_offset_walk * noise_.baro_offset_walk * dt;
  P_ = 0.5 * (P_ + P_.transpose()).eval();
}

void DroneEkf::predict(Time at) {
  if (!initialized_ || at <= t_) return;
  propagate(last_, at.seconds_since(t_));
  t_ = at;
}

template <int N>
bool DroneEkf::correct(const Eigen::Matrix<double, N, 1>& innovation, const Eigen::Matrix<double, N, kN>& H,
                       const Eigen::Matrix<double, N, N>& R, int kind) {
  const Eigen::Matrix<double, N, N> S = H * P_ * H.transpose() + R;
  // The innovation test, per axis, as PX4's: a measurement further than `gate` standard deviations is an outlier.
  for (int i = 0; i < N; ++i) {
    if (!(innovation(i) * innovation(i) <= noise_.gate * noise_.gate * S(i, i))) {
      ++counts_.outliers[kind];
      return false;
    }
  }
  const Eigen::Matrix<double, kN, N> K = P_ * H.transpose() * S.inverse();
  const Eigen::Matrix<double, kN, 1> dx = K * innovation;
  p_ += dx.template segment<3>(kP);
  v_ += dx.template segment<3>(kV);
  q_ = (q_ * exp_map(dx.template segment<3>(kTheta))).normalized();
  bg_ += dx.template segment<3>(kBg);
  ba_ += dx.template segment<3>(kBa);
  baro_ += dx(kBaro);
  // Joseph form: stays symmetric and positive with large gains; tiny correlations flushed to zero (subnormals
  // make the arithmetic tens of times slower, as in the planar EKF).
  const Cov I_KH = Cov::Identity() - K * H;
  P_ = I_KH * P_ * I_KH.transpose() + K * R * K.transpose();
  P_ = (P_.array().abs() < 1e-150).select(0.0, P_);
  ++counts_.fused[kind];
  return true;
}

bool DroneEkf::update(Time at, const DroneMeasurement& m) {
  const bool finite = std::visit(
      [](const auto& x) {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, ImuSample>) return x.gyro.allFinite() && x.accel.allFinite();
        if constexpr (std::is_same_v<T, GnssFix>) {
          return x.position.allFinite() && x.velocity.allFinite() && std::isfinite(x.eph) && std::isfinite(x.epv) &&
                 std::isfinite(x.speed_accuracy);
        }
        if constexpr (std::is_same_v<T, BaroAltitude>) return std::isfinite(x.altitude) && std::isfinite(x.std);
        if constexpr (std::is_same_v<T, MagField>) return x.field.allFinite();
      },
      m);
  if (!initialized_ || !finite) return false;
  if (const auto* imu = std::get_if<ImuSample>(&m)) {
    if (at > t_) {
      propagate(*imu, at.seconds_since(t_));
      t_ = at;
    }
    last_ = *imu;
    ++counts_.fused[0];
    return true;
  }
  predict(at);
  if (const auto* g = std::get_if<GnssFix>(&m)) {
    const double eph = g->eph > 0 ? g->eph : noise_.gnss_position;
    const double epv = g->epv > 0 ? g->epv : noise_.gnss_height;
    const double sv = g->speed_accuracy > 0 ? g->speed_accuracy : noise_.gnss_velocity;
    Eigen::Matrix<double, 6, 1> y;
    y << g->position - p_, g->velocity - v_;
    Eigen::Matrix<double, 6, kN> H = Eigen::Matrix<double, 6, kN>::Zero();
    H.block<3, 3>(0, kP).setIdentity();
    H.block<3, 3>(3, kV).setIdentity();
    Eigen::Matrix<double, 6, 6> R = Eigen::Matrix<double, 6, 6>::Zero();
    R.diagonal() << eph * eph, eph * eph, epv * epv, sv * sv, sv * sv, sv * sv;
    if (correct<6>(y, H, R, 1)) {
      last_fix_ = at;
    } else if (at.seconds_since(last_fix_) > noise_.reset_s) {
      // Every fix an outlier for reset_s: the estimate has left the GNSS behind; start from the fix again.
      p_ = g->position;
      v_ = g->velocity;
      P_.block<6, kN>(kP, 0).setZero();
      P_.block<kN, 6>(0, kP).setZero();
      P_.diagonal().segment<6>(kP) << eph * eph, eph * eph, epv * epv, sv * sv, sv * sv, sv * sv;
      last_fix_ = at;
      ++counts_.resets[1];
    }
  } else if (const auto* b = std::get_if<BaroAltitude>(&m)) {
    const double s = b->std > 0 ? b->std : noise_.baro;
    Eigen::Matrix<double, 1, kN> H = Eigen::Matrix<double, 1, kN>::Zero();
    H(0, kP + 2) = 1;
    H(0, kBaro) = 1;
    const Eigen::Matrix<double, 1, 1> y(b->altitude - (origin_alt_ + p_.z() + baro_));
    if (correct<1>(y, H, Eigen::Matrix<double, 1, 1>(s * s), 2)) {
      last_baro_ = at;
    } else if (at.seconds_since(last_baro_) > noise_.reset_s) {
      baro_ = b->altitude - origin_alt_ - p_.z();  // the barometer's offset from the height, as at the start
      P_.row(kBaro).setZero();
      P_.col(kBaro).setZero();
      P_(kBaro, kBaro) = s * s + P_(kP + 2, kP + 2);
      last_baro_ = at;
      ++counts_.resets[2];
    }
  } else if (const auto* mag = std::get_if<MagField>(&m)) {
    if (mag->field.norm() <= 0) return true;
    Eigen::Matrix<double, 1, kN> H = Eigen::Matrix<double, 1, kN>::Zero();
    // A small body-frame attitude error d turns the body by R d in the local frame; its z part turns the heading.
    H.block<1, 3>(0, kTheta) = q_.toRotationMatrix().row(2);
    const Eigen::Matrix<double, 1, 1> y(wrap_angle(magnetic_heading(mag->field, q_, declination_) - heading_of(q_)));
    correct<1>(y, H, Eigen::Matrix<double, 1, 1>(noise_.heading * noise_.heading), 3);
  }
  return true;
}

}  // namespace driftlab::estimator
