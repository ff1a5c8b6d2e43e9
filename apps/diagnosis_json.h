// The JSON form of a timing diagnosis (docs/diagnosis.md lists its fields).
#pragma once

#include <nlohmann/json.hpp>

#include "analyzers/timing.h"

namespace driftlab::apps {

/// What `driftlab diagnose --json` prints: times in seconds unless the key says utime [us].
nlohmann::json to_json(const analyzers::Diagnosis& d);

}  // namespace driftlab::apps
