// driftlab eval --gt SRC --est SRC: trajectory error (ATE, RPE, drift) against ground truth, equal to evo.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <future>
#include <memory>

#include "analyzers/trajectory.h"
#include "analyzers/trajectory_io.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/log_reader.h"
#include "core/same_file.h"

namespace driftlab::apps {
namespace {

using namespace analyzers;

struct EvalOptions {
  std::string gt, est;
  std::string align = "none";
  double max_dt = 0.01;
  double offset = 0.0;
  bool interpolate = false;
  double max_gap = 0.1;
  double delta = 1;
  std::string delta_unit = "frames";
  bool all_pairs = false;
  std::vector<double> segments;
  int segment_step = 10;
  std::string json;
};

nlohmann::json stats_json(const Stats& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std}, {"min", s.min}, {"max", s.max}};
}

struct Evaluation {
  size_t gt_poses = 0, est_poses = 0;
  Matched matched;
  Alignment alignment;
  ApeResult ape;
  RpeResult rpe;
  DriftResult drift;
};

nlohmann::json to_json(const EvalOptions& o, const Evaluation& ev) {
  nlohmann::json rotation = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) {
    rotation.push_back({ev.alignment.rotation(r, 0), ev.alignment.rotation(r, 1), ev.alignment.rotation(r, 2)});
  }
  nlohmann::json segments = nlohmann::json::array();
  for (const auto& s : ev.drift.segments) {
    segments.push_back({{"length_m", s.length_m}, {"count", s.count}, {"trans_pct", s.trans_pct},
                        {"rot_deg_per_m", s.rot_deg_per_m}});
  }
  return {{"reference", {{"source", o.gt}, {"poses", ev.gt_poses}}},
          {"estimate", {{"source", o.est}, {"poses", ev.est_poses}}},
          {"matching", {{"method", o.interpolate ? "interpolate" : "nearest"},
                        {"max_dt", o.max_dt},
                        {"offset", o.offset}}},
          {"matched", ev.matched.ref.size()},
          {"alignment", {{"type", to_string(ev.alignment.type)},
                         {"rotation", rotation},
                         {"translation", {ev.alignment.translation.x(), ev.alignment.translation.y(),
                                          ev.alignment.translation.z()}},
                         {"scale", ev.alignment.scale}}},
          {"ate", stats_json(ev.ape.trans)},
          {"ate_rot_deg", stats_json(ev.ape.rot_deg)},
          {"rpe", {{"delta", ev.rpe.delta},
                   {"unit", to_string(ev.rpe.unit)},
                   {"all_pairs", ev.rpe.all_pairs},
                   {"pairs", ev.rpe.pairs.size()},
                   {"trans", stats_json(ev.rpe.trans)},
                   {"rot_deg", stats_json(ev.rpe.rot_deg)}}},
          {"drift", {{"trans_pct", ev.drift.trans_pct},
                     {"rot_deg_per_m", ev.drift.rot_deg_per_m},
                     {"count", ev.drift.count},
                     {"step", o.segment_step},
                     {"segments", segments}}}};
}

void print_stats_row(const char* label, const Stats& s) {
  std::printf("%-16s %10.6f %10.6f %10.6f %10.6f %10.6f %10.6f\n", label, s.rmse, s.mean, s.median, s.std, s.min,
              s.max);
}

