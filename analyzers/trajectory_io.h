// Loading and saving trajectories: TUM files ("t x y z qx qy qz qw") and pose/odometry channels of LCM logs.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "analyzers/trajectory.h"
#include "core/result.h"

namespace driftlab::analyzers {

/// SRC is "LOG:CHANNEL" (a driftlab.pose_t or driftlab.odometry_t channel, stamped with header.utime) when the
/// part before the last ':' is an existing file, else a TUM file.
Result<Trajectory> load_trajectory(const std::string& src);

/// A TUM trajectory: one pose per line, "t x y z qx qy qz qw" separated by spaces, tabs or commas; blank lines
/// and lines starting with '#' are skipped. Errors name the file and the line.
Result<Trajectory> load_tum(const std::string& path);

/// Appends the pose of an encoded driftlab.pose_t or odometry_t (stamp: header.utime [s]); false for other types
/// or data that does not decode.
bool append_pose(std::span<const uint8_t> data, Trajectory& t);

/// Poses of one channel of a log, in log order; stamps are header.utime [s]. Errors name the log and channel.
Result<Trajectory> load_log_channel(const std::string& log, const std::string& channel);

/// Writes a TUM file: stamps to the microsecond, the rest with every digit a double has (it reads back exactly).
Status write_tum(const std::string& path, const Trajectory& t);

}  // namespace driftlab::analyzers
