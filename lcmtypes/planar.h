// Planar helpers for the message types: the yaw of a quaternion, and the quaternion of a yaw.
#pragma once

#include <cmath>

#include "driftlab/quaternion_t.hpp"

namespace driftlab {

/// The heading of a unit quaternion [rad]: its rotation about z in the z-y-x (yaw, pitch, roll) convention.
inline double yaw_of(const quaternion_t& q) {
  return std::atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z));
}

/// The unit quaternion of a rotation by yaw [rad] about z.
inline quaternion_t yaw_quaternion(double yaw) { return {std::cos(yaw / 2), 0, 0, std::sin(yaw / 2)}; }

}  // namespace driftlab