void print_table(const EvalOptions& o, const Evaluation& ev) {
  std::printf("matched %s of %s estimated poses with %s reference poses (%s, max dt %g s, offset %g s)\n",
              thousands(static_cast<int64_t>(ev.matched.ref.size())).c_str(),
              thousands(static_cast<int64_t>(ev.est_poses)).c_str(),
              thousands(static_cast<int64_t>(ev.gt_poses)).c_str(), o.interpolate ? "interpolated" : "nearest stamp",
              o.interpolate ? o.max_gap : o.max_dt, o.offset);
  const Alignment& a = ev.alignment;
  const Eigen::AngleAxisd aa(a.rotation);
  std::printf("alignment %s: rotation %.3f deg about (%.3f, %.3f, %.3f), translation (%.4f, %.4f, %.4f) m, scale %.6f\n\n",
              to_string(a.type), aa.angle() * 180 / M_PI, aa.axis().x(), aa.axis().y(), aa.axis().z(),
              a.translation.x(), a.translation.y(), a.translation.z(), a.scale);
  std::printf("%-16s %10s %10s %10s %10s %10s %10s\n", "", "rmse", "mean", "median", "std", "min", "max");
  print_stats_row("ATE [m]", ev.ape.trans);
  print_stats_row("ATE [deg]", ev.ape.rot_deg);
  char label[64];
  std::snprintf(label, sizeof(label), "RPE [m]");
  print_stats_row(label, ev.rpe.trans);
  print_stats_row("RPE [deg]", ev.rpe.rot_deg);
  const bool one_frame = ev.rpe.unit == DeltaUnit::kFrames && ev.rpe.delta == 1;
  std::printf("(RPE over %zu pairs %g %s apart%s)\n\n", ev.rpe.pairs.size(), ev.rpe.delta,
              one_frame ? "frame" : to_string(ev.rpe.unit), ev.rpe.all_pairs ? ", all pairs" : "");
  if (ev.drift.count == 0) {
    std::printf("drift: no segment fits in the reference path (%.3f m)\n", ev.matched.ref.path_length());
    return;
  }
  std::printf("drift: %.3f %% of distance, %.5f deg/m (KITTI style: %s segments, one from every %d poses)\n",
              ev.drift.trans_pct, ev.drift.rot_deg_per_m, thousands(static_cast<int64_t>(ev.drift.count)).c_str(),
              o.segment_step);
  std::printf("%12s %10s %10s %12s\n", "length [m]", "segments", "trans [%]", "rot [deg/m]");
  for (const auto& s : ev.drift.segments) {
    std::printf("%12.3f %10zu %10.3f %12.5f\n", s.length_m, s.count, s.trans_pct, s.rot_deg_per_m);
  }
}

/// The files a source reads (LOG of LOG:CHANNEL, or a TUM file), checked: a log must hold events, and a log given
/// without its channel is named as such (rather than read as a TUM file that is "not a number" on line 1).
Status check_source(const std::string& src, const char* option, std::vector<std::string>& files) {
  std::string log, channel;
  if (split_log_channel(src, &log, &channel)) {
    files.push_back(log);
    return check_event_log(log);
  }
  files.push_back(src);
  if (check_event_log(src).ok()) {
    return Error{src + ": an LCM event log: name the channel, as " + option + " " + src + ":CHANNEL"};
  }
  return {};
}

int run_eval(const EvalOptions& o) {
  std::vector<std::string> inputs;
  for (const auto& [src, option] : {std::pair{o.gt, "--gt"}, {o.est, "--est"}}) {
    if (Status s = check_source(src, option, inputs); !s) return fail(s.message());
  }
  if (Status s = refuse_same_file(o.json, inputs, "--json"); !s) return fail(s.message());
  // The two inputs load in parallel: parsing is most of the work on large trajectories.
  auto pending_gt = std::async(std::launch::async, [&] { return load_trajectory(o.gt); });
  auto est = load_trajectory(o.est);
  auto gt = pending_gt.get();
  if (!gt) return fail(gt.error().message);
  if (!est) return fail(est.error().message);
  Evaluation ev;
  ev.gt_poses = gt->size();
  ev.est_poses = est->size();
  ev.matched = o.interpolate ? match_interpolated(*gt, *est, o.max_gap, o.offset)
                             : match_nearest(*gt, *est, o.max_dt, o.offset);
  if (ev.matched.ref.size() == 0) {
    return fail(o.est + " against " + o.gt + ": " + explain_no_match(*gt, *est, o.interpolate ? o.max_gap : o.max_dt, o.offset));
  }
  const AlignmentType type = o.align == "se3"    ? AlignmentType::kSe3
                             : o.align == "sim3" ? AlignmentType::kSim3
                             : o.align == "posyaw" ? AlignmentType::kPosYaw
                                                   : AlignmentType::kNone;
  ev.alignment = align(ev.matched, type);
  ev.matched.est = apply(ev.alignment, std::move(ev.matched.est));
  const Matched& aligned = ev.matched;
  ev.ape = ape(aligned);
  const DeltaUnit unit = o.delta_unit == "m" ? DeltaUnit::kMeters
                         : o.delta_unit == "s" ? DeltaUnit::kSeconds
                                               : DeltaUnit::kFrames;
  ev.rpe = rpe(aligned, o.delta, unit, o.all_pairs);
  ev.drift = drift(aligned, o.segments, static_cast<size_t>(o.segment_step));

  if (o.json.empty()) {
    print_table(o, ev);
    return kExitOk;
  }
  if (!write_output(o.json, to_json(o, ev).dump(2) + "\n")) return kExitFailure;
  if (o.json != "-") print_table(o, ev);
  return kExitOk;
}

}  // namespace

