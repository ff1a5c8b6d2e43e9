// driftlab eval --gt SRC --est SRC: trajectory error (ATE, RPE, drift) against ground truth, equal to evo.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>

#include "analyzers/arm_tracking.h"
#include "analyzers/evaluate.h"
#include "analyzers/evaluate_text.h"
#include "analyzers/trajectory_io.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/log_reader.h"
#include "core/same_file.h"
#include "recordings/log_input.h"

namespace driftlab::apps {
namespace {

using namespace analyzers;

/// --offset [s]: up to centuries, so that an estimate stamped since boot meets a reference stamped since the epoch.
constexpr config::Range kOffsetRange = config::between(-1e10, 1e10);

struct EvalOptions {
  EvaluateOptions options;   ///< gt and est as given: read from their conversions when another tool's recordings
  std::string offset = "0";  // seconds, or "auto"
  std::string arm;
  ArmTrackingOptions arm_options;
  JsonOutput json;
};

/// A source (LOG:CHANNEL, or a trajectory file) checked: a log must hold events, and a log given without its
/// channel is named as such (rather than read as a TUM file that is "not a number" on line 1).
Status check_source(const std::string& src, const char* option) {
  std::string log, channel;
  if (split_log_channel(src, &log, &channel)) return check_event_log(log);
  if (check_event_log(src).ok()) {
    return Error{src + ": an LCM event log: name the channel, as " + option + " " + src + ":CHANNEL"};
  }
  return {};
}

/// driftlab eval --arm LOG: the arm's tracking error.
int run_arm_eval(const EvalOptions& o) {
  if (!o.options.gt.empty() || !o.options.est.empty() || !o.options.relations.empty()) {
    return fail("--arm evaluates an arm's tracking in one log: give it without --gt, --est and --relations");
  }
  if (Status s = refuse_same_file(o.json.file, {o.arm}, "--json-out"); !s) return fail(s.message());
  auto log = recordings::event_log_for(o.arm);  // another tool's recording: its cached conversion
  if (!log) return fail(log.error().message, exit_code_for(log.error()));
  auto a = evaluate_arm(*log, o.arm_options);
  if (!a) return fail(a.error().message);
  a->log = o.arm;
  if (!o.json.print) std::fputs(arm_tracking_text(*a).c_str(), stdout);
  nlohmann::json j = {{"arm", to_json(*a)}, {"notes", nlohmann::json::array()}};
  if (o.json.wanted() && !o.json.emit(j.dump(2) + "\n")) return kExitFailure;
  return kExitOk;
}

int run_eval(const EvalOptions& e) {
  if (!e.arm.empty()) return run_arm_eval(e);
  const EvaluateOptions& o = e.options;
  if (o.gt.empty() && o.relations.empty()) {
    return fail(
        "eval needs --gt (ATE, RPE and drift against a reference), --relations (the SLAM benchmark's relation "
        "error), or both; or --arm LOG (an arm's tracking error)");
  }
  if (o.est.empty()) return fail("--est is required with --gt and --relations");
  // An output over any input is refused before anything is read or converted.
  std::vector<std::string> inputs;
  for (const auto* src : {&o.gt, &o.est, &o.odometry}) {
    std::string log, channel;
    inputs.push_back(split_log_channel(*src, &log, &channel) ? log : *src);
  }
  for (const auto* file : {&o.relations, &o.gt_times, &o.est_times}) inputs.push_back(*file);
  if (Status s = refuse_same_file(e.json.file, inputs, "--json-out"); !s) return fail(s.message());
  // LOG:CHANNEL of another tool's recording: read from its cached conversion (the output names the source given).
  EvaluateOptions options = o;
  options.gt_name = o.gt;
  options.est_name = o.est;
  for (std::string* src : {&options.gt, &options.est}) {
    if (src->empty()) continue;
    auto converted = recordings::log_channel_for(*src);
    if (!converted) return fail(converted.error().message, exit_code_for(converted.error()));
    *src = *converted;
  }
  for (const auto& [src, option] :
       {std::pair{options.gt, "--gt"}, {options.est, "--est"}, {options.odometry, "--relations-odometry"}}) {
    if (src.empty()) continue;
    if (Status s = check_source(src, option); !s) return fail(s.message());
  }
  options.offset = e.offset == "auto" ? std::nullopt : std::optional(std::strtod(e.offset.c_str(), nullptr));
  options.on_note = [](const std::string& note) { std::fprintf(stderr, "driftlab: note: %s\n", note.c_str()); };
  auto ev = evaluate(options);
  if (!ev) return fail(ev.error().message);
  if (!e.json.print) std::fputs(evaluation_text(*ev).c_str(), stdout);
  if (e.json.wanted() && !e.json.emit(to_json(*ev).dump(2) + "\n")) return kExitFailure;
  return kExitOk;
}

}  // namespace

void add_eval_command(CLI::App& app, int* exit_code) {
  auto o = std::make_shared<EvalOptions>();
  CLI::App* cmd = app.add_subcommand(
      "eval",
      "Trajectory error of an estimate: ATE, RPE and drift against ground truth with evo's semantics, the SLAM "
      "benchmark's relation error, and an arm's tracking error.");
  cmd->footer(
      "SRC is LOG:CHANNEL (a driftlab.pose_t, odometry_t or trajectory_setpoint_t channel, stamped with\n"
      "header.utime; a setpoint is its position, level, turned by its yaw) or a file\n"
      "in one of the formats evo reads: TUM (t x y z qx qy qz qw), KITTI (12 numbers a line: a 3x4 pose matrix;\n"
      "stamps from --gt-times/--est-times, else compared pose for pose) or EuRoC ground truth CSV (#timestamp [ns],\n"
      "x, y, z, qw, qx, qy, qz, ...), told apart by their first line unless --gt-format/--est-format says. Poses\n"
      "out of stamp order are sorted; non-finite or non-unit poses are refused. Matching: for each stamp of the\n"
      "trajectory with fewer poses, the nearest stamp of the other within --max-dt (as evo), or with --interpolate\n"
      "the reference interpolated at each estimate stamp. --offset auto finds the estimate's time offset by\n"
      "cross-correlating the two motions (speed, angular speed) and applies it when its confidence (peak\n"
      "correlation) is 0.8 or more. RPE pairs as evo chooses them: along the estimate unless\n"
      "--pairs-from-reference. --relations: Kuemmerle et al.'s error of the estimate's relative poses between the\n"
      "stamps of each relation: mean, std and max of the absolute and squared translation and rotation errors, as\n"
      "the benchmark's metric evaluator reports them. --arm LOG: per commanded joint, the RMS and max of\n"
      "|measured - reference| at the joint states' stamps (reference: the commands' plans at their stamps, or\n"
      "the controller's desired state), the positions and speeds reached against the URDF's limits, and the end\n"
      "effector's position and angle error: FK (the URDF the log carries) of the reference joints against its\n"
      "ground truth, in the arm base's frame; its true motion above --arm-cutoff is reported as oscillation. See\n"
      "docs/trajectory-evaluation.md.");
  EvaluateOptions& ev = o->options;
  const auto formats = {TrajectoryFormat::kAuto, TrajectoryFormat::kTum, TrajectoryFormat::kKitti,
                        TrajectoryFormat::kEuroc};
  cmd->add_option("--gt", ev.gt, "Reference (ground truth): LOG:CHANNEL or a TUM, KITTI or EuRoC file");
  cmd->add_option("--est", ev.est, "Estimate: LOG:CHANNEL or a TUM, KITTI or EuRoC file");
  add_choice(cmd, "--gt-format", &ev.gt_format, formats, "Format of a --gt file");
  add_choice(cmd, "--est-format", &ev.est_format, formats, "Format of an --est file");
  cmd->add_option("--gt-times", ev.gt_times, "With KITTI --gt: its stamps, one a line [s]");
  cmd->add_option("--est-times", ev.est_times, "With KITTI --est: its stamps, one a line [s]");
  add_choice(
      cmd, "--align", &ev.align,
      {AlignmentType::kNone, AlignmentType::kSe3, AlignmentType::kSim3, AlignmentType::kPosYaw, AlignmentType::kOrigin},
      "Alignment of the estimate onto the reference (Umeyama; posyaw: x, y, z, yaw; origin: the first "
      "matched poses made equal, evo's --align_origin)");
  cmd->add_option("--max-dt", ev.max_dt, "Largest stamp difference of a matched pair [s]")
      ->capture_default_str()
      ->check(in_range(config::between(0, 86400), "s"));
  cmd->add_option("--offset", o->offset, "Added to the estimate's stamps before matching [s], or auto: from the motion")
      ->capture_default_str()
      ->check(CLI::Validator(
          [seconds = in_range(kOffsetRange, "s")](std::string& v) -> std::string {
            if (v == "auto") return "";
            char* end = nullptr;
            std::strtod(v.c_str(), &end);
            if (end == v.c_str() || *end != '\0') return "must be a number of seconds or auto, got " + v;
            return seconds(v);
          },
          interval(kOffsetRange) + "|auto", kRangeCheck));
  cmd->add_flag("--interpolate", ev.interpolate, "Interpolate the reference at the estimate's stamps");
  cmd->add_option("--max-gap", ev.max_gap,
                  "With --interpolate: largest gap between reference poses to interpolate across [s]")
      ->capture_default_str()
      ->check(in_range(config::above(0, 86400), "s"));
  cmd->add_option("--delta", ev.rpe.delta, "RPE: distance between the poses of a pair")
      ->capture_default_str()
      ->check(in_range(config::above(0, 1e9)));
  add_choice(cmd, "--delta-unit", &ev.rpe.unit,
             {DeltaUnit::kFrames, DeltaUnit::kMeters, DeltaUnit::kSeconds, DeltaUnit::kDegrees, DeltaUnit::kRadians},
             "RPE: unit of --delta (s: elapsed time, not in evo)");
  cmd->add_flag("--all-pairs", ev.rpe.all_pairs, "RPE: every pair --delta apart, not consecutive ones");
  cmd->add_flag("--pairs-from-reference", ev.rpe.pairs_from_reference,
                "RPE: choose the pairs along the reference, not the estimate (evo's --pairs_from_reference)");
  cmd->add_option("--delta-tol", ev.rpe.delta_tol,
                  "RPE with --all-pairs in m, s, deg or rad: accepted miss of --delta, relative (evo's rel_delta_tol)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1)));
  cmd->add_option("--segments", ev.segments,
                  "Drift: segment lengths [m], comma separated (default: 10..50% of the reference path)")
      ->delimiter(',')
      ->check(in_range(config::above(0, 1e7), "m"));
  cmd->add_option("--segment-step", ev.segment_step, "Drift: a segment starts at every N-th matched pose")
      ->capture_default_str()
      ->check(in_range(config::between(1, 1e6)));
  cmd->add_option("--relations", ev.relations,
                  "Relations file (t1 t2 x y z roll pitch yaw a line): the SLAM benchmark's relation error");
  cmd->add_option("--relations-max-dt", ev.relations_max_dt,
                  "With --relations: largest stamp difference of a relation and the pose it takes [s]")
      ->capture_default_str()
      ->check(in_range(config::between(0, 86400), "s"));
  cmd->add_option("--relations-odometry", ev.odometry,
                  "With --relations: raw odometry (LOG:CHANNEL or TUM file) to carry poses to stamps without one");
  cmd->add_option("--arm", o->arm,
                  "An arm's tracking error in LOG: per joint and at the end effector against ground truth");
  add_choice(cmd, "--arm-reference", &o->arm_options.reference, {ArmReference::kCommanded, ArmReference::kDesired},
             "With --arm: compare the joints with the commands' plans or the controller's desired state");
  cmd->add_option("--arm-command", o->arm_options.command_channel,
                  "With --arm: the channel of joint trajectory commands (default: the one with the most)");
  cmd->add_option("--arm-ee", o->arm_options.ee_channel,
                  "With --arm: the end effector's ground truth channel (default: found)");
  cmd->add_option("--arm-base", o->arm_options.base_channel,
                  "With --arm: the arm base's ground truth channel (default: found)");
  cmd->add_option("--arm-cutoff", o->arm_options.oscillation_cutoff_hz,
                  "With --arm: the end effector's motion above this frequency is reported as oscillation [Hz]")
      ->capture_default_str()
      ->check(in_range(config::above(0, 50), "Hz"));
  add_json_options(cmd, &o->json, "the results");
  cmd->callback([o, exit_code] {
    const RpeOptions& rpe = o->options.rpe;
    if (rpe.unit == DeltaUnit::kFrames && std::floor(rpe.delta) != rpe.delta) {
      *exit_code = fail("--delta must be a whole number of frames, got " + short_number(rpe.delta));
      return;
    }
    // An angle between two rotations lies in [0, 180] degrees (evo refuses other deltas too).
    const bool deg = rpe.unit == DeltaUnit::kDegrees;
    if ((deg && rpe.delta > 180) || (rpe.unit == DeltaUnit::kRadians && rpe.delta > M_PI)) {
      *exit_code = fail(std::string("--delta in ") + to_string(rpe.unit) + " must be at most " + (deg ? "180" : "pi") +
                        " (the largest angle between two rotations), got " + short_number(rpe.delta));
      return;
    }
    *exit_code = run_eval(*o);
  });
}

}  // namespace driftlab::apps
