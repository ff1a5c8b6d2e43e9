// Runs one point of a sweep or batch: the real driftlab subcommands, each a child process, in the point's folder
// (docs/batch.md). What each stage printed stays beside its output (STAGE.json or STAGE.txt, STAGE.err). The
// done-marker (result.json: parameters, metrics, stage times) is written atomically as the last step; a point
// already done returns at once. Thread-safety: one point per process at a time (it handles SIGINT and SIGTERM).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "batch/plan.h"
#include "core/wall_clock.h"

namespace driftlab::batch {

struct RunnerOptions {
  std::string driftlab;  ///< the driftlab program the stages run
};

/// Exit codes of run_point.
inline constexpr int kPointDone = 0;
inline constexpr int kPointFailed = 1;
inline constexpr int kPointInterrupted = 130;

/// Runs the point in dir/points/ID; prints one line on stderr when a stage fails (which stage, its exit code and
/// its last error line), also kept in failed.json. SIGINT or SIGTERM stops the stage under way and leaves the
/// point not done (kPointInterrupted). `clock` dates the attempt (running.json's "started").
int run_point(const Plan& plan, const Point& point, const std::string& dir, const RunnerOptions& options,
              const WallClock& clock);

/// The metrics of a finished point from its stages' JSON in folder pdir (ate_rmse, rpe_rmse, drops, offsets found,
/// the worst stream, the estimator's late measurements ...); exposed for tests.
nlohmann::json point_metrics(const Plan& plan, const std::string& pdir);

}  // namespace driftlab::batch
