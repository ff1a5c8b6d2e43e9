// The `slam` replay module: 2D lidar SLAM with MRPT's ICP map builder (slam2d.h). Config:
// `slam: {backend: 2d, 2d: {...}}` (docs/slam.md); the 3D point-cloud backend (PCL) joins it as `backend: 3d`.
#pragma once

#include <yaml-cpp/yaml.h>

#include <memory>
#include <string>

#include "core/bus.h"
#include "core/result.h"

namespace driftlab::slam {

/// The SLAM module its config asks for. Errors name the file, line and key.
Result<std::unique_ptr<Module>> make_slam(const YAML::Node& config, const std::string& origin);

}  // namespace driftlab::slam
