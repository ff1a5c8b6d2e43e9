// driftlab sweep SPEC -o DIR and driftlab batch diagnose|eval|report LOG... -o DIR: many runs of the existing
// commands, on a local process pool or as one Slurm job array (docs/batch.md). This file is the command line; the
// specs, points, markers, runner and executors are in batch/. Each point is this program run again with
// `sweep --point ID` (or `batch --item ID`), so a point runs the same way on a laptop and on a cluster node.
#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>

#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "batch/runner.h"
#include "batch/session.h"
#include "batch/spec.h"
#include "core/wall_clock.h"

namespace driftlab::apps {

namespace {

namespace fs = std::filesystem;
using namespace batch;

struct ExecArgs {
  std::string executor = "local";
  RunOptions run;
  bool dry_run = false;
  JsonOutput json;
};

struct SweepArgs {
  std::string spec, out, point;
  ExecArgs exec;
};

struct BatchArgs {
  std::string command, out, item, list, gt = "GROUND_TRUTH", est = "EKF_ODOM", align = "posyaw";
  std::vector<std::string> logs;
  ExecArgs exec;
};

int run_status(const std::string& dir, const JsonOutput& json) {
  auto plan = load_plan(dir);
  if (!plan) return fail(plan.error().message);
  const SweepState state = sweep_state(dir, *plan, true);
  if (json.wanted()) {
    if (!json.emit(to_json(state, dir).dump(2) + "\n")) return kExitFailure;
    if (json.print) return kExitOk;
  }
  std::fputs(state_text(state, dir).c_str(), stdout);
  return kExitOk;
}

int run_collect(const std::string& dir, bool plots) {
  auto plan = load_plan(dir);
  if (!plan) return fail(plan.error().message);
  std::vector<std::string> inputs = plan->spec.logs;
  if (!plan->spec.scenario.empty()) inputs.push_back(plan->spec.scenario);
  if (Status s = check_sweep_dir(dir, inputs); !s) return fail(s.message());
  auto page = collect(dir, *plan, plots);
  if (!page) return fail(page.error().message, kExitFailure);
  std::printf("%zu of %zu points done; table: %s/results.csv%s%s\n",
              sweep_state(dir, *plan, false).count(PointState::kDone), plan->points.size(), dir.c_str(),
              page->empty() ? "" : ", page: ", page->c_str());
  return kExitOk;
}

int run_point_command(const std::string& dir, const std::string& id) {
  auto plan = load_plan(dir);
  if (!plan) return fail(plan.error().message);
  for (const auto& p : plan->points) {
    if (p.id == id) return run_point(*plan, p, dir, {self_path()}, SystemWallClock());
  }
  return fail(dir + ": no point " + id + " in plan.json");
}

/// Runs or submits the points of plan that are not done, then (local) collects.
int execute(const std::string& dir, const Plan& plan, const ExecArgs& e, const std::string& point_flag) {
  if (e.dry_run) {
    std::fputs(dry_run_text(dir, plan).c_str(), stdout);
    return kExitOk;
  }
  RunOptions o = e.run;
  o.driftlab = self_path();
  o.point_flag = point_flag;
  o.progress = isatty(STDERR_FILENO) == 1 && !e.json.print;
  if (const char* sb = std::getenv("DRIFTLAB_SBATCH"); sb != nullptr && *sb != 0) o.sbatch = sb;
  if (e.executor == "slurm") {
    auto r = submit_to_slurm(dir, plan, o);
    if (!r) return fail(r.error().message, kExitFailure);
    const nlohmann::json j{{"job_id", r->job_id}, {"submitted", r->submitted}, {"done", r->already_done}, {"dir", dir}};
    if (!r->job_id.empty() && e.json.wanted() && !e.json.emit(j.dump() + "\n")) return kExitFailure;
    if (r->job_id.empty() || !e.json.print) std::fputs(submission_text(*r, dir, plan).c_str(), stdout);
    return kExitOk;
  }
  o.stop = stop_on_signals();
  auto run = run_locally(dir, plan, o);
  if (!run) return fail(run.error().message, kExitFailure);
  auto page = collect(dir, plan, !run->summary.interrupted);
  if (e.json.wanted() && !e.json.emit(to_json(*run, dir, plan, page ? *page : "").dump(2) + "\n")) return kExitFailure;
  if (!e.json.print) {
    std::fputs(local_run_text(*run, dir, page ? std::optional(*page) : std::nullopt).c_str(), stdout);
  }
  if (!page) return fail(page.error().message, kExitFailure);
  return run->summary.interrupted ? 130 : run->summary.failed > 0 ? kExitFailure : kExitOk;
}

void add_exec_options(CLI::App* cmd, ExecArgs& e) {
  cmd->add_option("--executor", e.executor, "Where the points run: local (a process pool here) or slurm (a job array)")
      ->capture_default_str()
      ->check(CLI::IsMember({"local", "slurm"}));
  cmd->add_option("-j,--jobs", e.run.jobs, "local: points at once (0: one per usable core)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 4096)));
  cmd->add_option("--retries", e.run.retries, "local: run a failed point again up to N times")
      ->capture_default_str()
      ->check(in_range(config::between(0, 100)));
  cmd->add_option("--max-parallel", e.run.max_parallel, "slurm: tasks of the array running at once (0: no limit)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e6)));
  cmd->add_option("--requeue", e.run.requeue, "slurm: a failed task requeues itself up to N times")
      ->capture_default_str()
      ->check(in_range(config::between(0, 100)));
  cmd->add_option(
         "--slurm-opt", e.run.slurm_options,
         "slurm: an sbatch option, passed as it is (repeatable): --partition=P, --time=1:00:00, --mem=4G, --account=A")
      ->allow_extra_args(false);
  cmd->add_flag("--dry-run", e.dry_run, "List the points (id, done or pending, values) and run nothing");
  add_json_options(cmd, &e.json, "a summary");
}

/// `status DIR` and `collect DIR` under cmd; `what` the sweep's items ("points", "logs").
void add_status_and_collect(CLI::App* cmd, const std::string& what, const std::string& collect_help, int* exit_code) {
  auto dir = std::make_shared<std::string>();
  auto json = std::make_shared<JsonOutput>();
  CLI::App* status =
      cmd->add_subcommand("status", (what == "points" ? "Points" : "Logs") +
                                        std::string(" done, running, failed and pending, and the Slurm jobs' states."));
  status->add_option("dir", *dir, "Folder of the " + std::string(cmd->get_name()))->required();
  add_json_options(status, json.get(), "the counts");
  status->callback([dir, json, exit_code] { *exit_code = run_status(*dir, *json); });
  auto cdir = std::make_shared<std::string>();
  auto no_plots = std::make_shared<bool>(false);
  CLI::App* coll = cmd->add_subcommand("collect", collect_help);
  coll->add_option("dir", *cdir, "Folder of the " + std::string(cmd->get_name()))->required();
  coll->add_flag("--no-plots", *no_plots, "Only the tables");
  coll->callback([cdir, no_plots, exit_code] { *exit_code = run_collect(*cdir, !*no_plots); });
}

int run_sweep(const SweepArgs& a) {
  if (a.out.empty()) return fail("sweep: -o DIR is required");
  if (!a.point.empty()) return run_point_command(a.out, a.point);
  if (a.spec.empty()) return fail("sweep: a SPEC.yaml is required (or --point ID, or status DIR, collect DIR)");
  auto spec = load_spec(a.spec);
  if (!spec) return fail(spec.error().message);
  if (spec->has(Stage::kReplay)) {
    if (Status s = validate_module_settings(*spec); !s) {
      return fail(s.message());
    }
  }
  std::vector<std::string> inputs = spec->logs;
  inputs.push_back(a.spec);
  if (!spec->scenario.empty()) inputs.push_back(spec->scenario);
  if (Status s = check_sweep_dir(a.out, inputs); !s) return fail(s.message());
  if (Status s = a.exec.json.check(inputs, sweep_files(a.out)); !s) return fail(s.message());
  return execute(a.out, Plan{*spec, expand(*spec)}, a.exec, "sweep --point");
}

int run_batch(const BatchArgs& a) {
  if (a.out.empty()) return fail("batch: -o DIR is required");
  if (!a.item.empty()) return run_point_command(a.out, a.item);
  if (a.command.empty()) return fail("batch: a command is required: diagnose, eval or report (or --item ID)");
  auto logs = batch_logs(a.logs, a.list);
  if (!logs) return fail(logs.error().message);
  auto spec = batch_spec(a.command, *logs);
  if (!spec) return fail(spec.error().message);
  spec->gt_channel = a.gt;
  spec->est_channel = a.est;
  spec->align = a.align;
  if (Status s = check_sweep_dir(a.out, spec->logs); !s) return fail(s.message());
  if (Status s = a.exec.json.check(spec->logs, sweep_files(a.out)); !s) return fail(s.message());
  return execute(a.out, Plan{*spec, expand(*spec)}, a.exec, "batch --item");
}

}  // namespace

void add_sweep_command(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<SweepArgs>();
  CLI::App* cmd = app.add_subcommand("sweep", "Run a pipeline (sim, replay, diagnose, eval) over a grid of parameters and seeds, here or on Slurm.");
  cmd->footer(
      "SPEC (YAML, docs/batch.md) names a scenario or logs, the parameters to vary (seed, duration, restamp,\n"
      "faults.CHANNEL.FIELD, MODULE.KEY; lists or {from, to, step} grids) and the pipeline. Each point runs the real\n"
      "subcommands in DIR/points/ID; a finished point is never run again, so running the same command again resumes.\n"
      "The table (DIR/results.csv, results.json) and a page of plots (DIR/index.html) are written at the end (local)\n"
      "or by `sweep collect DIR`. --executor slurm submits one job array and returns its job id at once; `sweep\n"
      "status DIR` and `sweep collect DIR` work from any node that sees DIR (a shared filesystem).");
  cmd->add_option("spec", a->spec, "Sweep spec (YAML)");
  add_config_help(*cmd, [] { std::printf("## Sweep spec: `driftlab sweep SPEC`\n\n%s", spec_reference().c_str()); });
  cmd->add_option("-o,--out", a->out, "Folder of the sweep (points, table, page)");
  cmd->add_option("--point", a->point, "Run one point of the sweep in DIR (what each task runs)");
  add_exec_options(cmd, a->exec);
  add_status_and_collect(cmd, "points", "Merge the finished points into one table (CSV, JSON) and a page of plots.",
                         exit_code);
  cmd->callback([a, cmd, exit_code] {
    if (!cmd->get_subcommands().empty()) return;
    *exit_code = run_sweep(*a);
  });
}

void add_batch_command(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<BatchArgs>();
  CLI::App* cmd = app.add_subcommand("batch", "Diagnose, score or report many logs, here or on Slurm, and rank them.");
  cmd->fallthrough();  // -o DIR and the executor options may follow the command's logs
  cmd->footer(
      "LOG... are paths, patterns (quoted: expanded here) or @FILE (one path a line). One result per log in\n"
      "DIR/points/ID; a finished log is never run again. The table (DIR/results.csv, results.json) ranks the logs\n"
      "worst first (streams with faults, then warnings, then drops, then ATE) and DIR/index.html shows it with each\n"
      "log's worst stream. Executors, status and collect as for `driftlab sweep` (docs/batch.md).");
  cmd->add_option("-o,--out", a->out, "Folder of the batch");
  cmd->add_option("--item", a->item, "Run one item of the batch in DIR (what each task runs)");
  add_exec_options(cmd, a->exec);
  for (const char* word : {"diagnose", "eval", "report"}) {
    CLI::App* sub = cmd->add_subcommand(word, std::string("driftlab ") + word + " of every log");
    sub->add_option("logs", a->logs, "Logs, patterns or @FILE")->required();
    sub->add_option("--list", a->list, "A file of log paths, one a line");
    if (std::string(word) == "eval") {
      sub->add_option("--gt", a->gt, "Ground-truth channel of each log")->capture_default_str();
      sub->add_option("--est", a->est, "Estimate channel of each log")->capture_default_str();
      sub->add_option("--align", a->align, "Alignment (as driftlab eval)")->capture_default_str()
          ->check(CLI::IsMember({"none", "se3", "sim3", "posyaw"}));
    }
    sub->callback([a, word, exit_code] {
      a->command = word;
      *exit_code = run_batch(*a);
    });
  }
  add_status_and_collect(cmd, "logs", "Merge the finished logs into one ranked table and page.", exit_code);
  cmd->callback([a, cmd, exit_code] {
    if (!cmd->get_subcommands().empty()) return;
    *exit_code = run_batch(*a);
  });
}

}  // namespace driftlab::apps
