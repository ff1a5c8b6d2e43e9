// Conversions between driftlab.laser_scan_t and MRPT's CObservation2DRangeScan (used by the 2D SLAM module and the
// rawlog import/export). MRPT's beams span `aperture` symmetrically about the sensor's x axis, counter-clockwise
// when rightToLeft; ours start at angle_min and step by angle_increment, so the centre of our fan goes into the
// sensor's yaw.
#pragma once

#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/poses/CPose2D.h>

#include <cmath>

#include "core/time.h"
#include "driftlab/laser_scan_t.hpp"

namespace driftlab::slam::internal {

/// Readings at or above this share of range_max are a scanner's "no return" code, not an echo.
inline constexpr float kNoReturnShare = 0.99f;

/// Our scan (at least two beams) as an MRPT observation, for a scanner at `sensor_on_base` (x, y, yaw). Readings
/// at or beyond `no_return_from` are no returns too (a code no_return.h found, or a maximum the user set).
inline mrpt::obs::CObservation2DRangeScan::Ptr to_mrpt(const driftlab::laser_scan_t& scan,
                                                       const mrpt::poses::CPose2D& sensor_on_base,
                                                       float no_return_from = INFINITY) {
  auto obs = mrpt::obs::CObservation2DRangeScan::Create();
  const int n = scan.nranges;
  const double increment = scan.angle_increment;
  obs->aperture = static_cast<float>(std::abs(increment) * (n - 1));
  obs->rightToLeft = true;
  obs->maxRange = scan.range_max;
  obs->stdError = 0.01f;
  obs->resizeScan(n);
  for (int i = 0; i < n; ++i) {
    const float r = scan.ranges[static_cast<size_t>(increment > 0 ? i : n - 1 - i)];
    // A reading at range_max is the scanner saying "no return" (a SICK reports its maximum, 50 m or 81.83 m, for
    // every beam without an echo; ROS bags made from CARMEN logs carry it as range_max, or a little above the
    // code: Freiburg's clinic log has range_max 81.9 with 81.83 and 81.91 as its no-echo readings): not a point.
    // Within 1% of range_max counts as there.
    const bool valid =
        std::isfinite(r) && r >= scan.range_min && r < kNoReturnShare * scan.range_max && r < no_return_from;
    obs->setScanRange(i, valid ? r : scan.range_max);
    obs->setScanRangeValidity(i, valid);
  }
  const double centre = scan.angle_min + increment * (n - 1) / 2;
  obs->sensorPose = mrpt::poses::CPose3D(sensor_on_base.x(), sensor_on_base.y(), 0,
                                         sensor_on_base.phi() + centre, 0, 0);
  obs->timestamp = mrpt::Clock::fromDouble(Time::from_us(scan.header.utime).seconds());
  return obs;
}

/// An MRPT observation as our scan in the sensor's frame (the sensor's pose on the robot goes to TF).
inline driftlab::laser_scan_t from_mrpt(const mrpt::obs::CObservation2DRangeScan& obs) {
  driftlab::laser_scan_t s{};
  const int n = static_cast<int>(obs.getScanSize());
  s.nranges = n;
  s.ranges.resize(static_cast<size_t>(n));
  const float half = obs.aperture / 2;
  s.angle_min = -half;
  s.angle_max = half;
  s.angle_increment = n > 1 ? obs.aperture / static_cast<float>(n - 1) : 0.0f;
  s.range_min = 0;
  s.range_max = obs.maxRange;
  for (int i = 0; i < n; ++i) {
    const int j = obs.rightToLeft ? i : n - 1 - i;
    s.ranges[static_cast<size_t>(i)] = obs.getScanRangeValidity(j) ? obs.getScanRange(j) : NAN;
  }
  s.nintensities = 0;
  return s;
}

}  // namespace driftlab::slam::internal
