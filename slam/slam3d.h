// 3D point-cloud odometry with PCL registration (ICP, NDT or GICP) behind the Bus: each cloud, corrected for the
// motion during its sweep and downsampled, is registered against a local map of recent keyframes, starting from
// the wheel odometry's motion when there is some; a pose per cloud goes out, and at the end the keyframes make a
// map written as a PCD file (`<artifact prefix>-map.pcd`). Nothing large is published on the bus.
// Thread-safety: a module is called from its bus's thread only. PCL stays inside slam3d.cc.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <memory>
#include <string>

#include "core/result.h"
#include "runtime/bus.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::slam {

struct Slam3dConfig {
  std::string cloud_channel = "POINTS";         ///< driftlab.point_cloud_t
  std::string odom_channel = "ODOM";            ///< driftlab.odometry_t initial guess; "" to ignore
  std::string tf_static_channel = "TF_STATIC";  ///< where base_link -> cloud frame is found
  std::string pose_channel = "SLAM_POSE";       ///< driftlab.pose_t out
  std::string base_frame = "base_link";
  std::array<double, 4> sensor_pose = {0, 0, 0, 0};  ///< x, y, z, yaw of the sensor when TF has none
  std::string method = "ndt";            ///< icp, ndt or gicp
  bool deskew = true;                    ///< undo the motion during a sweep (per-point time_offsets)
  double min_range = 0.5;                ///< returns nearer are the robot itself [m]
  double max_range = 40;                 ///< [m]
  double voxel = 0.4;                    ///< leaf of the downsampled scan [m]
  double max_correspondence = 1.0;       ///< icp, gicp: largest point pair distance; all: for max_fitness [m]
  double ndt_resolution = 1.0;           ///< ndt: cell size [m]
  double ndt_step = 0.1;                 ///< ndt: More-Thuente line search step [m]
  int max_iterations = 30;
  double max_fitness = 0.25;  ///< mean squared distance to the map (pairs within max_correspondence) above which
                              ///< a registration is rejected [m^2]
  double keyframe_distance = 1.0;        ///< a cloud becomes a keyframe after this much motion [m]
  double keyframe_angle = 15;            ///< ... or this much rotation [deg]
  int local_map_keyframes = 10;          ///< keyframes in the registration target
  double map_voxel = 0.1;                ///< leaf of the final map [m] (kept at this resolution while running)
};

/// The keys of the `slam.3d` map, with units, ranges and defaults (core/config.h).
const config::Table<Slam3dConfig>& slam3d_config_table();

/// Reads the `slam.3d` map; an undefined node gives the defaults. Errors name the file, line and key.
Result<Slam3dConfig> parse_slam3d_config(const YAML::Node& node, const std::string& origin);

/// 3D point-cloud odometry. Counters: dropped = clouds that could not be decoded, had too few returns, or whose
/// registration did not converge or was rejected by max_fitness (their pose is the prior); warnings when no clouds
/// or no odometry were seen, or when the sensor pose came from the config instead of TF_STATIC.
class Slam3d final : public Module {
 public:
  explicit Slam3d(Slam3dConfig config);
  ~Slam3d() override;
  std::string name() const override { return "slam"; }
  Status start(Bus& bus) override;
  void finish(Bus& bus) override;
  ModuleCounters counters() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A Slam3d from its `slam.3d` settings (see parse_slam3d_config); errors are one line naming origin:line and key.
Result<std::unique_ptr<Module>> make_slam3d(const YAML::Node& config, const std::string& origin);

}  // namespace driftlab::slam
