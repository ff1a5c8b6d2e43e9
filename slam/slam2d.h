// 2D lidar SLAM behind the Bus: laser scans in, wheel odometry as the prior when present, a pose per scan out, and
// at the end the whole trajectory as last optimised and the occupancy map as a PNG (on the bus and beside the
// output log, with a map_server-style YAML). Two methods: `graph` (the default), a pose graph over keyframes with
// loop closures found by scan matching against older keyframes (MRPT's ICP and its sparse pose-graph optimiser,
// slam/internal/scan_graph.h), and `icp-slam`, MRPT's ICP map builder (mrpt::slam::CMetricMapBuilderICP, the
// engine of MRPT's icp-slam application) as it is. docs/slam.md says how each works and why the defaults are
// what they are.
// Thread-safety: a module is called from its bus's thread only. MRPT stays inside slam2d.cc.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <memory>
#include <set>
#include <string>

#include "core/result.h"
#include "runtime/bus.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::slam {

struct Slam2dConfig {
  std::string scan_channel = "SCAN";            ///< driftlab.laser_scan_t
  std::string odom_channel = "ODOM";            ///< driftlab.odometry_t prior; "" to ignore
  std::string tf_static_channel = "TF_STATIC";  ///< where base_link -> scan frame is found
  std::string pose_channel = "SLAM_POSE";       ///< driftlab.pose_t out
  std::string map_channel = "SLAM_MAP";         ///< driftlab.image_t (png) at the end
  std::string base_frame = "base_link";
  std::array<double, 3> sensor_pose = {0, 0, 0};  ///< x, y, yaw of the scanner on the base when TF has none
  double max_range = 0;  ///< readings at or beyond it are no returns [m]; 0: range_max and a code found in them
  std::string ini;  ///< an MRPT icp-slam .ini file ([MappingApplication] and [ICP]); the keys below override it
  // Method and pose graph (method graph). Defaults chosen on the Intel and ACES logs and the simulator's sessions
  // (docs/slam.md says why each is what it is).
  std::string method = "graph";                        ///< graph | icp-slam (the default with `ini`)
  std::string trajectory_channel = "SLAM_TRAJECTORY";  ///< every scan's pose as last optimised, at the end
  std::string loops_channel = "SLAM_LOOPS";            ///< driftlab.loop_closure_t: each loop test, decided
  double odom_wait_s = 2;           ///< how long a scan waits for the odometry at its stamp [s of scan stamps]
  double keyframe_distance = 0.5;   ///< travel that makes a new keyframe [m]
  double keyframe_angle = 20;       ///< turn that makes a new keyframe [deg]
  int local_map_keyframes = 10;     ///< keyframes each scan is matched against
  bool loop_closure = true;         ///< match new keyframes against older ones and optimise the graph
  double loop_min_travel = 10;      ///< path between two keyframes before they may close a loop [m]
  double loop_radius = 1.5;         ///< old keyframes within this of the estimate are candidates [m] ...
  double loop_drift = 0.05;         ///< ... plus this fraction of the graph distance between the two
  double loop_max_radius = 16;      ///< [m]
  double loop_min_goodness = 0.65;  ///< share of the current points an old place must explain [0, 1]
  bool loop_rescue_near = false;    ///< a near loop test whose ICP left its reach searches the window instead
  bool loop_seen_only = false;      ///< a near loop test's ICP takes only the points an old scan could see
  /// Weigh the odometry into each scan match (docs/slam.md): "false", "true", or "auto": on when the odometry's
  /// heading agrees with the first 600 matches within its noise model (a graph with it weighed in from the first
  /// scan runs beside the one without until then).
  std::string match_odometry = "auto";
  double match_sigma = 0.15;        ///< a point's noise about its wall, for the match's information [m]
  std::array<double, 4> odometry_noise = {0.05, 0.01, 0.05, 0.005};  ///< m/m, m, rad/rad, rad
  // Map building (icp-slam's [MappingApplication], method icp-slam); defaults are MRPT's icp-slam_demo_classic.ini
  // but fuse_points.
  double insertion_lin_distance = 1.2;    ///< [m]
  double insertion_ang_distance = 45;     ///< [deg]
  double localization_lin_distance = 0.2; ///< [m]
  double localization_ang_distance = 5;   ///< [deg]
  double min_icp_goodness = 0.4;          ///< [0, 1]
  double min_dist_between_points = 0.05;  ///< point-map insertion [m]
  bool fuse_points = true;                ///< fuse new points with the map's (keeps the map, and ICP, fast on long
                                          ///< sessions that revisit places; icp-slam's demo .ini has false)
  // ICP ([ICP]).
  int max_iterations = 80;
  double threshold_dist = 0.3;            ///< [m]
  double threshold_ang = 1;               ///< [deg]
  double alfa = 0.8;
  double smallest_threshold_dist = 0.05;  ///< [m]
  int decimation = 5;                     ///< corresponding_points_decimation
  double map_resolution = 0.05;           ///< of the occupancy image [m]
  std::set<std::string> given;            ///< the keys set in YAML (they override the .ini file's)
};

/// The keys of the `slam.2d` map, with units, ranges and defaults (core/config.h).
const config::Table<Slam2dConfig>& slam2d_config_table();

/// Reads the `slam.2d` map; an undefined node gives the defaults. Errors name the file, line and key.
Result<Slam2dConfig> parse_slam2d_config(const YAML::Node& node, const std::string& origin);

class Slam2d final : public Module {
 public:
  explicit Slam2d(Slam2dConfig config);
  ~Slam2d() override;
  std::string name() const override { return "slam"; }
  Status start(Bus& bus) override;
  void finish(Bus& bus) override;
  ModuleCounters counters() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace driftlab::slam
