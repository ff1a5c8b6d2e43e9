// Two recordings of one flight on one clock: a flight controller's log (PX4 ULog, stamped by time since boot) and a
// companion computer's bag (stamped by its wall clock) both hold the vehicle's IMU, so the body's rotation, measured
// twice, says how the two clocks relate. The gyros' mean |angular rate| per half second (the same in any body
// frame: PX4's forward-right-down and MAVROS's forward-left-up alike) is cross-correlated by estimate_time_offset
// (analyzers/time_offset.h, given the angle turned so far as a path: every lag at which they overlap by FFT, then a
// fine search and a parabola); on a long enough overlap the same is done on
// segments of it, and the line through their offsets gives the drift of one clock against the other.
// Thread-safety: pure functions.
#pragma once

#include <Eigen/Core>

#include <string>
#include <vector>

#include "analyzers/correlation.h"

namespace driftlab::analyzers {

/// An IMU's angular rates, sorted by stamp.
struct AngularRates {
  std::vector<double> stamps;          ///< [s]
  std::vector<Eigen::Vector3d> rates;  ///< body frame [rad/s]
};

struct ClockAlignment {
  bool found = false;
  /// reference time = other time + offset_s + drift * (other time - at_s) [s]
  double offset_s = 0;
  double at_s = 0;                  ///< the other clock's time the offset holds at (the middle of the overlap) [s]
  double drift = 0;                 ///< [s/s]; 0 unless drift_applied
  bool drift_measured = false;      ///< the overlap was long enough to measure it on segments
  bool drift_applied = false;       ///< and its 95% interval left out zero
  double drift_measured_value = 0;  ///< the slope measured, applied or not [s/s]
  double drift_ci95 = 0;            ///< half-width of its 95% confidence interval [s/s]
  int segments = 0;                 ///< segments whose offsets the drift was fitted to
  double confidence = 0;            ///< peak Pearson correlation of the angular speeds, 0..1
  double overlap_s = 0;             ///< how long the two share at that offset [s]
  std::string problem;              ///< why not found

  /// The other clock's time t on the reference clock [s].
  double to_reference(double t) const { return t + offset_s + drift * (t - at_s); }
};

/// Correlations below kConfidentCorrelation (analyzers/correlation.h) are no alignment: the two IMUs did not see one
/// motion. The shared FMUv4-Pro flight against a 50 Hz copy of its own rates shuffled in time (the same values, no
/// common timing) reaches 0.42 over its 9 s, against the true copy with 0.02 rad/s of noise 0.98.

/// How `other`'s clock maps onto `reference`'s (both IMUs of one vehicle, any frames and rates). Not found (with a
/// problem saying why) when either has fewer than 10 samples or under 2 s, when they never overlap by half the
/// shorter one, or when the best correlation is below kConfidentCorrelation. The drift is measured when the
/// overlap is at least 120 s long, on up to 8 segments of at least 30 s of `other`.
ClockAlignment align_imu_clocks(const AngularRates& reference, const AngularRates& other);

}  // namespace driftlab::analyzers
