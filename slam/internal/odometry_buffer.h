// The recent wheel odometry of a SLAM module, by stamp, interpolated at a scan's stamp (the prior for matching).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <utility>

#include "core/time.h"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "lcmtypes/planar.h"
#include "runtime/module_input.h"

namespace driftlab::slam::internal {

class OdometryBuffer {
 public:
  /// Adds a pose at its stamp [us] (late ones go in place); keeps `depth_us` of history.
  void add(int64_t stamp, const Pose2& pose, int64_t depth_us = 5000000) {
    auto at = std::upper_bound(q_.begin(), q_.end(), stamp, [](int64_t t, const Sample& s) { return t < s.stamp; });
    q_.insert(at, {stamp, pose});
    while (q_.size() > 2 && us_after(q_.front().stamp, q_.back().stamp) > static_cast<uint64_t>(depth_us))
      q_.pop_front();
  }
  bool empty() const { return q_.empty(); }

  /// Whether at(stamp) is final, when a sample comes at most `late` [us of stamps] after a newer one and the
  /// newest stamp yet is `newest`: the sample at the stamp is there, or the first after it is and `newest` is
  /// `late` past that one, so that every sample before it has come (the two around the stamp are the ones the
  /// stream sorted by stamp gives).
  bool settled(int64_t stamp, int64_t newest, uint64_t late) const {
    const auto hi = first_from(stamp);
    if (hi == q_.end()) return false;
    return hi->stamp == stamp || (hi->stamp <= newest && us_after(hi->stamp, newest) >= late);
  }

  /// The pose at a stamp: interpolated between the samples around it (yaw along the shorter way), or the nearest
  /// at either end.
  std::optional<Pose2> at(int64_t stamp) const {
    if (q_.empty()) return std::nullopt;
    if (stamp <= q_.front().stamp) return q_.front().pose;
    if (stamp >= q_.back().stamp) return q_.back().pose;
    const auto hi = first_from(stamp);
    const auto lo = std::prev(hi);
    const double f =
        static_cast<double>(us_after(lo->stamp, stamp)) / static_cast<double>(us_after(lo->stamp, hi->stamp));
    const double dyaw = wrap_angle(hi->pose.yaw - lo->pose.yaw);
    return Pose2{lo->pose.x + f * (hi->pose.x - lo->pose.x), lo->pose.y + f * (hi->pose.y - lo->pose.y),
                 lo->pose.yaw + f * dyaw};
  }

 private:
  struct Sample {
    int64_t stamp;
    Pose2 pose;
  };
  std::deque<Sample> q_;

  /// The first sample at the stamp or after it.
  std::deque<Sample>::const_iterator first_from(int64_t stamp) const {
    return std::lower_bound(q_.begin(), q_.end(), stamp, [](const Sample& s, int64_t t) { return s.stamp < t; });
  }
};

/// The stamp [us] and planar pose of an odometry message on the bus (driftlab.odometry_t, or any pose stream as
/// driftlab.pose_t: a CARMEN laser line's odometry, a robot's pose topic), or nullopt when it is malformed (counted
/// in *malformed) or a number of it is not finite or beyond lcmtypes::kMaxMagnitude (counted by `in`, naming it).
/// *child_frame, when given, is set to the frame whose pose it is (its child_frame_id: base_link, or a sensor's
/// when the pose is the sensor's, as a CARMEN laser line's is).
inline std::optional<std::pair<int64_t, Pose2>> planar_odometry(const BusMessage& m, NonFiniteInputs& in,
                                                                int64_t* malformed,
                                                                std::string* child_frame = nullptr) {
  driftlab::odometry_t o;
  if (driftlab::pose_t p; !decode_message(m, o)) {
    if (!decode_message(m, p)) {
      ++*malformed;
      return std::nullopt;
    }
    o.header = p.header;
    o.position = p.position;
    o.orientation = p.orientation;
    o.child_frame_id = p.child_frame_id;
  }
  if (child_frame != nullptr) *child_frame = o.child_frame_id;
  if (!in.finite(m)) return std::nullopt;
  const double yaw = yaw_of(o.orientation);  // NaN for a quaternion of huge numbers
  if (!std::isfinite(yaw)) {
    in.count(m.channel, "the yaw of orientation = nan");
    return std::nullopt;
  }
  if (!in.plausible(m.channel, "position.x", o.position.x) || !in.plausible(m.channel, "position.y", o.position.y)) {
    return std::nullopt;
  }
  return std::pair{o.header.utime, Pose2{o.position.x, o.position.y, yaw}};
}

}  // namespace driftlab::slam::internal
