// What a log holds, as series to plot: per stream the arrival time and latency of every message, every pose
// channel as a trajectory, and the last map image of each channel that carries one. Read in one pass.
// Thread-safety: pure function of the log.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "analyzers/trajectory.h"
#include "core/result.h"

namespace driftlab::analyzers {

struct StreamSeries {
  std::string channel;
  std::string type;             ///< "driftlab.imu_t", or "" when unknown
  bool has_header = false;      ///< stamps were read from driftlab.header_t (latency is meaningful)
  std::vector<double> arrival;  ///< log time of each message [s from the log's first event]
  std::vector<double> latency;  ///< arrival - header stamp [s], as diagnose measures it (a scan from its last
                                ///< beam: ready_after_us); empty without a header
};

struct MapImage {
  std::string channel;
  int32_t width = 0, height = 0;
  std::vector<uint8_t> png;  ///< the image as sent (driftlab.image_t with encoding "png")
};

/// A 2D SLAM's loop tests (driftlab.loop_closure_t), in the order published: the current and the old keyframe by
/// their scans' stamps, and the outcome.
struct LoopSeries {
  std::string channel;
  std::vector<int64_t> utime, old_utime;  ///< [us]
  std::vector<std::string> outcome;       ///< accepted, waiting, low_overlap, ... (docs/slam.md)
};

/// An arm's command loop: the commanded and measured positions of its joints at the joint states' stamps, where the
/// commanded motion is defined (the plan of the last command stamped at or before each time, as `driftlab
/// diagnose` reads it); every joint state, or every k-th so that at most 20,000 are kept.
struct ArmSeries {
  std::string command_channel;  ///< driftlab.joint_trajectory_t
  std::string state_channel;    ///< driftlab.joint_state_t with all its joints (the most messages)
  std::vector<std::string> joints;
  std::vector<double> t;                       ///< [s from the log's first event]
  std::vector<std::vector<double>> commanded;  ///< per joint [rad or m]
  std::vector<std::vector<double>> measured;   ///< per joint [rad or m]
};

/// What an estimator did with its inputs over time, from its driftlab.estimator_status_t messages (cumulative
/// counts per input, as the estimator publishes them).
struct EstimatorSeries {
  std::string channel;
  std::vector<std::string> inputs;  ///< "imu", "gnss", ...
  std::vector<double> t;            ///< [s from the log's first event]
  /// Per input, per message: measurements fused, and rejected as stale, from the future, late, or outliers.
  std::vector<std::vector<int64_t>> fused, stale, future, late, outliers;
};

struct LogSeries {
  std::string log;
  int64_t start_utime = 0, end_utime = 0;      ///< first and last log time [us]
  std::vector<StreamSeries> streams;           ///< by channel name
  std::map<std::string, Trajectory> poses;     ///< driftlab.pose_t and odometry_t channels (stamps: header [s])
  std::map<std::string, std::string> pose_bodies;  ///< pose channel -> its first pose's child_frame_id (the body)
  std::vector<MapImage> maps;                  ///< image_t channels whose frame is "map"
  std::vector<ArmSeries> arms;                 ///< per channel of joint trajectory commands
  std::vector<EstimatorSeries> estimators;     ///< per channel of driftlab.estimator_status_t
  std::vector<LoopSeries> loops;               ///< per channel of driftlab.loop_closure_t
  uint64_t problems = 0;                       ///< corruption met while reading
};

/// Reads the whole log, or only the channels `channels` names (LogReader's channel filter: comma-separated names
/// or patterns; empty: all). Errors name the log (missing, unreadable); corruption is counted, not fatal.
Result<LogSeries> read_log_series(const std::string& log, const std::string& channels = "");

}  // namespace driftlab::analyzers
