// What `driftlab sweep` and `driftlab batch` do with a sweep's folder (docs/batch.md), beside its points and
// executors: the folder checked before anything is written, a batch's logs expanded, the pending points run here or
// submitted to Slurm, the finished ones merged into tables, and the folder's state counted. The command line parses
// options and prints what these return; the tests call them. Thread-safety: functions on paths.
#pragma once

#include <atomic>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "batch/executor.h"
#include "batch/plan.h"
#include "batch/store.h"
#include "core/result.h"

namespace driftlab::batch {

/// The files a sweep or batch writes at the top of its folder: plan.json, results.csv, results.json, index.html.
std::vector<std::string> sweep_files(const std::string& dir);

/// A sweep's or batch's folder -o DIR, checked before anything is written: DIR is a folder or absent, not an
/// input and not inside an input folder (a ROS 2 bag); each file written at its top (sweep_files) is a regular
/// file or absent and not an input; and no input lies in DIR/points, where the points' folders are made and
/// cleared. `inputs`: the spec, its scenario and its logs.
Status check_sweep_dir(const std::string& dir, const std::vector<std::string>& inputs);

/// A batch's logs: each item a path, a pattern (expanded here: quoted, or the shell found no match) or @FILE (a
/// list, one path a line, # comments, relative to the list); `list` is one more such file ("" for none).
/// Errors: one line naming the pattern that matches nothing or the list and its problem.
Result<std::vector<std::string>> batch_logs(const std::vector<std::string>& items, const std::string& list);

/// Writes DIR/results.csv and DIR/results.json (the merged table, the varied keys, the stages and, for logs, the
/// ranking worst first). Returns results.json's path.
Result<std::string> write_tables(const std::string& dir, const Plan& plan);

/// `sweep collect`: the tables (write_tables) and, with `plots`, the page drawn by sweep_page.py (matplotlib).
/// Returns the page's path, or "" without plots.
Result<std::string> collect(const std::string& dir, const Plan& plan, bool plots);

/// Where the points of a sweep stand, and its Slurm jobs'.
struct SweepState {
  size_t points = 0;
  std::map<PointState, size_t> by_state;
  std::vector<PointStatus> failed;
  std::vector<std::string> slurm_jobs;                           ///< submitted for the folder, oldest first
  std::vector<std::pair<std::string, std::string>> slurm_tasks;  ///< "ID STATE" still known to squeue
  size_t count(PointState s) const { return by_state.count(s) != 0 ? by_state.at(s) : 0; }
};
/// The points' states; with_slurm also asks squeue about the folder's jobs.
SweepState sweep_state(const std::string& dir, const Plan& plan, bool with_slurm);
/// What `sweep status --json` prints.
nlohmann::json to_json(const SweepState& s, const std::string& dir);
/// What `sweep status` prints: the counts, each failed point with its error, the Slurm jobs' states.
std::string state_text(const SweepState& s, const std::string& dir);

/// The points not done yet, in the plan's order.
std::vector<std::string> pending_points(const std::string& dir, const Plan& plan);
/// `--dry-run`: a line per point: its id, done or pending, its values.
std::string dry_run_text(const std::string& dir, const Plan& plan);

/// Where and how the pending points run.
struct RunOptions {
  std::string driftlab;                     ///< this program, which runs each point as `POINT_FLAG ID -o DIR`
  std::string point_flag;                   ///< "sweep --point" or "batch --item"
  int jobs = 0, retries = 0;                ///< local (executor.h's LocalOptions)
  bool progress = false;                    ///< local: a progress bar on stderr
  const std::atomic<bool>* stop = nullptr;  ///< local: set to stop (a signal)
  int max_parallel = 0, requeue = 2;        ///< slurm (SlurmOptions)
  std::vector<std::string> slurm_options;
  std::string sbatch = "sbatch";
};

/// The points of plan not done, run here on a process pool after saving the plan. The summary, the wall time and
/// the processes used at once.
struct LocalRun {
  ExecutionSummary summary;
  size_t already_done = 0;
  double wall_s = 0;
  int jobs = 0;
};
Result<LocalRun> run_locally(const std::string& dir, const Plan& plan, const RunOptions& o);
/// What a local run prints with --json: the counts, the time, the table and the page (when drawn: `page`).
nlohmann::json to_json(const LocalRun& run, const std::string& dir, const Plan& plan, const std::string& page);
/// Its lines: what ran, how long, what failed (and how to resume when interrupted), and where the table and the
/// page ("": not drawn) are, unless `page` is absent (collecting failed).
std::string local_run_text(const LocalRun& run, const std::string& dir, const std::optional<std::string>& page);

/// The points of plan not done, submitted as one Slurm job array after saving the plan; job_id is empty when
/// every point was done (nothing submitted). The job's name is driftlab-NAME with what Slurm would not take as _.
struct Submission {
  std::string job_id;
  size_t submitted = 0, already_done = 0;
};
Result<Submission> submit_to_slurm(const std::string& dir, const Plan& plan, const RunOptions& o);
/// Its line: the job's id and how to follow it, or that nothing was left to submit.
std::string submission_text(const Submission& s, const std::string& dir, const Plan& plan);

}  // namespace driftlab::batch
