// A sweep's folder (docs/batch.md): DIR/plan.json (the resolved spec and its points), DIR/points/ID/ (one folder
// per point: its inputs, the stages' outputs and logs), and the markers that say where a point is:
//   DIR/points/ID/result.json   the done-marker: the point's row, written atomically as the very last step
//   DIR/points/ID/failed.json   the last attempt failed (stage, exit code, its last error line)
//   DIR/points/ID/running.json  an attempt is under way (host, pid, start); read on that host with the pid gone,
//                               the point counts as failed (killed)
//   DIR/points/ID/attempts      how many attempts were started
// Every file is written beside its target and renamed, so a reader on another node sees whole files only (a shared
// filesystem is the assumption). Thread-safety: functions on paths; one writer per point at a time.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "batch/plan.h"
#include "core/result.h"

namespace driftlab::batch {

/// This machine's host name (as running.json records it).
std::string host_name();

/// Reads a JSON file; the error names it.
Result<nlohmann::json> read_json_file(const std::string& path);

std::string plan_path(const std::string& dir);
std::string point_dir(const std::string& dir, const std::string& id);
std::string result_path(const std::string& dir, const std::string& id);

Status save_plan(const std::string& dir, const Plan& plan);
Result<Plan> load_plan(const std::string& dir);

enum class PointState { kPending, kRunning, kDone, kFailed };
const char* state_name(PointState s);

struct PointStatus {
  std::string id;
  PointState state = PointState::kPending;
  int attempts = 0;
  nlohmann::json record;  ///< result.json (done), failed.json (failed), running.json (running), else null
};

PointStatus point_status(const std::string& dir, const std::string& id);
bool is_done(const std::string& dir, const std::string& id);
/// Counts the attempt (DIR/points/ID/attempts) and returns its number (1 for the first).
int count_attempt(const std::string& dir, const std::string& id);

/// The merged table of a sweep: one row per point of the plan, in the plan's order, with its parameters, status,
/// attempts and (done points) metrics and stage times. The columns: id, status, attempts, every varied parameter,
/// then the metric columns the done rows have (sorted), seconds.* last.
struct Table {
  std::vector<std::string> columns;
  nlohmann::json rows = nlohmann::json::array();  ///< objects keyed by column
};
Table merge_results(const std::string& dir, const Plan& plan);
std::string table_csv(const Table& t);
/// The rows ordered worst first for a batch: logs with faults before warnings, then more flagged streams, then
/// more drops (and, with eval, the larger ATE).
nlohmann::json rank_batch(const Table& t);

}  // namespace driftlab::batch
