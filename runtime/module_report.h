// A run's module reports (runtime/module_host.h's ModuleReport) as `driftlab replay`, `driftlab run` and the
// closed-loop replay print them: the JSON under "modules" and the lines of the text summary; and that JSON read back
// (the demo and the batches read a replay's).
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/result.h"
#include "runtime/live_runner.h"
#include "runtime/module_host.h"

namespace driftlab::runtime {

nlohmann::json to_json(const std::vector<ModuleReport>& reports);
/// The reports under "modules" of what `replay --json` or `run --json` printed. Errors: one line saying what is
/// missing or of the wrong type.
Result<std::vector<ModuleReport>> module_reports_from_json(const nlohmann::json& run);

/// A module's metric by name (ModuleCounters::metrics), when it reported it.
std::optional<double> metric(const ModuleReport& report, std::string_view name);

/// The text summary's lines of each module: its counts (with processing times when `timing`), its metrics, its
/// warnings.
std::string module_report_text(const std::vector<ModuleReport>& reports, bool timing);

/// `driftlab run --json`: the URL, the output log, the counts, the notes and the module reports.
nlohmann::json to_json(const LiveOptions& options, const LiveReport& report, const std::vector<std::string>& notes);
/// The lines of `driftlab run`: the notes, how long it ran on which URL and what it handled, the module reports.
std::string live_text(const LiveOptions& options, const LiveReport& report, const std::vector<std::string>& notes);

}  // namespace driftlab::runtime
