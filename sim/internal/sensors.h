// Sensor models of the simulator, each sampled on the physics steps at its own rate. Internal to sim/.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>

#include "core/time.h"
#include "sim/internal/output.h"
#include "sim/robot.h"
#include "sim/scenario.h"

namespace driftlab::sim {

class RayCaster;

/// Distance along a unit ray to the first obstacle or the floor, +infinity when none within max_range [m].
using RangeFn = std::function<double(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range)>;

/// What a sensor sees at one physics step.
struct SensorContext {
  const Robot& robot;
  const RayCaster& caster;  ///< for the camera
  const RangeFn& range;     ///< for the lidars
  Output& out;
  int64_t start_utime;  ///< true time of the first step [us]
  int64_t now_utime;    ///< true time of this step [us]
};

/// The robot's own dead reckoning from its wheel encoders, with quantisation, slip and calibration errors.
/// Pose in the odometry frame, which starts at the robot's start pose.
class WheelOdometry {
 public:
  WheelOdometry(const OdometryParams& p, const Robot& robot, uint64_t seed);
  /// Reads the encoders and integrates since the last update, dt [s] apart.
  void update(const Robot& robot, double dt);
  double x() const { return x_; }
  double y() const { return y_; }
  double yaw() const { return yaw_; }
  double linear() const { return v_; }   ///< [m/s]
  double angular() const { return w_; }  ///< [rad/s]
  double var_xy() const { return var_xy_; }
  double var_yaw() const { return var_yaw_; }

 private:
  int64_t ticks(double angle) const;
  OdometryParams p_;
  double radius_, separation_;
  std::mt19937_64 rng_;
  double true_l_ = 0, true_r_ = 0;  // last true wheel angles [rad]
  double meas_l_ = 0, meas_r_ = 0;  // what the encoder disks turned, slip included [rad]
  int64_t ticks_l_ = 0, ticks_r_ = 0;
  double x_ = 0, y_ = 0, yaw_ = 0, v_ = 0, w_ = 0, var_xy_ = 0, var_yaw_ = 0;
};

class Sensor {
 public:
  virtual ~Sensor() = default;
  /// Called after every physics step; publishes what falls due.
  virtual void step(SensorContext& ctx) = 0;
};

/// Builds the sensor of a config (links already validated). `odometry` is the robot's dead reckoning, which the
/// odometry sensor publishes; `geo` places the world on Earth for the GNSS, barometer and magnetometer.
std::unique_ptr<Sensor> make_sensor(const SensorConfig& config, const Robot& robot, Output& out, uint64_t seed,
                                    WheelOdometry* odometry, const GeoConfig& geo);

/// Independent, reproducible random streams: one per sensor, from the run's seed and a name.
uint64_t stream_seed(uint64_t seed, const std::string& name);

/// Due time of the n-th sample of a `rate` Hz stream since the start [us].
inline int64_t due_us(int64_t n, double rate) { return Duration::periods_rounded(rate, n).us(); }

}  // namespace driftlab::sim
