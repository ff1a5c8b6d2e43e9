// A planar EKF for a wheeled robot: state (x, y, yaw, v, w, gyro bias) in the odometry or map frame, a constant
// velocity motion model, and updates from the IMU's gyro, wheel odometry's twist and absolute poses (SLAM).
// Measurements are applied at their header stamps; DelayedEkf handles the ones that arrive after later ones
// (timestamp skew, latency, reordering): within a window it rewinds to the state before the late measurement and
// re-applies everything after it in stamp order, and older ones it rejects and counts.
// Thread-safety: plain values; one thread.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <variant>

#include "core/time.h"
#include "estimator/delayed_filter.h"
#include "lcmtypes/planar.h"

namespace driftlab::estimator {

/// Process and measurement noise (standard deviations).
struct EkfNoise {
  double accel = 0.5;           ///< linear acceleration, as process noise on v [m/s^2 / sqrt(s)... per sqrt(s)]
  double angular_accel = 1.0;   ///< angular acceleration, as process noise on w [rad/s^2 per sqrt(s)]
  double gyro_bias_walk = 2e-4; ///< gyro bias random walk [rad/s per sqrt(s)]
  double gyro = 0.003;          ///< gyro white noise per sample [rad/s]
  double odom_v = 0.02;         ///< odometry linear velocity [m/s], when the message has no covariance
  double odom_w = 0.02;         ///< odometry angular velocity [rad/s], when the message has no covariance
  double pose_xy = 0.05;        ///< absolute pose position [m], when the message has no covariance
  double pose_yaw = 0.02;       ///< absolute pose yaw [rad], when the message has no covariance
  double initial_bias = 0.01;   ///< initial gyro bias uncertainty [rad/s]
};

/// A gyro z rate [rad/s], with its variance (<= 0: the configured noise).
struct GyroZ {
  double w = 0, var = 0;
};
/// Body velocities from odometry [m/s, rad/s] with variances (<= 0: configured).
struct Twist {
  double v = 0, w = 0, var_v = 0, var_w = 0;
};
/// An absolute pose with variances [m^2, rad^2] (<= 0: configured).
struct PoseFix {
  Pose2 pose;
  double var_xy = 0, var_yaw = 0;
};
using Measurement = std::variant<GyroZ, Twist, PoseFix>;

class Ekf {
 public:
  using State = Eigen::Matrix<double, 6, 1>;  ///< x, y, yaw, v, w, gyro bias
  using Cov = Eigen::Matrix<double, 6, 6>;
  enum Index { kX = 0, kY, kYaw, kV, kW, kBias };

  explicit Ekf(const EkfNoise& noise = {}) : noise_(noise) {}

  /// Starts at a pose and velocity, at time `at`; false (and not initialised) when a value is NaN,
  /// infinite or beyond any robot's (over 1e9 m, m/s or rad/s).
  bool init(Time at, const PoseFix& fix, double v, double w);
  bool initialized() const { return initialized_; }

  /// Moves the state to `at` (no-op for earlier times).
  void predict(Time at);
  /// Predicts to `at` and applies a measurement. A measurement with a NaN or infinite value, a value beyond any
  /// robot's (over 1e9 m, m/s or rad/s), or one that would leave a NaN or infinite number in the state or
  /// covariance is refused: false, and the filter stays as it was. The state is always finite.
  bool update(Time at, const Measurement& m);

  Time time() const { return t_; }
  const State& state() const { return x_; }
  const Cov& covariance() const { return P_; }

 private:
  void apply(Time at, const Measurement& m);
  template <int N>
  void correct(const Eigen::Matrix<double, N, 1>& innovation, const Eigen::Matrix<double, N, 6>& H,
               const Eigen::Matrix<double, N, N>& R);
  EkfNoise noise_;
  bool initialized_ = false;
  Time t_;
  State x_ = State::Zero();
  Cov P_ = Cov::Identity();
};

/// An Ekf that accepts measurements in any order within a window (delayed_filter.h).
class DelayedEkf : public DelayedFilter<Ekf, Measurement> {
 public:
  DelayedEkf(const EkfNoise& noise, double window_s) : DelayedFilter(Ekf(noise), window_s), noise_(noise) {}

  /// Starts from a first fix; false (and nothing changes) when the filter refuses it (Ekf::init).
  bool init(Time at, const PoseFix& fix, double v, double w) {
    Ekf e(noise_);
    if (!e.init(at, fix, v, w)) return false;
    reset(e);
    return true;
  }
  bool initialized() const { return filter().initialized(); }

 private:
  EkfNoise noise_;
};

}  // namespace driftlab::estimator
