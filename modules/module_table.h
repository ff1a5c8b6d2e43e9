// The processing modules `driftlab replay` and `driftlab run` host, named once and in one order: the registry
// (modules/registry.h) makes each from its row and writes the settings' reference in this order; sweeps and
// batches (batch/plan.h) check the module names of their specs against it. Header only, with no library behind it,
// so what reads the names does not link the modules (SLAM, the estimators, the flight stack, the simulator).
// Thread-safety: constants.
#pragma once

#include <algorithm>
#include <array>
#include <string>
#include <string_view>

namespace driftlab::modules {

struct ModuleKind {
  std::string_view name;  ///< as --modules and a config file's top-level keys spell it
  std::string_view what;  ///< one line for --help and docs
};

inline constexpr std::array<ModuleKind, 6> kModuleKinds{{
    {"slam", "2D (MRPT's ICP) or 3D (PCL) SLAM from scans or point clouds and odometry"},
    {"estimator", "the planar EKF: odometry, IMU and SLAM poses"},
    {"controller", "the route follower, its commands compared with the logged ones"},
    {"drone_estimator", "the drone's error-state EKF: IMU, GNSS, barometer, magnetometer"},
    {"flight", "the drone's PX4-style flight stack: commander, cascade control, mixer"},
    {"offboard", "the offboard script: setpoints, offboard mode and arming, a mission"},
}};

inline bool is_module(std::string_view name) {
  return std::any_of(kModuleKinds.begin(), kModuleKinds.end(), [&](const ModuleKind& k) { return k.name == name; });
}

/// The module names, comma-separated, in the table's order ("slam, estimator, controller, ...").
inline std::string known_modules() {
  std::string s;
  for (const auto& k : kModuleKinds) (s += s.empty() ? "" : ", ") += k.name;
  return s;
}

}  // namespace driftlab::modules
