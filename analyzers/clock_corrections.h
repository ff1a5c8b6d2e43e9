// Which clocks a timing diagnosis says to correct, and by how much: the rule `driftlab replay --restamp auto`
// applies and the diagnosis summary (report, demo) names, in one place. Thread-safety: pure functions.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "analyzers/timing.h"
#include "core/clock_correction.h"
#include "core/result.h"
#include "core/time.h"

namespace driftlab::analyzers {

/// A clock whose stamps run ahead of their arrival by this much or more is ahead: no transport can explain it.
inline constexpr double kClockAheadMin_s = 0.001;
/// A clock drifting by this much or more (either way) is corrected.
inline constexpr double kClockDriftMin_ppm = 25;

inline bool clock_ahead(double offset_s) { return offset_s >= kClockAheadMin_s; }
inline bool clock_drifts(double drift_ppm) { return drift_ppm >= kClockDriftMin_ppm || drift_ppm <= -kClockDriftMin_ppm; }

/// A command loop whose measured delay is this long or longer is re-timed: longer than the controller's own lag
/// (under a millisecond in the shipped arm), short of any transport worth naming.
inline constexpr double kRetimeDelayMin_s = 0.01;
/// ... when the measured joints repeat the commanded motion at that delay as closely as analyzers/correlation.h asks.

/// Per command channel of a diagnosis' command loops, the delay to take off each command's arrival when a
/// closed-loop replay re-times them (`driftlab replay --closed-loop --retime auto`): the measured command-to-motion
/// delay, where it is long and sure enough. `notes` receives a line per channel re-timed or left alone.
std::map<std::string, Duration> command_retiming(const Diagnosis& d, std::vector<std::string>* notes = nullptr);

/// The corrections for the channels of a diagnosis whose clock is ahead or drifts (a clock behind cannot be told
/// from latency in one log and is left alone), each only where its 95% confidence interval leaves out zero.
/// `notes` receives one line per correction, saying what and why, and one per correction left out.
ClockCorrections clock_corrections(const Diagnosis& d, std::vector<std::string>* notes = nullptr);

/// The corrections a replay of these logs is asked for: each log diagnosed once, and only when a correction comes
/// from its diagnosis.
struct CorrectionPlan {
  ClockCorrections clocks;                 ///< by clock_corrections, merged over the logs; empty unless asked
  std::map<std::string, Duration> retime;  ///< per command channel, the delay taken off each command's arrival
  std::vector<std::string> notes;          ///< one line per correction made or left out, and why
};

/// Plans a replay's corrections: with `clocks_from_diagnosis`, the clocks the diagnosis says to correct
/// (`--restamp auto`); and each `retime` item, "auto" (command_retiming) or "CHANNEL=SECONDS" (0..3600, by hand:
/// `--retime`). An item of neither form is an error naming it, as is a log that cannot be diagnosed.
Result<CorrectionPlan> plan_corrections(const std::vector<std::string>& logs, bool clocks_from_diagnosis,
                                        const std::vector<std::string>& retime);

}  // namespace driftlab::analyzers
