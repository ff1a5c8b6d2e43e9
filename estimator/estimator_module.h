// The estimator module: a DelayedEkf fed from the bus (IMU gyro, wheel odometry twist, SLAM poses when present),
// publishing its estimate as driftlab.odometry_t. Measurements are applied at their header stamps, so a skewed
// clock shows as what it does to a real estimator; late and out-of-order ones are re-applied within `window_s`
// or rejected and counted.
// Thread-safety: a module is called from its bus's thread only.
#pragma once

#include <yaml-cpp/yaml.h>

#include <memory>
#include <string>

#include "core/result.h"
#include "estimator/ekf.h"
#include "runtime/bus.h"
#include "runtime/module_input.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::estimator {

struct EstimatorConfig {
  std::string imu_channel = "IMU";         ///< driftlab.imu_t; "" to ignore
  std::string odom_channel = "ODOM";       ///< driftlab.odometry_t (twist used; the first pose initialises)
  std::string pose_channel = "SLAM_POSE";  ///< driftlab.pose_t absolute poses; "" to ignore
  std::string output_channel = "EKF_ODOM"; ///< driftlab.odometry_t
  std::string frame_id = "";               ///< output frame; "": the odometry's frame, or "map" with poses
  std::string child_frame_id = "base_link";
  double window_s = 0.5;      ///< how far back late measurements are re-applied [s]; 0: reject every late one
  double publish_rate = 50;   ///< output rate in stamp time [Hz]
  EkfNoise noise;
};

/// The keys of the `estimator:` map of a replay config, with units, ranges and defaults (core/config.h).
const config::Table<EstimatorConfig>& estimator_config_table();

/// Reads the `estimator:` map of a replay config; errors name the file, line and key.
Result<EstimatorConfig> parse_estimator_config(const YAML::Node& node, const std::string& origin);

class EstimatorModule final : public Module {
 public:
  explicit EstimatorModule(EstimatorConfig config);
  std::string name() const override { return "estimator"; }
  Status start(Bus& bus) override;
  void finish(Bus& bus) override;
  ModuleCounters counters() const override;
  const DelayedEkf& filter() const { return ekf_; }

 private:
  void add(Bus& bus, Time stamp, const Measurement& m);
  void publish(Bus& bus);
  EstimatorConfig c_;
  DelayedEkf ekf_;
  std::string frame_;
  int64_t next_publish_ = 0, seq_ = 0;
  int64_t imu_ = 0, odom_ = 0, poses_ = 0, undecodable_ = 0, before_init_ = 0, refused_init_ = 0;
  NonFiniteInputs non_finite_;
};

Result<std::unique_ptr<Module>> make_estimator(const YAML::Node& config, const std::string& origin);

}  // namespace driftlab::estimator