void add_eval_command(CLI::App& app, int* exit_code) {
  auto o = std::make_shared<EvalOptions>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "Trajectory error of an estimate against ground truth: ATE, RPE and drift, with evo's semantics.");
  cmd->footer(
      "SRC is LOG:CHANNEL (a driftlab.pose_t or driftlab.odometry_t channel, stamped with header.utime) or a TUM\n"
      "file (t x y z qx qy qz qw). Matching: for each stamp of the trajectory with fewer poses, the nearest stamp of\n"
      "the other within --max-dt (as evo), or with --interpolate the reference interpolated at each estimate stamp.");
  cmd->add_option("--gt", o->gt, "Reference (ground truth): LOG:CHANNEL or TUM file")->required();
  cmd->add_option("--est", o->est, "Estimate: LOG:CHANNEL or TUM file")->required();
  cmd->add_option("--align", o->align, "Alignment of the estimate onto the reference (Umeyama; posyaw: x, y, z, yaw)")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "se3", "sim3", "posyaw"}));
  cmd->add_option("--max-dt", o->max_dt, "Largest stamp difference of a matched pair [s]")
      ->capture_default_str()
      ->check(non_negative());
  cmd->add_option("--offset", o->offset, "Added to the estimate's stamps before matching [s]")->capture_default_str();
  cmd->add_flag("--interpolate", o->interpolate, "Interpolate the reference at the estimate's stamps");
  cmd->add_option("--max-gap", o->max_gap, "With --interpolate: largest gap between reference poses to interpolate across [s]")
      ->capture_default_str()
      ->check(positive());
  cmd->add_option("--delta", o->delta, "RPE: distance between the poses of a pair")
      ->capture_default_str()
      ->check(positive());
  cmd->add_option("--delta-unit", o->delta_unit, "RPE: unit of --delta")
      ->capture_default_str()
      ->check(CLI::IsMember({"frames", "m", "s"}));
  cmd->add_flag("--all-pairs", o->all_pairs, "RPE: every pair --delta apart, not consecutive ones");
  cmd->add_option("--segments", o->segments,
                  "Drift: segment lengths [m], comma separated (default: 10..50% of the reference path)")
      ->delimiter(',')
      ->check(positive());
  cmd->add_option("--segment-step", o->segment_step, "Drift: a segment starts at every N-th matched pose")
      ->capture_default_str()
      ->check(positive());
  cmd->add_option("--json", o->json, "Also write the results as JSON to this file ('-': print only the JSON)");
  cmd->callback([o, exit_code] {
    if (o->delta_unit == "frames" && std::floor(o->delta) != o->delta) {
      *exit_code = fail("--delta must be a whole number of frames, got " + std::to_string(o->delta));
      return;
    }
    *exit_code = run_eval(*o);
  });
}

}  // namespace driftlab::apps
