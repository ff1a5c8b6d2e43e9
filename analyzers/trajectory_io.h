// Loading and saving trajectories: the text formats evo reads (TUM, KITTI, EuRoC ground truth) and pose/odometry
// channels of LCM logs. Every pose is checked on the way in: finite numbers and a rotation (a unit quaternion
// within rounding, an orthonormal matrix), with errors naming the file and line or the log and byte.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <string>

#include "analyzers/trajectory.h"
#include "core/result.h"

namespace driftlab::analyzers {

enum class TrajectoryFormat { kAuto, kTum, kKitti, kEuroc };
const char* to_string(TrajectoryFormat format);

/// Splits "LOG:CHANNEL" at its last ':' when the part before it exists (a file, or a folder: a bag); false (log and
/// channel untouched) otherwise. So a log's name may hold ':' and a channel's may not (ROS names hold none). The
/// outputs may alias src.
bool split_log_channel(const std::string& src, std::string* log, std::string* channel);

/// SRC is "LOG:CHANNEL" (a driftlab.pose_t, odometry_t or trajectory_setpoint_t channel, stamped with header.utime;
/// a setpoint is the pose it asks for: its position, level, turned by its yaw) when the
/// part before the last ':' is an existing file, else a text file in `format`. kAuto tells the text formats apart
/// by their first data line: 8 numbers a TUM file, 12 a KITTI file, a "#timestamp" header or more than 8
/// comma-separated numbers (other than 12) an EuRoC file. `times`: with KITTI, the file of its stamps.
Result<Trajectory> load_trajectory(const std::string& src, TrajectoryFormat format = TrajectoryFormat::kAuto,
                                   const std::string& times = "");

/// A TUM trajectory: one pose per line, "t x y z qx qy qz qw" separated by spaces, tabs or commas; blank lines
/// and lines starting with '#' are skipped. Errors name the file and the line.
Result<Trajectory> load_tum(const std::string& path);

/// A KITTI pose file: one pose per line, the first three rows of its 4x4 matrix, "r11 r12 r13 tx r21 r22 r23 ty
/// r31 r32 r33 tz". KITTI poses carry no stamps: with `times` (KITTI odometry's times.txt: one stamp [s] a line,
/// as many as poses) they get those, else the trajectory is unstamped (Trajectory::stamped false, stamps 0, 1, ...)
/// and can only be compared pose for pose with another unstamped one of the same length, as evo does.
Result<Trajectory> load_kitti(const std::string& path, const std::string& times = "");

/// EuRoC MAV ground truth (state_groundtruth_estimate0/data.csv): comma-separated, "#" header, at least 8 columns
/// "timestamp [ns], x, y, z, qw, qx, qy, qz, ..." (the rest, velocities and biases, ignored).
Result<Trajectory> load_euroc(const std::string& path);

/// Why a pose cannot be used, or "" when it can: a number that is not finite, a zero quaternion, or one whose norm
/// is not 1 within 1% (any quaternion printed with three decimals or more is within that; further off it is not a
/// rotation at all, and normalising it would hide the bug that made it).
std::string pose_problem(double stamp, const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation);

/// Appends the pose of an encoded driftlab.pose_t, odometry_t or trajectory_setpoint_t (its position, level, turned
/// by its yaw) (stamp: header.utime [s]) when it is usable; false
/// for other types, data that does not decode, or a pose with a pose_problem (said in *why when given).
bool append_pose(std::span<const uint8_t> data, Trajectory& t, std::string* why = nullptr);

/// Poses of one channel of a log, in log order; stamps are header.utime [s]. Errors name the log, channel and the
/// byte of the event.
Result<Trajectory> load_log_channel(const std::string& log, const std::string& channel);

/// Writes a TUM file, whole or not at all (core/text_file.h): stamps to the microsecond, the rest with every digit a
/// double has (it reads back exactly).
Status write_tum(const std::string& path, const Trajectory& t);

}  // namespace driftlab::analyzers
