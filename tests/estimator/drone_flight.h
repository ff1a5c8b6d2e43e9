// A known 3D flight for the drone estimator's tests: a climbing circle with a rocking roll, and what an IMU (250 Hz),
// barometer and magnetometer (50 Hz) and GNSS (5 Hz) with white noise, a gyro bias and a barometer offset measure
// of it.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "estimator/drone_ekf.h"

namespace driftlab::estimator::test {

constexpr int64_t kT0 = 1763776800000000;
constexpr double kG = 9.81;
constexpr double kDeclination = 0.05;  // [rad]
constexpr double kOriginAlt = 420;     // [m above sea level]
constexpr double kBaroOffset = 1.5;    // the barometer reads this much above the true height [m]

/// Circle of radius 5 m at 0.2 rad/s, climbing and sinking by 1 m; heading along the path; roll rocking 0.1 rad.
struct Truth {
  double r = 5, w = 0.2;
  Eigen::Vector3d position(double t) const { return {r * std::cos(w * t), r * std::sin(w * t), 2 + std::sin(0.3 * t)}; }
  Eigen::Vector3d velocity(double t) const {
    return {-r * w * std::sin(w * t), r * w * std::cos(w * t), 0.3 * std::cos(0.3 * t)};
  }
  Eigen::Vector3d acceleration(double t) const {
    return {-r * w * w * std::cos(w * t), -r * w * w * std::sin(w * t), -0.09 * std::sin(0.3 * t)};
  }
  Eigen::Quaterniond attitude(double t) const {
    return Eigen::Quaterniond(Eigen::AngleAxisd(w * t + M_PI / 2, Eigen::Vector3d::UnitZ()) *
                              Eigen::AngleAxisd(0.1 * std::sin(0.5 * t), Eigen::Vector3d::UnitX()));
  }
};

inline Eigen::Vector3d field_world() {
  return Eigen::Vector3d(std::sin(kDeclination), std::cos(kDeclination), -1.2) * 2e-5;
}

struct Stamped {
  int64_t utime;
  DroneMeasurement m;
};

inline const Eigen::Vector3d kGyroBias(0.01, -0.02, 0.015);

/// 60 s: IMU at 250 Hz, barometer and magnetometer at 50 Hz, GNSS at 5 Hz, each with white noise.
inline std::vector<Stamped> flight(uint64_t seed) {
  const Truth truth;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0, 1);
  auto noise3 = [&](double s) {
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) v(k) = s * n(rng);
    return v;
  };
  std::vector<Stamped> out;
  for (int i = 1; i <= 15000; ++i) {
    const double t0 = (i - 1) * 0.004, t1 = i * 0.004, tm = 0.5 * (t0 + t1);
    const int64_t utime = kT0 + int64_t{i} * 4000;
    // Each sample describes the interval up to its stamp: the rotation over it and the mean specific force.
    const Eigen::AngleAxisd turn(truth.attitude(t0).inverse() * truth.attitude(t1));
    ImuSample imu;
    imu.gyro = turn.axis() * turn.angle() / 0.004 + kGyroBias + noise3(0.003);
    imu.accel = truth.attitude(tm).inverse() * (truth.acceleration(tm) + Eigen::Vector3d(0, 0, kG)) + noise3(0.05);
    out.push_back({utime, imu});
    if (i % 5 == 0) {
      out.push_back({utime, BaroAltitude{kOriginAlt + truth.position(t1).z() + kBaroOffset + 0.1 * n(rng), 0.1}});
      out.push_back({utime, MagField{truth.attitude(t1).inverse() * field_world() + noise3(2e-7)}});
    }
    if (i % 50 == 0) {
      GnssFix g;
      g.position = truth.position(t1) + noise3(0.3);
      g.position.z() += 0.4 * n(rng);  // vertical: 0.5 m in all
      g.velocity = truth.velocity(t1) + noise3(0.1);
      g.eph = 0.3;
      g.epv = 0.5;
      g.speed_accuracy = 0.1;
      out.push_back({utime, g});
    }
  }
  return out;
}

}  // namespace driftlab::estimator::test
