// The drone's EKF: the planar EKF (ekf.h) extended to 3D, as an error-state filter in the manner of PX4's EKF2.
// Nominal state: position and velocity in the local east-north-up frame ("odom", at a geodetic origin), attitude
// (body x forward, y left, z up, to the local frame), gyro and accelerometer biases, and the barometer's offset
// from the local height; 16 error states. The IMU drives the prediction (each sample's rates hold over the interval
// up to its stamp); GNSS position and velocity, barometric altitude and the magnetometer's heading correct it, each
// after a chi-square innovation test (outliers are counted, not fused). Measurements arriving late are re-applied
// through DelayedFilter (delayed_filter.h) within its window, exactly as the planar EKF's.
// The IMU frame is the body frame (the shipped quadrotor's imu_link sits at the base origin, unrotated).
// Units: SI throughout; times [us]. Thread-safety: plain values; one thread.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <variant>

#include "core/geo.h"
#include "core/time.h"
#include "estimator/delayed_filter.h"

namespace driftlab::estimator {

/// Process and measurement noise (standard deviations), and the innovation gates.
struct DroneEkfNoise {
  double gyro = 0.004;             ///< gyro white noise, as process noise on attitude [rad/s per sqrt(Hz)]
  double accel = 0.05;             ///< accelerometer white noise, as process noise on velocity [m/s^2 per sqrt(Hz)]
  double gyro_bias_walk = 1e-4;    ///< gyro bias random walk [rad/s^2 per sqrt(Hz)]
  double accel_bias_walk = 1e-3;   ///< accelerometer bias random walk [m/s^3 per sqrt(Hz)]
  double baro_offset_walk = 0.01;  ///< barometer offset random walk [m/s per sqrt(Hz)]
  double gnss_position = 0.5;      ///< GNSS horizontal position, when the fix gives no accuracy [m]
  double gnss_height = 0.8;        ///< GNSS height, when the fix gives no accuracy [m]
  double gnss_velocity = 0.2;      ///< GNSS velocity per axis, when the fix gives no accuracy [m/s]
  double baro = 0.2;               ///< barometric altitude, when the reading gives no variance [m]
  double heading = 0.05;           ///< magnetometer heading [rad]
  double gate = 5;  ///< innovation test: measurements further than this many standard deviations are outliers
  /// When a sensor's measurements have all been outliers for this long, the state is reset to them, as PX4's
  /// EKF2 does (GNSS: position and velocity; barometer: its offset) [s].
  double reset_s = 5;
  double initial_tilt = 0.05;       ///< initial roll and pitch uncertainty [rad]
  double initial_heading = 0.2;     ///< initial heading uncertainty [rad]
  double initial_velocity = 0.3;    ///< initial velocity uncertainty per axis [m/s]
  double initial_gyro_bias = 0.01;  ///< [rad/s]
  double initial_accel_bias = 0.1;  ///< [m/s^2]
};

/// An IMU sample in the body frame: rates [rad/s] and specific force [m/s^2].
struct ImuSample {
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
};
/// A GNSS fix in the local frame [m, m/s] with accuracies (standard deviations; <= 0: the configured noise).
struct GnssFix {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  double eph = 0, epv = 0, speed_accuracy = 0;
};
/// Barometric altitude above mean sea level [m] with its standard deviation (<= 0: configured).
struct BaroAltitude {
  double altitude = 0, std = 0;
};
/// A magnetometer reading in the body frame [any unit: only its direction counts].
struct MagField {
  Eigen::Vector3d field = Eigen::Vector3d::Zero();
};
using DroneMeasurement = std::variant<ImuSample, GnssFix, BaroAltitude, MagField>;

/// Which measurements an update fused and which failed the innovation test, by kind (the index of the variant).
struct FusionCounts {
  int64_t fused[4] = {0, 0, 0, 0};
  int64_t outliers[4] = {0, 0, 0, 0};
  int64_t resets[4] = {0, 0, 0, 0};  ///< the state reset to a sensor after reset_s of outliers
};

class DroneEkf {
 public:
  static constexpr int kN = 16;
  using Cov = Eigen::Matrix<double, kN, kN>;
  enum Index { kP = 0, kV = 3, kTheta = 6, kBg = 9, kBa = 12, kBaro = 15 };

