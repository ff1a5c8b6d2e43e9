// `driftlab demo`'s two stories as data: the stages (each a driftlab subcommand, with the file its output is kept
// in), the report drawn after them, and the summary read back from the stages' files by the libraries that wrote
// them. The program runs the stages and draws the report (apps/demo_main.cc); tests read a story's plan and a
// summary without running either.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "analyzers/diagnosis_json.h"
#include "core/result.h"

namespace driftlab::batch {

struct DemoSettings {
  std::string scenario;               ///< empty: the story's own (the default indoor scenario; drone_timebase)
  std::string out;                    ///< the folder every stage writes into
  double duration = 120;              ///< simulated seconds (the ground story; the drone's scenarios say theirs)
  int64_t seed = -1;                  ///< -1: the scenario's
  std::string estimate = "EKF_ODOM";  ///< the replays' channel scored against ground truth (the ground story)
  double estimator_window = 0;  ///< the estimator's window_s (0: late measurements dropped, as robot_localization)
  bool drone = false;           ///< the drone's story (issue 16) instead of the ground robot's
};

/// One stage: a driftlab subcommand (args[0] is the program), its standard output kept in `stdout_file`.
struct DemoStage {
  std::string what;  ///< "replaying as logged"
  std::vector<std::string> args;
  std::string stdout_file;
};

struct DemoPlan {
  std::vector<DemoStage> stages;
  /// The report drawn after the stages: the recording first, then what was made from it.
  std::vector<std::string> report_logs;
  std::string report_dir, diagnosis, title;
  std::vector<std::string> evals;  ///< the evaluations the report tabulates
  /// `driftlab report` with the arguments above: what the demo prints for the report it draws in-process.
  std::vector<std::string> report_command;
};

/// The story's stages, `exe` being the driftlab program to run. The ground story's module settings are written
/// into the folder (replay.yaml), which must exist. Errors: that file could not be written.
Result<DemoPlan> plan_demo(const DemoSettings& settings, const std::string& exe);

/// How a stage ran: its subcommand, its exit code, the last line it wrote on stderr, how long it took [s].
struct StageRun {
  std::string name;
  int code = 0;
  std::string said;
  double seconds = 0;
};
/// Runs the plan's stages in turn until one fails, each one's standard output kept in its file and its errors in
/// DIR/stage.err (removed at the end), so that a failed stage's last line can be said; a failed stage's output is
/// removed (empty or cut short). `around(i, run)` is called with each stage's index and a function that runs it:
/// to print the stage, to draw a progress line while it runs. The last stage returned failed when its code is not 0.
std::vector<StageRun> run_stages(const DemoPlan& plan, const std::string& dir,
                                 const std::function<void(size_t, const std::function<void()>&)>& around);
/// A stage's command line as one would type it: "driftlab sim ...".
std::string command_text(const std::vector<std::string>& args);
/// The stages' names and times, as `demo --json` gives them.
nlohmann::json to_json(const std::vector<StageRun>& stages);

/// What the drone's estimator did with its IMU, from the last driftlab.estimator_status_t of a log: rejected
/// (stale, future or late) of all it received, and how many of the rejections were from the future.
struct ImuRejections {
  int64_t rejected = 0, received = 0, future = 0;
  double percent() const;  ///< rejected of received, 0 when none was received
};
ImuRejections imu_rejections(const std::string& log);

/// The story's outcome, read from the stages' files.
struct DemoSummary {
  analyzers::DiagnosisSummary diagnosis;
  // The ground story: the estimate's ATE [m] and the late measurements the estimator dropped, as logged and with
  // the clocks corrected.
  double ate_before = 0, ate_after = 0;
  int64_t late_rejected_before = 0, late_rejected_after = 0;
  // The drone's story, by flight ("clean", "logged", "restamped"): the setpoint tracking's and the estimate's ATE
  // RMSE [m], and the IMU samples its estimator rejected as logged and flown again.
  std::map<std::string, double> tracking_m, estimate_ate_m;
  ImuRejections imu_logged, imu_restamped;
};
/// Errors: a stage's file is not what that stage writes (one line naming it).
Result<DemoSummary> read_demo(const DemoSettings& settings, const DemoPlan& plan);

/// The summary as `driftlab demo --json` prints it (with the report's path, the folder and the stages added by the
/// program).
nlohmann::json to_json(const DemoSettings& settings, const DemoSummary& summary);
/// The summary's lines as the demo ends with them, but the report's path: the worst stream, the clocks ahead, then
/// the drops and the ATE before and after (the ground story) or the IMU rejections and the flights' errors (the
/// drone's).
std::string demo_text(const DemoSettings& settings, const DemoSummary& summary);

}  // namespace driftlab::batch
