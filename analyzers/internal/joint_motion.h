// Joint trajectory commands and joint states read from a log, and the commanded position of each joint at a time:
// what the command loop check of `driftlab diagnose`, the arm's tracking error of `driftlab eval` and the report's
// commanded-vs-measured plot share, so the three see the same commanded motion. Internal to analyzers.
// Thread-safety: plain values.
#pragma once

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

namespace driftlab::analyzers::internal {

/// Linear interpolation of y at x in ascending xs (at least one), held after the end; before the start,
/// extrapolated along the first two points when `extrapolate_front` (a plan's first point lies a period after its
/// stamp: the controller moves towards it from the stamp on), held otherwise.
double interpolate(const std::vector<int64_t>& xs, const std::vector<double>& ys, int64_t x, bool extrapolate_front);

/// One driftlab.joint_trajectory_t: stamp and arrival [us], and its points.
struct JointCommand {
  int64_t stamp = 0, arrival = 0;
  std::vector<int64_t> t;              ///< points' times from the stamp [us], increasing
  std::vector<std::vector<double>> q;  ///< per point, in the channel's joint order
};

/// The commands of one channel. Commands whose joints differ from the first one's, without points, with times
/// that do not increase, or with numbers that are not finite are left out, as are stamps and plan times beyond
/// bounds no clock reaches (so that sums of two of them cannot overflow).
struct JointCommands {
  std::vector<std::string> joints;
  std::vector<JointCommand> list;  ///< in arrival order
  /// Adds an encoded driftlab.joint_trajectory_t that arrived at `arrival` [us]; false when left out.
  bool add(std::span<const uint8_t> data, int64_t arrival);
};

/// The joint states of one channel: positions at their stamps, in the first message's joint order. Messages whose
/// names differ from the first's, whose stamps do not increase or whose positions are not finite are left out;
/// a first message naming a joint twice leaves the channel empty.
struct JointStates {
  std::vector<std::string> names;       ///< of the first message
  std::map<std::string, size_t> index;  ///< joint name -> column
  std::vector<int64_t> stamp;           ///< [us]
  std::vector<std::vector<double>> q;   ///< positions [rad or m], per message
  std::vector<std::vector<double>> v;   ///< velocities [rad/s or m/s], per message (empty rows when not sent)
  /// Adds an encoded driftlab.joint_state_t; false when left out.
  bool add(std::span<const uint8_t> data);
  /// Whether every one of `joints` is a column.
  bool has_all(const std::vector<std::string>& joints) const;
};

/// The commanded motion of a command channel: at time t, the plan of the last command stamped at or before t,
/// interpolated along its points (from its stamp; before its first point, along the first two).
class CommandedMotion {
 public:
  explicit CommandedMotion(const JointCommands& commands);
  size_t joints() const { return joints_; }
  size_t commands() const { return by_stamp_.size(); }
  /// The commands by stamp (ties in arrival order).
  const std::vector<const JointCommand*>& by_stamp() const { return by_stamp_; }
  /// The first command's stamp and the end of the last command's plan [us]: where the motion is defined.
  int64_t start() const;
  int64_t end() const;
  /// The commanded positions at t [us] into q (joints() of them); false before the first command. Calls with
  /// increasing t take linear time overall.
  bool at(int64_t t, std::vector<double>& q) const;

 private:
  size_t joints_ = 0;
  std::vector<const JointCommand*> by_stamp_;
  mutable size_t active_ = 0;
  mutable std::vector<double> plan_j_;
};

}  // namespace driftlab::analyzers::internal
