// MRPT rawlogs <-> driftlab logs, so MRPT's own tools (icp-slam, RawLogViewer) work on our logs and MRPT's datasets
// replay through driftlab. Both rawlog formats are read (action/sensory-frame pairs and observations only); rawlogs
// are written as observations only. MRPT stays inside rawlog.cc.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "core/result.h"

namespace driftlab::slam {

struct RawlogCounts {
  std::map<std::string, int64_t> written;   ///< messages (import) or observations (export) by channel / class
  std::map<std::string, int64_t> skipped;   ///< what has no counterpart, by MRPT class or driftlab channel
  int64_t observations = 0;                 ///< import: observations read (converted or skipped)
  /// import: when two or more observations were read and all carry one timestamp (MRPT 2.5's carmen2rawlog gives
  /// every observation the time it ran), their count; else 0. The log's times then say nothing.
  int64_t one_stamp = 0;
  int64_t one_stamp_us = 0;  ///< import: that timestamp [us since the epoch]
};

/// Converts an MRPT rawlog (plain or gzip) into a driftlab log: 2D scans on SCAN (their sensor poses on TF_STATIC
/// as base_link -> the sensor label), odometry on ODOM (CObservationOdometry, or CActionRobotMovement2D
/// increments integrated, stamped with the sensory frame that follows), IMU on IMU, robot poses
/// (CObservationRobotPose) on GROUND_TRUTH. Event times are the observations' timestamps. The log is written as
/// OUT.partial and renamed when complete. Errors name the file and the entry. A rawlog whose observations all carry
/// one timestamp is converted (in file order) and counted in one_stamp, for the caller to report.
Result<RawlogCounts> import_rawlog(const std::string& rawlog, const std::string& out_log);

/// Converts a driftlab log into an observations-only rawlog: laser_scan_t channels (with base_link -> scan frame
/// from TF_STATIC) to CObservation2DRangeScan, odometry_t to CObservationOdometry, imu_t to CObservationIMU and
/// GROUND_TRUTH pose_t to CObservationRobotPose, in log order, stamped with the header stamps.
Result<RawlogCounts> export_rawlog(const std::string& log, const std::string& out_rawlog);

}  // namespace driftlab::slam
