#include "slam/slam_module.h"

#include "core/config.h"

namespace driftlab::slam {

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

Result<std::unique_ptr<Module>> make_slam(const YAML::Node& config, const std::string& origin, const HasData& has_data,
                                          std::string* chosen) {
  // Both backends' settings are read, so a bad key is reported whichever backend runs.
  auto c = slam_config_table().parse(config::Value(config, origin, "slam"));
  if (!c) return c.error();
  std::string backend = c->backend;
  if (backend == "auto") {
    const bool scans = has_data(c->two_d.scan_channel, "driftlab.laser_scan_t");
    backend = !scans && has_data(c->three_d.cloud_channel, "driftlab.point_cloud_t") ? "3d" : "2d";
  }
  if (chosen != nullptr) *chosen = backend;
  if (backend == "2d") return std::unique_ptr<Module>(new Slam2d(std::move(c->two_d)));
  return std::unique_ptr<Module>(new Slam3d(std::move(c->three_d)));
}

}  // namespace driftlab::slam
