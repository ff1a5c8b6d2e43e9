// Which clocks a timing diagnosis says to correct, and by how much: the rule `driftlab replay --restamp auto`
// applies and the diagnosis summary (report, demo) names, in one place. Thread-safety: pure functions.
#pragma once

#include <string>
#include <vector>

#include "analyzers/timing.h"
#include "core/clock_correction.h"

namespace driftlab::analyzers {

/// A clock whose stamps run ahead of their arrival by this much or more is ahead: no transport can explain it.
inline constexpr double kClockAheadMin_s = 0.001;
/// A clock drifting by this much or more (either way) is corrected.
inline constexpr double kClockDriftMin_ppm = 25;

inline bool clock_ahead(double offset_s) { return offset_s >= kClockAheadMin_s; }
inline bool clock_drifts(double drift_ppm) { return drift_ppm >= kClockDriftMin_ppm || drift_ppm <= -kClockDriftMin_ppm; }

/// The corrections for the channels of a diagnosis whose clock is ahead or drifts (a clock behind cannot be told
/// from latency in one log and is left alone), each only where its 95% confidence interval leaves out zero.
/// `notes` receives one line per correction, saying what and why, and one per correction left out.
ClockCorrections clock_corrections(const Diagnosis& d, std::vector<std::string>* notes = nullptr);

}  // namespace driftlab::analyzers
