// The `slam` replay module: 2D lidar SLAM (MRPT's ICP map builder, slam2d.h) or 3D point-cloud odometry (PCL
// registration, slam3d.h), chosen by `backend` in its config or, with `auto`, by the data the logs hold.
// Config: `slam: {backend: auto|2d|3d, 2d: {...}, 3d: {...}}` (docs/slam.md).
#pragma once

#include <yaml-cpp/yaml.h>

#include <functional>
#include <memory>
#include <string>

#include "core/bus.h"
#include "core/result.h"
#include "slam/slam2d.h"
#include "slam/slam3d.h"

namespace driftlab::slam {

/// The `slam:` map of a replay config.
struct SlamConfig {
  std::string backend = "auto";  ///< auto, 2d or 3d
  Slam2dConfig two_d;            ///< `2d:`
  Slam3dConfig three_d;          ///< `3d:`
};

/// Its keys, with units, ranges and defaults (core/config.h); `2d` and `3d` are slam2d's and slam3d's tables.
const config::Table<SlamConfig>& slam_config_table();

/// Whether the input holds a message of the named type ("driftlab.laser_scan_t") on a channel.
using HasData = std::function<bool(const std::string& channel, const std::string& type)>;

/// The SLAM module its config asks for; `auto` takes 2D when the logs have laser scans on the 2D scan channel,
/// else 3D when they have point clouds on the 3D cloud channel, else 2D (which then warns that it saw no scans).
/// `chosen` receives "2d" or "3d". Errors name the file, line and key.
Result<std::unique_ptr<Module>> make_slam(const YAML::Node& config, const std::string& origin, const HasData& has_data,
                                          std::string* chosen = nullptr);

}  // namespace driftlab::slam
