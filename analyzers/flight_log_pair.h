// A flight log beside a bag: a PX4 ULog and a ROS bag (MAVROS's /mavros/imu/data, ...) of the same flight given
// together (`driftlab diagnose run.mcap flight.ulg`, `driftlab import run.mcap flight.ulg -o both.lcm`) are two
// recordings on two clocks, not the parts of one split recording. Each is imported (formats/import.h), the ULog's
// clock (time since boot) is put on the bag's by its IMU against the bag's (analyzers/imu_clock_alignment.h: the
// angular speeds cross-correlated, the drift measured on long flights), and one log holds both: the bag's events
// as they are, the ULog's with their event times and header stamps on the bag's clock. ROS topic names start with
// '/', ULog topics never do, so both keep their names (flight_log.h still finds the PX4 topics); a name in both
// is refused. Thread-safety: plain functions.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/result.h"
#include "formats/import.h"

namespace driftlab::analyzers {

struct FlightLogPair {
  std::string ulog;              ///< the flight log
  std::vector<std::string> bag;  ///< the bag's files (or its folder), in the order given
};

/// The inputs as a flight log beside a bag: exactly one of them a ULog and the others a recording driftlab imports
/// (none a ULog); nullopt otherwise.
std::optional<FlightLogPair> flight_log_pair(const std::vector<std::string>& inputs);

struct PairImport {
  formats::ImportSummary summary;  ///< both imports' topics, the bag's first
  std::string alignment;           ///< one line: how the flight log was put on the bag's clock, and by how much
};

/// Imports both into out (written atomically), the flight log on the bag's clock. Problems of either import go to
/// on_problem as import_log's do. Errors: either import's, one line naming both recordings when no alignment is
/// found ("cannot put FLIGHT on BAG's clock: why") or a channel is in both.
Result<PairImport> import_flight_log_pair(const FlightLogPair& pair, const std::string& out,
                                          const std::function<void(const std::string&)>& on_problem);

/// What `driftlab import` and the conversion cache make of inputs: import_flight_log_pair() for a flight log beside
/// a bag (its alignment line in *alignment), formats::import_log() for anything else (*alignment left empty).
Result<formats::ImportSummary> import_recording(const std::vector<std::string>& inputs, const std::string& out,
                                                const std::function<void(const std::string&)>& on_problem,
                                                std::string* alignment);

}  // namespace driftlab::analyzers
