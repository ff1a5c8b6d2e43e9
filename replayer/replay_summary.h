// A replay's outcome as `driftlab replay` prints it: the JSON of --json and the summary lines.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "core/clock_correction.h"
#include "replayer/replayer.h"

namespace driftlab::replay {

struct ReplaySummary {
  std::vector<std::string> logs;  ///< as replayed (another tool's recording: its conversion)
  std::string out;                ///< the output log, or empty
  ReplayReport report;
  double wall_s = 0;               ///< how long the replay took [s]
  std::vector<std::string> notes;  ///< what the corrections and the modules' settings said of themselves
  ClockCorrections restamp;        ///< the corrections applied
  std::string faults_channel;      ///< where the manifest of injected faults went
};

/// --json: the counts, the replayed and wall times with the real-time factor, the channels, the corrections, the
/// module reports (runtime/module_report.h) and how many faults were injected.
nlohmann::json to_json(const ReplaySummary& s);
/// The lines: the notes, what was replayed how fast, problems met in the logs, faults injected, and each module's
/// report (with processing times when `timing`).
std::string replay_text(const ReplaySummary& s, bool timing);

}  // namespace driftlab::replay
