// The JSON form of a timing diagnosis (docs/diagnosis.md lists its fields).
#pragma once

#include <nlohmann/json.hpp>

#include "analyzers/timing.h"

namespace driftlab::apps {

/// What `driftlab diagnose --json` prints: times in seconds unless the key says utime [us].
nlohmann::json to_json(const analyzers::Diagnosis& d);

/// The headline of a diagnosis (as to_json gives it), shared by the report page and the demo's summary:
/// `worst_stream` ({name, verdict, reasons, causes}, or null when nothing was flagged: faults before warnings, among
/// them the deepest first cause: a clock, then a late stream or loop, loss, undecodable data, a symptom; then the
/// most reasons), `clocks_ahead_s` (channel -> offset,
/// clocks ahead by 1 ms or more; one behind cannot be told from latency in one log) and `drops` (channel -> count).
/// Throws nlohmann::json::exception when the JSON is not a diagnosis.
nlohmann::json diagnosis_summary(const nlohmann::json& diagnosis);

}  // namespace driftlab::apps
