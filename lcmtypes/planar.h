// Planar helpers for the message types: the one planar pose, the one angle wrap, the yaw of a quaternion and the
// quaternion of a yaw.
#pragma once

#include <cmath>

#include "driftlab/quaternion_t.hpp"

namespace driftlab {

/// A pose in the plane: position [m] and heading [rad, counter-clockwise from the x axis].
struct Pose2 {
  double x = 0, y = 0;
  double yaw = 0;
};

/// An angle wrapped to (-pi, pi] [rad]: -pi becomes pi, pi stays (ROS's angles::normalize_angle has the same
/// boundary), so an angle and its wrap differ by a whole number of turns and every direction has one value.
/// Angle differences (a - b) are wrapped with it to take the shorter way round.
inline double wrap_angle(double a) {
  a = std::remainder(a, 2 * M_PI);  // [-pi, pi], exact: remainder rounds the quotient to nearest
  return a <= -M_PI ? a + 2 * M_PI : a;
}

/// The heading of a unit quaternion [rad]: its rotation about z in the z-y-x (yaw, pitch, roll) convention.
inline double yaw_of(const quaternion_t& q) {
  return std::atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z));
}

/// The unit quaternion of a rotation by yaw [rad] about z.
inline quaternion_t yaw_quaternion(double yaw) { return {std::cos(yaw / 2), 0, 0, std::sin(yaw / 2)}; }

}  // namespace driftlab
