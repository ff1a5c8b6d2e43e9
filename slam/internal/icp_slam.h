#pragma once
// The icp-slam method, MRPT's ICP map builder (mrpt::slam::CMetricMapBuilderICP), behind an interface of its own:
// it lives in a library loaded only when the method is chosen (driftlab-icp-slam.so, beside the programs), so that
// a program running the graph method (every default run of `driftlab replay`) neither loads nor binds MRPT's SLAM
// library and the hundred-odd libraries it brings (MRPT vision, OpenCV's whole set) at every start
// (docs/benchmarks.md, "Start-up").
#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose3D.h>

#include <cstddef>
#include <memory>

#include "core/result.h"

namespace driftlab::slam::internal {

class IcpSlamBuilder {
 public:
  virtual ~IcpSlamBuilder() = default;
  /// One scan (in `frame`) after the odometry's motion in `actions` (empty when there is none); the map's size
  /// (keyframes) after it.
  virtual size_t process(mrpt::obs::CActionCollection& actions, mrpt::obs::CSensoryFrame& frame) = 0;
  /// The pose estimate now, MRPT's (x, y, z, yaw, pitch, roll) covariance.
  virtual void estimate(mrpt::math::CMatrixDouble66& covariance, mrpt::poses::CPose3D& mean) const = 0;
  /// The keyframes: each scan inserted into the map with its pose.
  virtual void keyframes(mrpt::maps::CSimpleMap& out) const = 0;
};

/// What the library exports (kIcpSlamFactory): a builder with `ini`'s [MappingApplication] and [ICP] sections;
/// throws what MRPT throws for settings it rejects.
using IcpSlamFactory = IcpSlamBuilder* (*)(const mrpt::config::CConfigFileBase* ini);
inline constexpr const char* kIcpSlamLibrary = "driftlab-icp-slam.so";
inline constexpr const char* kIcpSlamFactory = "driftlab_make_icp_slam";

/// The factory, from the library loaded (once per process) from beside the running program
/// (core/install_layout.h); an error naming the library when it is missing or cannot be loaded.
Result<IcpSlamFactory> icp_slam_factory();

}  // namespace driftlab::slam::internal
