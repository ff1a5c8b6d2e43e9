// The drone's estimator behind the Bus: a DelayedDroneEkf (drone_ekf.h) fed by the IMU, GNSS, barometer and
// magnetometer, publishing its estimate as driftlab.odometry_t on every IMU sample it applies (the flight stack's
// rate loop runs on it) and its statistics as driftlab.estimator_status_t. Like PX4's EKF2 it judges every
// measurement's stamp against its own clock (the bus's): older than `max_age_s` is stale, more than `max_future_s`
// ahead is from the future, both rejected and counted per input; within those, stamps before the oldest state the
// filter keeps (`window_s`) are late, rejected and counted too. An IMU stamped on another time base therefore shows
// as its rejection fraction in the status. The local frame's origin is the first GNSS fix (as PX4's).
// Thread-safety: a module is called from its bus's thread only.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <memory>
#include <optional>
#include <string>

#include "core/geo.h"
#include "core/result.h"
#include "estimator/drone_ekf.h"
#include "runtime/bus.h"
#include "runtime/module_input.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::estimator {

struct DroneEstimatorConfig {
  std::string imu_channel = "IMU";                         ///< driftlab.imu_t
  std::string gnss_channel = "GNSS";                       ///< driftlab.gnss_t
  std::string baro_channel = "BARO";                       ///< driftlab.barometer_t
  std::string mag_channel = "MAG";                         ///< driftlab.magnetometer_t
  std::string output_channel = "VEHICLE_ODOM_REPLAY";      ///< driftlab.odometry_t out
  std::string status_channel = "ESTIMATOR_STATUS_REPLAY";  ///< driftlab.estimator_status_t out
  double window_s = 0.3;                                   ///< late measurements re-applied this far back [s]
  double max_age_s = 0.5;                                  ///< older than this against the bus's clock: stale [s]
  double max_future_s = 0.1;  ///< further ahead of the bus's clock than this: from the future [s]
  double status_rate = 1;     ///< [Hz]
  /// The filter starts from the IMU and magnetometer averaged over this long with the vehicle still (every
  /// accelerometer reading within 2 m/s^2 of gravity), as PX4's EKF2 aligns its tilt [s].
  double align_s = 0.5;
  double declination = 0;     ///< magnetic north east of true north [rad]
  DroneEkfNoise noise;
};
const config::Table<DroneEstimatorConfig>& drone_estimator_config_table();
Result<std::unique_ptr<Module>> make_drone_estimator(const YAML::Node& config, const std::string& origin);

/// What happened to one input's measurements [count].
struct InputCounts {
  int64_t received = 0, stale = 0, future = 0, late = 0, before_init = 0;
};

class DroneEstimatorModule final : public Module {
 public:
  enum Input { kImu = 0, kGnss = 1, kBaro = 2, kMag = 3 };  ///< as DroneMeasurement's alternatives
  explicit DroneEstimatorModule(DroneEstimatorConfig config);
  std::string name() const override { return "drone_estimator"; }
  Status start(Bus& bus) override;
  void finish(Bus& bus) override;
  ModuleCounters counters() const override;

  const DelayedDroneEkf& filter() const { return ekf_; }
  const InputCounts& input(Input i) const { return inputs_[i]; }

 private:
  void add(Bus& bus, Input kind, Time stamp, const DroneMeasurement& m);
  void try_init(Time stamp);
  void publish_estimate(Bus& bus);
  void publish_status(Bus& bus);

  DroneEstimatorConfig c_;
  DelayedDroneEkf ekf_;
  std::optional<geo::LocalFrame> frame_;
  // Before the start: the IMU and magnetometer averaged while the vehicle is still.
  struct Alignment {
    Time first, last;  ///< stamps of the IMU samples averaged
    Eigen::Vector3d accel = Eigen::Vector3d::Zero(), gyro = Eigen::Vector3d::Zero(), field = Eigen::Vector3d::Zero();
    int64_t imu = 0, mag = 0;
  } align_;
  std::optional<GnssFix> last_fix_;
  std::optional<BaroAltitude> last_baro_;
  std::array<InputCounts, 4> inputs_;
  int64_t odom_seq_ = 0, status_seq_ = 0, undecodable_ = 0, no_fix_ = 0;
  NonFiniteInputs non_finite_;
};

}  // namespace driftlab::estimator
