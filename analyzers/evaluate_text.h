// `driftlab eval`'s text: the matching, the alignment and the ATE, RPE and drift tables of an evaluation against a
// reference, the SLAM benchmark's relation error, and an arm's tracking (joints, end effector, oscillation). The
// text form of what evaluate.h gives as JSON. Thread-safety: pure functions.
#pragma once

#include <string>

#include "analyzers/arm_tracking.h"
#include "analyzers/evaluate.h"

namespace driftlab::analyzers {

/// The tables of an evaluation: against the reference (when it has one), then the relation error (when asked).
std::string evaluation_text(const Evaluation& ev);

/// An arm's tracking error (`driftlab eval --arm LOG`).
std::string arm_tracking_text(const ArmTracking& a);

}  // namespace driftlab::analyzers
