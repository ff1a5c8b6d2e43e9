// The time offset between two trajectories of the same motion, found from the motion itself: an estimate stamped
// by another clock (a camera's, a time base started at boot) against ground truth. evo leaves the user to guess
// --t_offset (evo issue 417: "it only finds 1 matching pose"); `driftlab eval --offset auto` measures it.
// Thread-safety: a pure function.
#pragma once

#include <string>

#include "analyzers/trajectory.h"

namespace driftlab::analyzers {

struct TimeOffset {
  bool found = false;
  double offset_s = 0;     ///< add to the estimate's stamps to line its motion up with the reference's [s]
  /// Peak normalised (Pearson) correlation of the two motion signals at that offset, 0..1: the measure the timing
  /// diagnosis gives stream skew (trusted from kConfidentCorrelation, analyzers/correlation.h).
  double confidence = 0;
  std::string signal;      ///< "speed" or "angular speed": the one that correlated best
  double overlap_s = 0;    ///< how long the two trajectories share at that offset [s]
  std::string problem;     ///< why no offset was found, when not found
};

struct TimeOffsetOptions {
  /// The two must overlap by at least this share of the shorter one's duration at a candidate offset.
  double min_overlap = 0.5;
};

/// Cross-correlates the speed and the angular speed of the two trajectories (both independent of their frames,
/// and the correlation of their scale: a monocular estimate's unknown scale does not matter), each over a window of
/// 0.5 s or two sampling intervals (the longer), at every offset at which they overlap enough, then refines the
/// best one. Coarse stage: both signals on a grid of a fifth of the window (at most 2^17 points over both spans,
/// and 8 per pose), every lag at once by FFT, each lag's correlation taken over the samples both trajectories have
/// there (tracking gaps left out). Fine stage: lags every fiftieth of the window within two coarse steps of the
/// peak, then a parabola through the top three. Both trajectories must be sorted by stamp, stamped, and at least
/// 2 s long.
TimeOffset estimate_time_offset(const Trajectory& ref, const Trajectory& est, const TimeOffsetOptions& options = {});

}  // namespace driftlab::analyzers
