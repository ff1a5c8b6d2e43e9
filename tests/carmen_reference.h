// GMapping's corrected CARMEN trajectories (../shared/data/carmen) as a reference for the raw logs' scans. Used by
// the tests and by scripts/bench (through bench/carmen_reference_tum).
#pragma once

#include <string>

#include "analyzers/trajectory.h"
#include "core/result.h"

namespace driftlab::test {

/// GMapping's corrected poses at the raw scans' stamps. The corrected CARMEN log counts time from 0 with six
/// significant digits and holds only the scans GMapping integrated; its readings are the raw ones, unchanged, so
/// each corrected scan is found among the raw scans (`/scan` in `raw_log`, an imported bag) by its readings (data
/// README), and its pose takes that stamp. `corrected_log` is the imported corrected log (FLASER, FLASER_POSE).
/// An error when two raw scans have the same readings (the match would be ambiguous) or a corrected scan is not
/// among the raw ones.
Result<analyzers::Trajectory> corrected_at_raw_stamps(const std::string& raw_log, const std::string& corrected_log);

}  // namespace driftlab::test
