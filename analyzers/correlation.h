// How sure a motion correlation has to be before driftlab acts on it: one figure for every measure that lines up
// two motions by their peak normalised (Pearson) correlation (the skew between two streams, an estimate's offset
// against ground truth, a command loop's delay, an IMU's clock against another's).
#pragma once

namespace driftlab::analyzers {

/// A peak correlation this high or higher is a match driftlab trusts: diagnose names the skew, eval applies
/// `--offset auto`, a closed-loop replay re-times commands, a flight log's IMU is aligned to a bag's. Below it, the
/// motions are too plain or too unlike for one lag to stand out (a robot driving straight at constant speed
/// correlates with itself at every lag), and the finding is reported as unsure, not used.
inline constexpr double kConfidentCorrelation = 0.8;

}  // namespace driftlab::analyzers
