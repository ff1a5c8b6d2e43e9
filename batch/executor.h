// Where the points of a sweep or batch run, behind one interface (docs/batch.md): a pool of processes on this
// machine, or one Slurm job array. Either way each point is one run of `driftlab sweep --point ID -o DIR` (or
// `batch --item`), so a point runs the same code wherever it runs. No scheduler of our own: the local pool only
// keeps N processes busy, Slurm does the rest. Thread-safety: an executor is used from one thread.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab::batch {

struct ExecutionSummary {
  size_t done = 0;         ///< finished in this run
  size_t failed = 0;       ///< failed every attempt
  size_t not_started = 0;  ///< left when stopped
  bool interrupted = false;
  std::string job_id;      ///< Slurm: the array's job id (the run goes on after submit returns)
};

class Executor {
 public:
  virtual ~Executor() = default;
  /// Runs (local) or submits (slurm) the points `ids` of the sweep in `dir`. Errors are one line.
  virtual Result<ExecutionSummary> execute(const std::string& dir, const std::vector<std::string>& ids) = 0;
};

/// The command that runs one point: argv for its id.
using PointCommand = std::function<std::vector<std::string>(const std::string& id)>;

struct LocalOptions {
  int jobs = 0;        ///< processes at once; 0: the cores this process may use
  int retries = 0;     ///< a failed point is run again up to this many times
  bool progress = false;  ///< draw a progress bar on stderr (a terminal)
  PointCommand command;
  /// Set from a signal handler to stop: no new point starts, the running ones get SIGTERM and are awaited, and
  /// the finished ones are kept.
  const std::atomic<bool>* stop = nullptr;
};
std::unique_ptr<Executor> make_local_executor(LocalOptions options);

struct SlurmOptions {
  std::string driftlab;    ///< absolute path of driftlab, as the nodes see it
  std::string point_flag;  ///< "sweep --point" or "batch --item": the words before ID
  std::string job_name = "driftlab";
  int max_parallel = 0;    ///< the array's concurrency limit (--array=0-N%LIMIT); 0: none
  int requeue = 2;         ///< a failed task requeues itself (scontrol requeue) up to this many times
  std::vector<std::string> slurm_options;  ///< passed to sbatch as they are (--partition=..., --time=...)
  std::string sbatch = "sbatch";
};
std::unique_ptr<Executor> make_slurm_executor(SlurmOptions options);

/// The CPUs this process may run on (sched_getaffinity), at least 1.
int usable_cpus();

/// The Slurm job ids submitted for the sweep in dir (DIR/slurm/jobs), oldest first.
std::vector<std::string> slurm_jobs(const std::string& dir);

/// "ID STATE" of each task of those jobs still known to squeue (empty when squeue is missing or knows none).
std::vector<std::pair<std::string, std::string>> slurm_queue(const std::vector<std::string>& jobs);

}  // namespace driftlab::batch
