// A simulation's outcome as `driftlab sim` prints it, and a closed-loop run's as `driftlab replay --closed-loop`
// prints it: the JSON of --json and the summary lines.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "sim/simulator.h"

namespace driftlab::sim {

struct SimRun {
  std::string scenario_path, scenario_name;
  bool ground_robot = true;  ///< a robot that drives a route (its distance, laps and odometry error are said)
  std::string out;           ///< the log written
  SimReport report;
  double wall_s = 0;  ///< how long the run took [s]
};

/// `sim --json`: the log, its fault manifest, the simulated and wall times with the real-time factor, the messages
/// per channel, the distance driven, the laps, the odometry's error, the run's notes.
nlohmann::json to_json(const SimRun& run);
/// The lines of `driftlab sim`: what was simulated how fast, the messages per channel, the drive, the notes, the
/// faults injected.
std::string sim_run_text(const SimRun& run);

/// The simulation that made a log, run again with corrections applied where its messages are received on board.
struct ClosedLoopRun {
  std::string log;                 ///< the log the run repeats
  SimRun run;                      ///< the new run
  ReceiveCorrections corrections;  ///< what was applied
  std::vector<std::string> notes;  ///< where the corrections came from, and those left out
};

/// `replay --closed-loop --json`.
nlohmann::json to_json(const ClosedLoopRun& closed);
/// The lines of `driftlab replay --closed-loop`: the notes, what ran, the run's own notes.
std::string closed_loop_text(const ClosedLoopRun& closed);

}  // namespace driftlab::sim