  DroneEkf() = default;
  /// `declination`: the angle of magnetic north east of true north [rad]; `origin_altitude`: the local frame's
  /// origin above mean sea level [m].
  DroneEkf(const DroneEkfNoise& noise, double declination, double origin_altitude)
      : noise_(noise), declination_(declination), origin_alt_(origin_altitude) {}

  /// Starts at `at`: tilt from the accelerometer at rest, heading from the magnetometer, position from GNSS,
  /// velocity zero; the barometer's offset is what the barometer reads above the GNSS height.
  void init(Time at, const ImuSample& imu, const MagField& mag, const GnssFix& gnss, const BaroAltitude& baro);
  bool initialized() const { return initialized_; }

  /// Moves the state to `at` with the last IMU sample's rates (no-op for earlier times).
  void predict(Time at);
  /// Predicts to `at` and applies a measurement (an IMU sample: predicts with its rates instead, then holds them).
  /// A measurement with a NaN or infinite value, or one before init, is refused: false, and nothing changes.
  bool update(Time at, const DroneMeasurement& m);

  Time time() const { return t_; }
  const Eigen::Vector3d& position() const { return p_; }
  const Eigen::Vector3d& velocity() const { return v_; }     ///< in the local frame [m/s]
  const Eigen::Quaterniond& attitude() const { return q_; }  ///< body to local
  const Eigen::Vector3d& gyro_bias() const { return bg_; }
  const Eigen::Vector3d& accel_bias() const { return ba_; }
  double baro_offset() const { return baro_; }
  /// The last IMU sample's rates less the gyro bias, in the body frame [rad/s].
  Eigen::Vector3d angular_velocity() const { return last_.gyro - bg_; }
  const Cov& covariance() const { return P_; }
  const FusionCounts& counts() const { return counts_; }
  /// When a GNSS position was last fused (at init: the start).
  Time last_position_fix() const { return last_fix_; }

 private:
  template <int N>
  bool correct(const Eigen::Matrix<double, N, 1>& innovation, const Eigen::Matrix<double, N, kN>& H,
               const Eigen::Matrix<double, N, N>& R, int kind);
  void propagate(const ImuSample& s, double dt);
  DroneEkfNoise noise_;
  double declination_ = 0, origin_alt_ = 0;
  bool initialized_ = false;
  Time t_, last_fix_, last_baro_;
  Eigen::Vector3d p_ = Eigen::Vector3d::Zero(), v_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d bg_ = Eigen::Vector3d::Zero(), ba_ = Eigen::Vector3d::Zero();
  double baro_ = 0;
  ImuSample last_;
  Cov P_ = Cov::Identity();
  FusionCounts counts_;
};

/// The heading of a body attitude: the angle of its x axis from the local x (east) axis, counter-clockwise [rad].
double heading_of(const Eigen::Quaterniond& q);

/// The heading a magnetometer reading gives at attitude q (its roll and pitch used to level the reading), for a
/// field whose north is `declination` east of true north [rad].
double magnetic_heading(const Eigen::Vector3d& field_body, const Eigen::Quaterniond& q, double declination);

/// Roll and pitch from the specific force at rest, and the heading from the magnetometer: the attitude [body to
/// local].
Eigen::Quaterniond align(const Eigen::Vector3d& accel, const Eigen::Vector3d& field_body, double declination);

/// At one stamp, the IMU sample (which carries the state to it) before the corrections.
struct ImuFirst {
  int operator()(const DroneMeasurement& m) const { return std::holds_alternative<ImuSample>(m) ? 0 : 1; }
};
using DelayedDroneEkf = DelayedFilter<DroneEkf, DroneMeasurement, ImuFirst>;

}  // namespace driftlab::estimator
