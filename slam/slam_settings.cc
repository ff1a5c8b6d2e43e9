// The SLAM modules' config tables, apart from their code: what reads their settings (the registry, a sweep's
// check, --help-config) links no MRPT and no PCL.
#include <fstream>

#include "core/config.h"
#include "slam/slam_module.h"

namespace driftlab::slam {

const config::Table<Slam2dConfig>& slam2d_config_table() {
  using C = Slam2dConfig;
  using config::above;
  using config::between;
  static const auto t =
      config::Table<C>()
          .text("scan_channel", &C::scan_channel, "driftlab.laser_scan_t in", config::Text::kNonEmpty)
          .text("odom_channel", &C::odom_channel,
                "driftlab.odometry_t or any pose stream (driftlab.pose_t): the prior; \"\" for none")
          .text("tf_static_channel", &C::tf_static_channel, "where base_link -> scan frame is read")
          .text("pose_channel", &C::pose_channel, "driftlab.pose_t out, one per scan")
          .text("map_channel", &C::map_channel, "driftlab.image_t (PNG) of the occupancy map out, at the end")
          .text("base_frame", &C::base_frame, "the robot's base frame")
          .numbers("sensor_pose", &C::sensor_pose, between(-1e3, 1e3), "m, m, rad",
                   "x, y, yaw of the scanner on the base, when TF has none")
          .number("max_range", &C::max_range, between(0, 1e6), "m",
                  "readings at or beyond it are no returns; 0: those at the scan's range_max and at a no-return "
                  "code found in the readings (a pile at their very top)")
          .text("ini", &C::ini,
                "an MRPT icp-slam .ini file (relative to the config file), for method icp-slam: its "
                "[MappingApplication] and [ICP] replace the defaults; the keys given here override it")
          // Method and pose graph (method graph); docs/slam.md says why each default is what it is.
          .choice("method", &C::method, {"graph", "icp-slam"},
                  "graph: keyframes, loop closures and a pose graph; icp-slam: MRPT's ICP map builder as icp-slam "
                  "runs it (the default when `ini` is given)")
          .text("trajectory_channel", &C::trajectory_channel,
                "graph: driftlab.pose_t out at the end, every scan's pose as last optimised; \"\" for none")
          .text("loops_channel", &C::loops_channel,
                "graph: driftlab.loop_closure_t out, each loop test as it is decided and why; \"\" for none")
          .number("odom_wait_s", &C::odom_wait_s, between(0, 60), "s",
                  "graph: how long (in scan stamps) a scan waits for the odometry at its stamp")
          .number("keyframe_distance", &C::keyframe_distance, above(0, 1e3), "m",
                  "graph: travel after which a scan becomes a keyframe (a graph node)")
          .number("keyframe_angle", &C::keyframe_angle, above(0, 360), "deg", "graph: ... or turn")
          .integer("local_map_keyframes", &C::local_map_keyframes, between(1, 1000), "",
                   "graph: the last keyframes each scan is matched against")
          .flag("loop_closure", &C::loop_closure, "graph: match new keyframes against old places, optimise the graph")
          .number("loop_min_travel", &C::loop_min_travel, above(0, 1e6), "m",
                  "graph: path between two keyframes before they may close a loop")
          .number("loop_radius", &C::loop_radius, above(0, 1e3), "m",
                  "graph: an old keyframe within this of the estimate is a candidate ...")
          .number("loop_drift", &C::loop_drift, between(0, 1), "",
                  "graph: ... plus this share of the graph distance between the two")
          .number("loop_max_radius", &C::loop_max_radius, above(0, 1e3), "m", "graph: ... at most")
          .number("loop_min_goodness", &C::loop_min_goodness, between(0, 1), "",
                  "graph: share of the current points a loop match must put near old ones")
          .flag("loop_rescue_near", &C::loop_rescue_near,
                "graph: a near loop test whose ICP was pulled beyond its reach searches the same window as a far "
                "test does (turned up to 30 deg) instead of failing; docs/slam.md says what it does to robustness")
          .flag("loop_seen_only", &C::loop_seen_only,
                "graph: a near loop test's ICP takes only the current points one of the old place's scans could "
                "have seen (a corridor passed the other way); docs/slam.md says what it does to robustness")
          .choice("match_odometry", &C::match_odometry, {"auto", "false", "true"},
                  "graph: weigh the odometry's prediction into each scan match by the information of each (for "
                  "wheel odometry better than the scans along featureless corridors); auto: once 600 scans are "
                  "matched, on (as if from the first scan) when 90% of the matches' headings are within 2.2 of "
                  "the odometry's standard deviations, else off")
          .number("match_sigma", &C::match_sigma, above(0, 10), "m",
                  "graph, match_odometry: a point's noise about its wall, for the match's information")
          .numbers("odometry_noise", &C::odometry_noise, between(0, 10), "m/m, m, rad/rad, rad",
                   "graph, match_odometry: the odometry's standard deviation over a step: per metre of travel, "
                   "plus, per radian of turn, plus")
          .number("insertion_lin_distance", &C::insertion_lin_distance, above(0, 1e3), "m",
                  "motion after which a scan becomes a keyframe of the map")
          .number("insertion_ang_distance", &C::insertion_ang_distance, above(0, 360), "deg", "... or rotation")
          .number("localization_lin_distance", &C::localization_lin_distance, above(0, 1e3), "m",
                  "motion after which a scan is matched against the map")
          .number("localization_ang_distance", &C::localization_ang_distance, above(0, 360), "deg", "... or rotation")
          .number("min_icp_goodness", &C::min_icp_goodness, between(0, 1), "",
                  "below it, an ICP correction is rejected")
          .number("min_dist_between_points", &C::min_dist_between_points, above(0, 100), "m", "point-map insertion")
          .flag("fuse_points", &C::fuse_points,
                "fuse new points with the map's (icp-slam's demo has false, which makes the map, and every ICP, "
                "grow with each revisit)")
          .integer("max_iterations", &C::max_iterations, between(1, 100000), "", "ICP iterations")
          .number("threshold_dist", &C::threshold_dist, above(0, 100), "m", "ICP: initial pairing distance")
          .number("threshold_ang", &C::threshold_ang, above(0, 180), "deg", "ICP: initial pairing angle")
          .number("alfa", &C::alfa, between(0.01, 1), "", "ICP: factor the thresholds shrink by on convergence")
          .number("smallest_threshold_dist", &C::smallest_threshold_dist, above(0, 100), "m",
                  "ICP: the pairing distance it stops shrinking at")
          .integer("decimation", &C::decimation, between(1, 1000), "", "ICP: use one point in this many")
          .number("map_resolution", &C::map_resolution, between(0.001, 10), "m", "cell of the occupancy image")
          .check([](const config::Value& v, C& c) -> Status {
            c.given.clear();
            for (const auto& kv : v.node()) c.given.insert(kv.first.Scalar());
            if (!c.ini.empty() && !c.given.count("method")) c.method = "icp-slam";  // an icp-slam .ini asks for it
            if (!c.ini.empty() && c.method != "icp-slam") {
              return Error{v["ini"].place() + ": " + v["ini"].key() + ": an icp-slam .ini file is for method icp-slam"};
            }
            if (!c.ini.empty()) {
              if (c.ini[0] != '/' && v.file().find('/') != std::string::npos) {
                c.ini = v.file().substr(0, v.file().rfind('/') + 1) + c.ini;  // relative to the config file
              }
              if (!std::ifstream(c.ini))
                return Error{v["ini"].place() + ": " + v["ini"].key() + ": cannot open " + c.ini};
            }
            return {};
          });
  return t;
}

const config::Table<Slam3dConfig>& slam3d_config_table() {
  using C = Slam3dConfig;
  using config::above;
  using config::between;
  static const auto t =
      config::Table<C>()
          .text("cloud_channel", &C::cloud_channel, "driftlab.point_cloud_t in", config::Text::kNonEmpty)
          .text("odom_channel", &C::odom_channel,
                "driftlab.odometry_t or pose_t: the guess and the deskewing; \"\" for none")
          .text("tf_static_channel", &C::tf_static_channel, "where base_link -> cloud frame is read; \"\" for none")
          .text("pose_channel", &C::pose_channel, "driftlab.pose_t out, one per cloud")
          .text("base_frame", &C::base_frame, "the robot's base frame")
          .numbers("sensor_pose", &C::sensor_pose, between(-1e3, 1e3), "m, m, m, rad",
                   "x, y, z, yaw of the sensor on the base, when TF has none")
          .flag("deskew", &C::deskew, "undo the motion during a sweep (needs odometry and per-point time_offsets)")
          .choice("method", &C::method, {"icp", "ndt", "gicp"}, "the registration")
          .number("min_range", &C::min_range, between(0, 1e6), "m", "returns nearer are the robot itself")
          .number("max_range", &C::max_range, above(0, 1e6), "m", "returns farther are dropped")
          .number("voxel", &C::voxel, above(0, 100), "m", "leaf of the downsampled scan and of the local map")
          .number("max_correspondence", &C::max_correspondence, above(0, 100), "m",
                  "icp, gicp: largest point pair distance; all: the pairs max_fitness counts")
          .number("ndt_resolution", &C::ndt_resolution, above(0, 100), "m", "ndt: cell size")
          .number("ndt_step", &C::ndt_step, above(0, 100), "m", "ndt: More-Thuente line search step")
          .integer("max_iterations", &C::max_iterations, between(1, 10000), "", "registration iterations")
          .number("max_fitness", &C::max_fitness, above(0, 1e4), "m^2",
                  "mean squared distance to the map above which a registration is rejected")
          .number("keyframe_distance", &C::keyframe_distance, above(0, 1e3), "m",
                  "a cloud becomes a keyframe after this much motion")
          .number("keyframe_angle", &C::keyframe_angle, above(0, 360), "deg", "... or this much rotation")
          .integer("local_map_keyframes", &C::local_map_keyframes, between(1, 10000), "",
                   "keyframes in the registration target")
          .number("map_voxel", &C::map_voxel, above(0, 100), "m", "leaf of the final map (PCD)");
  return t;
}

const config::Table<SlamConfig>& slam_config_table() {
  static const auto t =
      config::Table<SlamConfig>()
          .choice("backend", &SlamConfig::backend, {"auto", "2d", "3d"},
                  "auto: 2d when the logs have laser scans on the 2D scan channel, else 3d when they have point "
                  "clouds on the 3D cloud channel, else 2d")
          .section("2d", &SlamConfig::two_d, slam2d_config_table(), "2D lidar SLAM (MRPT's ICP map builder)")
          .section("3d", &SlamConfig::three_d, slam3d_config_table(), "3D point-cloud odometry (PCL registration)");
  return t;
}

}  // namespace driftlab::slam
