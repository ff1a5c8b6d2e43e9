// The `slam` replay module: 2D lidar SLAM (MRPT's ICP map builder, slam2d.h) or 3D point-cloud odometry (PCL
// registration, slam3d.h), chosen by `backend` in its config or, with `auto`, by the data the logs hold.
// Config: `slam: {backend: auto|2d|3d, 2d: {...}, 3d: {...}}` (docs/slam.md).
#pragma once

#include <yaml-cpp/yaml.h>

#include <functional>
#include <memory>
#include <string>

#include "core/result.h"
#include "runtime/bus.h"
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

/// The SLAM module its config asks for. `auto` takes 2D when the input has laser scans, else 3D when it has point
/// clouds, else 2D (which then warns that it saw no scans). An input channel not set in the config and absent from
/// `inputs` (what the run delivers) is found there by type: the scans (or clouds) on the channel of that type with
/// the most messages, the odometry on a driftlab.odometry_t channel or else on the scan channel's pose stream
/// (SCAN_POSE: a CARMEN laser line's odometry), the sensor's mounting on a driftlab.tf_t channel named *tf_static.
/// `notes` receives what was chosen ("slam: 2d backend", "slam: scans from /scan ..."). Errors name the file, line
/// and key.
Result<std::unique_ptr<Module>> make_slam(const YAML::Node& config, const std::string& origin,
                                          const InputChannels& inputs, std::vector<std::string>* notes = nullptr);

}  // namespace driftlab::slam
