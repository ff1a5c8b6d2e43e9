// driftlab eval --gt SRC --est SRC: trajectory error (ATE, RPE, drift) against ground truth, equal to evo.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <future>
#include <memory>

#include "analyzers/arm_tracking.h"
#include "analyzers/correlation.h"
#include "analyzers/relations.h"
#include "analyzers/time_offset.h"
#include "analyzers/trajectory.h"
#include "analyzers/trajectory_io.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "apps/log_input.h"
#include "core/log_reader.h"
#include "core/same_file.h"

namespace driftlab::apps {
namespace {

using namespace analyzers;

/// --offset [s]: up to centuries, so that an estimate stamped since boot meets a reference stamped since the epoch.
constexpr config::Range kOffsetRange = config::between(-1e10, 1e10);

struct EvalOptions {
  std::string gt, est;
  std::string gt_format = "auto", est_format = "auto";
  std::string gt_times, est_times;
  std::string align = "none";
  double max_dt = 0.01;
  std::string offset = "0";  // seconds, or "auto"
  bool interpolate = false;
  double max_gap = 0.1;
  double delta = 1;
  std::string delta_unit = "frames";
  bool all_pairs = false;
  bool pairs_from_reference = false;
  double delta_tol = 0.1;
  std::vector<double> segments;
  int segment_step = 10;
  std::string relations;
  double relations_max_dt = 1e-4;
  std::string odometry;
  std::string arm;
  std::string arm_reference = "commanded";
  std::string arm_command, arm_ee, arm_base;
  double arm_cutoff = 5.0;
  JsonOutput json;
};

/// Statistics as JSON; null when there is nothing to take them over.
nlohmann::json stats_json(const Stats& s) {
  if (s.count == 0) return nullptr;
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std}, {"min", s.min}, {"max", s.max}};
}

struct Evaluation {
  size_t gt_poses = 0, est_poses = 0;
  double offset = 0;                  ///< applied to the estimate's stamps [s]
  std::optional<TimeOffset> offset_auto;
  std::vector<std::string> notes;     ///< what was done to the inputs (sorted, repeated stamps), also on stderr
  std::optional<RelationResult> relations;
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
          {"matching", {{"method", !ev.matched.ref.stamped ? "index" : o.interpolate ? "interpolate" : "nearest"},
                        {"max_dt", o.max_dt},
                        {"offset", ev.offset},
                        {"offset_auto", ev.offset_auto ? nlohmann::json{{"offset_s", ev.offset_auto->offset_s},
                                                                        {"confidence", ev.offset_auto->confidence},
                                                                        {"signal", ev.offset_auto->signal},
                                                                        {"overlap_s", ev.offset_auto->overlap_s}}
                                                       : nlohmann::json(nullptr)}}},
          {"matched", ev.matched.ref.size()},
          {"alignment", {{"type", to_string(ev.alignment.type)},
                         {"rotation", rotation},
                         {"translation", {ev.alignment.translation.x(), ev.alignment.translation.y(),
                                          ev.alignment.translation.z()}},
                         {"scale", ev.alignment.scale}}},
          {"ate", stats_json(ev.ape.trans)},
          {"ate_rot_deg", stats_json(ev.ape.rot_deg)},
          {"rpe", {{"delta", ev.rpe.options.delta},
                   {"unit", to_string(ev.rpe.options.unit)},
                   {"all_pairs", ev.rpe.options.all_pairs},
                   {"pairs_from", ev.rpe.options.pairs_from_reference ? "reference" : "estimate"},
                   {"delta_tol", ev.rpe.options.delta_tol},
                   {"pairs", ev.rpe.pairs.size()},
                   {"trans", stats_json(ev.rpe.trans)},
                   {"rot_deg", stats_json(ev.rpe.rot_deg)}}},
          {"drift", {{"trans_pct", ev.drift.trans_pct},
                     {"rot_deg_per_m", ev.drift.rot_deg_per_m},
                     {"count", ev.drift.count},
                     {"step", o.segment_step},
                     {"segments", segments}}}};
}

nlohmann::json relation_stats_json(const RelationStats& s) {
  return {{"mean", s.mean}, {"std", s.std}, {"max", s.max}};
}

nlohmann::json relations_json(const EvalOptions& o, const RelationResult& r) {
  return {{"source", o.relations},
          {"odometry", o.odometry.empty() ? nlohmann::json(nullptr) : nlohmann::json(o.odometry)},
          {"max_dt", o.relations_max_dt},
          {"relations", r.relations},
          {"used", r.used},
          {"bridged", r.bridged},
          {"max_bridge_s", r.max_bridge_s},
          {"trans_m", relation_stats_json(r.trans_m)},
          {"trans_sq_m2", relation_stats_json(r.trans_sq_m2)},
          {"rot_deg", relation_stats_json(r.rot_deg)},
          {"rot_sq_deg2", relation_stats_json(r.rot_sq_deg2)}};
}

void print_relations(const EvalOptions& o, const RelationResult& r) {
  std::printf("relation error (Kuemmerle et al. 2009) of %s over %s of %s relations", o.est.c_str(),
              thousands(static_cast<int64_t>(r.used)).c_str(), thousands(static_cast<int64_t>(r.relations)).c_str());
  if (r.bridged > 0) {
    std::printf(" (%s with a pose carried by odometry, at most %.3f s)", thousands(static_cast<int64_t>(r.bridged)).c_str(),
                r.max_bridge_s);
  }
  std::printf("\n%-20s %12s %12s %12s\n", "", "mean", "std", "max");
  const std::pair<const char*, const RelationStats*> rows[] = {{"translation [m]", &r.trans_m},
                                                               {"translation^2 [m^2]", &r.trans_sq_m2},
                                                               {"rotation [deg]", &r.rot_deg},
                                                               {"rotation^2 [deg^2]", &r.rot_sq_deg2}};
  for (const auto& [label, st] : rows) std::printf("%-20s %12.6f %12.6f %12.6f\n", label, st->mean, st->std, st->max);
}

void print_stats_row(const char* label, const Stats& s) {
  std::printf("%-16s %10.6f %10.6f %10.6f %10.6f %10.6f %10.6f\n", label, s.rmse, s.mean, s.median, s.std, s.min,
              s.max);
}

void print_table(const EvalOptions& o, const Evaluation& ev) {
  const std::string matched = thousands(static_cast<int64_t>(ev.matched.ref.size()));
  if (!ev.matched.ref.stamped) {
    std::printf("matched %s poses pose for pose (no stamps)\n", matched.c_str());
  } else {
    std::printf("matched %s of %s estimated poses with %s reference poses (%s, max dt %g s, offset %.6g s",
                matched.c_str(), thousands(static_cast<int64_t>(ev.est_poses)).c_str(),
                thousands(static_cast<int64_t>(ev.gt_poses)).c_str(), o.interpolate ? "interpolated" : "nearest stamp",
                o.interpolate ? o.max_gap : o.max_dt, ev.offset);
    if (ev.offset_auto) {
      std::printf(" found from the %s: confidence %.2f over %.1f s", ev.offset_auto->signal.c_str(),
                  ev.offset_auto->confidence, ev.offset_auto->overlap_s);
    }
    std::printf(")\n");
  }
  const Alignment& a = ev.alignment;
  const Eigen::AngleAxisd aa(a.rotation);
  std::printf("alignment %s: rotation %.3f deg about (%.3f, %.3f, %.3f), translation (%.4f, %.4f, %.4f) m, scale %.6f\n\n",
              to_string(a.type), aa.angle() * 180 / M_PI, aa.axis().x(), aa.axis().y(), aa.axis().z(),
              a.translation.x(), a.translation.y(), a.translation.z(), a.scale);
  std::printf("%-16s %10s %10s %10s %10s %10s %10s\n", "", "rmse", "mean", "median", "std", "min", "max");
  print_stats_row("ATE [m]", ev.ape.trans);
  print_stats_row("ATE [deg]", ev.ape.rot_deg);
  const RpeOptions& r = ev.rpe.options;
  const bool one_frame = r.unit == DeltaUnit::kFrames && r.delta == 1;
  char how[160];
  std::snprintf(how, sizeof(how), "%g %s apart along the %s%s", r.delta, one_frame ? "frame" : to_string(r.unit),
                r.pairs_from_reference ? "reference" : "estimate",
                !r.all_pairs ? "" : r.unit == DeltaUnit::kFrames ? ", all pairs" : ", all pairs within the tolerance");
  if (ev.rpe.pairs.empty()) {
    std::printf("RPE: no pair of poses is %s: try a smaller --delta%s\n\n", how,
                r.all_pairs && r.unit != DeltaUnit::kFrames ? " or a larger --delta-tol" : "");
  } else {
    print_stats_row("RPE [m]", ev.rpe.trans);
    print_stats_row("RPE [deg]", ev.rpe.rot_deg);
    std::printf("(RPE over %s pairs %s)\n\n", thousands(static_cast<int64_t>(ev.rpe.pairs.size())).c_str(), how);
  }
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

/// Puts a loaded trajectory in stamp order and checks its stamps: out-of-order poses are sorted (said in a note),
/// poses sharing the stamp before them are kept (matching takes the first, as evo does; said in a note), and a
/// trajectory whose stamps mostly repeat is refused: frozen stamps, which no matching can tell apart. Returns
/// false after printing why.
bool put_in_order(const std::string& what, const std::string& src, Trajectory& t, Evaluation& ev) {
  if (!t.stamped) return true;
  const StampOrder order = sort_by_stamp(t);
  char buf[512];
  if (order.repeated * 2 > t.size()) {
    std::snprintf(buf, sizeof(buf),
                  "%s %s: %zu of %zu poses carry the stamp of the pose before them (the first at %.6f s): frozen "
                  "stamps (a stamp set once, or one time given to every pose), which leave nothing to match in time",
                  what.c_str(), src.c_str(), order.repeated, t.size(), order.first_repeated);
    fail(buf);
    return false;
  }
  if (order.out_of_order > 0) {
    const bool one = order.out_of_order == 1;
    std::snprintf(buf, sizeof(buf), "%s %s: %zu pose%s stamped earlier than the pose before %s (the first at %.6f s); "
                  "sorted by stamp",
                  what.c_str(), src.c_str(), order.out_of_order, one ? " was" : "s were", one ? "it" : "them",
                  order.first_out_of_order);
    ev.notes.push_back(buf);
  }
  if (order.repeated > 0) {
    const bool one = order.repeated == 1;
    std::snprintf(buf, sizeof(buf), "%s %s: %zu pose%s %s stamp with the pose before %s (the first at %.6f s); "
                  "matching takes the first of them, as evo does",
                  what.c_str(), src.c_str(), order.repeated, one ? "" : "s", one ? "shares its" : "share their",
                  one ? "it" : "them", order.first_repeated);
    ev.notes.push_back(buf);
  }
  return true;
}

/// The relation error of the estimate, when --relations is given; false (after printing why) on bad input.
bool evaluate_relations(const EvalOptions& o, const Trajectory& est, Evaluation& ev) {
  if (!est.stamped) {
    fail("--est " + o.est + ": relations are found by stamp, and these poses have none (give --est-times)");
    return false;
  }
  auto pending_odometry = std::async(std::launch::async, [&]() -> Result<Trajectory> {
    if (o.odometry.empty()) return Trajectory{};
    return load_trajectory(o.odometry);
  });
  auto relations = load_relations(o.relations);
  auto odometry = pending_odometry.get();
  if (!relations) return fail(relations.error().message), false;
  if (!odometry) return fail(odometry.error().message), false;
  if (!odometry->stamped) return fail("--relations-odometry " + o.odometry + ": odometry without stamps"), false;
  if (!put_in_order("--relations-odometry", o.odometry, *odometry, ev)) return false;
  RelationOptions options;
  options.max_dt = o.relations_max_dt;
  options.odometry = o.odometry.empty() ? nullptr : &*odometry;
  ev.relations = relation_error(est, *relations, options);
  if (ev.relations->used == 0) {
    fail(o.relations + ": no relation has estimate poses at both of its stamps (within --relations-max-dt " +
         short_number(o.relations_max_dt) + " s" + (o.odometry.empty() ? "; --relations-odometry can carry the nearest poses to them" : "") + ")");
    return false;
  }
  return true;
}

TrajectoryFormat format_of(const std::string& name) {
  return name == "tum"     ? TrajectoryFormat::kTum
         : name == "kitti" ? TrajectoryFormat::kKitti
         : name == "euroc" ? TrajectoryFormat::kEuroc
                           : TrajectoryFormat::kAuto;
}

/// The pairs of an unstamped trajectory (KITTI poses without times) with another: pose for pose, as evo compares
/// them; false after printing why when that is impossible.
bool match_by_index(const EvalOptions& o, const Trajectory& gt, const Trajectory& est, Matched& m) {
  if (gt.stamped != est.stamped) {
    const bool gt_unstamped = !gt.stamped;
    fail(std::string(gt_unstamped ? "--gt " + o.gt : "--est " + o.est) +
         ": KITTI poses without stamps can only be compared pose for pose with another trajectory without stamps; "
         "give " + (gt_unstamped ? "--gt-times" : "--est-times") + " FILE (one stamp a line)");
    return false;
  }
  if (gt.size() != est.size()) {
    fail("--gt " + o.gt + " has " + std::to_string(gt.size()) + " poses and --est " + o.est + " " +
         std::to_string(est.size()) + ": without stamps they are compared pose for pose, so they must be as many");
    return false;
  }
  if (o.offset == "auto" || std::strtod(o.offset.c_str(), nullptr) != 0 || o.interpolate) {
    fail("--offset and --interpolate need stamps, and KITTI poses without --gt-times/--est-times have none");
    return false;
  }
  m.ref = gt;
  m.est = est;
  for (auto* t : {&m.ref, &m.est}) {
    for (auto& q : t->orientations) q.normalize();
  }
  return true;
}

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

nlohmann::json arm_json(const ArmTracking& a) {
  auto or_null = [](const std::string& s) { return s.empty() ? nlohmann::json() : nlohmann::json(s); };
  nlohmann::json joints = nlohmann::json::array();
  for (const JointTracking& j : a.joints) {
    joints.push_back(
        {{"name", j.name},
         {"error_rad", stats_json(j.error_rad)},
         {"mean_signed_rad", j.mean_signed_rad},
         {"limits", j.has_position_limits
                        ? nlohmann::json{{"lower", j.lower}, {"upper", j.upper}, {"velocity", j.velocity_limit}}
                        : nlohmann::json()},
         {"reached", {{"min", j.min}, {"max", j.max}, {"max_speed", j.max_speed}}},
         {"beyond", {{"position", j.beyond_position}, {"velocity", j.beyond_velocity}}}});
  }
  nlohmann::json ee;
  if (a.ee_position_m.count > 0) {
    ee = {
        {"base_link", a.base_link},
        {"tip_link", a.tip_link},
        {"position_m", stats_json(a.ee_position_m)},
        {"rotation_deg", stats_json(a.ee_rotation_deg)},
        {"oscillation",
         {{"cutoff_hz", a.oscillation.cutoff_hz}, {"rms_m", a.oscillation.rms_m}, {"peak_hz", a.oscillation.peak_hz}}}};
  }
  return {{"log", a.log},
          {"reference", to_string(a.reference)},
          {"channels",
           {{"commands", a.command_channel},
            {"joint_states", a.state_channel},
            {"controller_state", or_null(a.controller_channel)},
            {"ee_truth", or_null(a.ee_channel)},
            {"base_truth", or_null(a.base_channel)}}},
          {"commands", a.commands},
          {"span_s", {a.start_s, a.end_s}},
          {"joints", joints},
          {"ee", ee},
          {"ee_problem", or_null(a.ee_problem)}};
}

void print_arm(const ArmTracking& a) {
  constexpr double kDeg = 180.0 / M_PI;
  std::printf("arm tracking of %s: %s against the %s (%s commands on %s), %.3f to %.3f s\n", a.log.c_str(),
              a.state_channel.c_str(),
              a.reference == ArmReference::kCommanded ? "commanded plans" : "controller's desired state",
              thousands(a.commands).c_str(), a.command_channel.c_str(), a.start_s, a.end_s);
  if (a.reference == ArmReference::kDesired) std::printf("(desired state from %s)\n", a.controller_channel.c_str());
  std::printf("\n%-16s %10s %10s %10s %22s %22s %16s\n", "joint [deg]", "rmse", "max", "mean", "reached", "limits",
              "speed max/limit");
  for (const JointTracking& j : a.joints) {
    char reached[64], limits[64] = "-", speed[64];
    std::snprintf(reached, sizeof(reached), "%.1f .. %.1f", j.min * kDeg, j.max * kDeg);
    if (j.has_position_limits) std::snprintf(limits, sizeof(limits), "%.1f .. %.1f", j.lower * kDeg, j.upper * kDeg);
    std::snprintf(speed, sizeof(speed), j.velocity_limit > 0 ? "%.2f/%.2f" : "%.2f/-", j.max_speed, j.velocity_limit);
    std::printf("%-16s %10.4f %10.4f %+10.4f %22s %22s %16s%s\n", j.name.c_str(), j.error_rad.rmse * kDeg,
                j.error_rad.max * kDeg, j.mean_signed_rad * kDeg, reached, limits, speed,
                j.beyond_position + j.beyond_velocity > 0 ? "  beyond its limits" : "");
  }
  if (a.ee_position_m.count == 0) {
    std::printf("\nend effector: %s\n", a.ee_problem.c_str());
    return;
  }
  std::printf("\nend effector %s in %s: FK of the %s joints against %s and %s, %s poses\n", a.tip_link.c_str(),
              a.base_link.c_str(), to_string(a.reference), a.ee_channel.c_str(), a.base_channel.c_str(),
              thousands(static_cast<int64_t>(a.ee_position_m.count)).c_str());
  std::printf("%-16s %10s %10s %10s %10s %10s %10s\n", "", "rmse", "mean", "median", "std", "min", "max");
  const Stats& p = a.ee_position_m;
  std::printf("%-16s %10.3f %10.3f %10.3f %10.3f %10.3f %10.3f\n", "position [mm]", p.rmse * 1e3, p.mean * 1e3,
              p.median * 1e3, p.std * 1e3, p.min * 1e3, p.max * 1e3);
  print_stats_row("rotation [deg]", a.ee_rotation_deg);
  std::printf("oscillation (the end effector's motion above %g Hz): %.3f mm RMS, strongest at %.2f Hz\n",
              a.oscillation.cutoff_hz, a.oscillation.rms_m * 1e3, a.oscillation.peak_hz);
}

/// driftlab eval --arm LOG: the arm's tracking error.
int run_arm_eval(const EvalOptions& o) {
  if (!o.gt.empty() || !o.est.empty() || !o.relations.empty()) {
    return fail("--arm evaluates an arm's tracking in one log: give it without --gt, --est and --relations");
  }
  if (Status s = refuse_same_file(o.json.file, {o.arm}, "--json-out"); !s) return fail(s.message());
  auto log = event_log_for(o.arm);  // another tool's recording: its cached conversion
  if (!log) return fail(log.error().message, exit_code_for_input(log.error()));
  ArmTrackingOptions options;
  options.reference = o.arm_reference == "desired" ? ArmReference::kDesired : ArmReference::kCommanded;
  options.command_channel = o.arm_command;
  options.ee_channel = o.arm_ee;
  options.base_channel = o.arm_base;
  options.oscillation_cutoff_hz = o.arm_cutoff;
  auto a = evaluate_arm(*log, options);
  if (!a) return fail(a.error().message);
  a->log = o.arm;
  if (!o.json.print) print_arm(*a);
  nlohmann::json j = {{"arm", arm_json(*a)}, {"notes", nlohmann::json::array()}};
  if (o.json.wanted() && !o.json.emit(j.dump(2) + "\n")) return kExitFailure;
  return kExitOk;
}

int run_eval(const EvalOptions& o) {
  if (!o.arm.empty()) return run_arm_eval(o);
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
  if (Status s = refuse_same_file(o.json.file, inputs, "--json-out"); !s) return fail(s.message());
  // LOG:CHANNEL of another tool's recording: read from its cached conversion (the output names the source given).
  Result<std::string> gt_src = std::string();
  if (!o.gt.empty()) gt_src = log_channel_for(o.gt);
  if (!gt_src) return fail(gt_src.error().message, exit_code_for_input(gt_src.error()));
  auto est_src = log_channel_for(o.est);
  if (!est_src) return fail(est_src.error().message, exit_code_for_input(est_src.error()));
  for (const auto& [src, option] :
       {std::pair{*gt_src, "--gt"}, {*est_src, "--est"}, {o.odometry, "--relations-odometry"}}) {
    if (src.empty()) continue;
    if (Status s = check_source(src, option); !s) return fail(s.message());
  }
  // The inputs load in parallel: parsing is most of the work on large trajectories.
  auto pending_gt = std::async(std::launch::async, [&]() -> Result<Trajectory> {
    if (o.gt.empty()) return Trajectory{};
    return load_trajectory(*gt_src, format_of(o.gt_format), o.gt_times);
  });
  auto est = load_trajectory(*est_src, format_of(o.est_format), o.est_times);
  auto gt = pending_gt.get();
  if (!gt) return fail(gt.error().message);
  if (!est) return fail(est.error().message);
  Evaluation ev;
  ev.est_poses = est->size();
  ev.gt_poses = gt->size();
  if (!put_in_order("--est", o.est, *est, ev)) return kExitBadInput;
  if (!o.gt.empty() && !put_in_order("--gt", o.gt, *gt, ev)) return kExitBadInput;
  if (!o.relations.empty() && !evaluate_relations(o, *est, ev)) return kExitBadInput;
  for (const auto& note : ev.notes) std::fprintf(stderr, "driftlab: note: %s\n", note.c_str());
  nlohmann::json notes(ev.notes);

  if (o.gt.empty()) {
    nlohmann::json j = {{"estimate", {{"source", o.est}, {"poses", ev.est_poses}}},
                        {"relations", relations_json(o, *ev.relations)},
                        {"notes", notes}};
    if (!o.json.print) print_relations(o, *ev.relations);
    if (o.json.wanted() && !o.json.emit(j.dump(2) + "\n")) return kExitFailure;
    return kExitOk;
  }

  if (!gt->stamped || !est->stamped) {
    if (!match_by_index(o, *gt, *est, ev.matched)) return kExitBadInput;
  } else {
    if (o.offset == "auto") {
      ev.offset_auto = estimate_time_offset(*gt, *est);
      const TimeOffset& a = *ev.offset_auto;
      if (!a.found) return fail("--offset auto: no offset found between " + o.est + " and " + o.gt + ": " + a.problem);
      if (a.confidence < analyzers::kConfidentCorrelation) {
        char buf[400];
        std::snprintf(buf, sizeof(buf),
                      "--offset auto: the motions of %s and %s do not line up clearly (best %+.4f s, from the %s, "
                      "confidence %.2f < %.1f): give --offset",
                      o.est.c_str(), o.gt.c_str(), a.offset_s, a.signal.c_str(), a.confidence,
                      analyzers::kConfidentCorrelation);
        return fail(buf);
      }
      ev.offset = a.offset_s;
    } else {
      ev.offset = std::strtod(o.offset.c_str(), nullptr);
    }
    ev.matched = o.interpolate ? match_interpolated(*gt, *est, o.max_gap, ev.offset)
                               : match_nearest(*gt, *est, o.max_dt, ev.offset);
    if (ev.matched.ref.size() == 0) {
      return fail(o.est + " against " + o.gt + ": " +
                  explain_no_match(*gt, *est, o.interpolate ? o.max_gap : o.max_dt, ev.offset) +
                  (o.offset == "auto" ? "" : " (or --offset auto)"));
    }
  }
  const AlignmentType type = o.align == "se3"      ? AlignmentType::kSe3
                             : o.align == "sim3"   ? AlignmentType::kSim3
                             : o.align == "posyaw" ? AlignmentType::kPosYaw
                             : o.align == "origin" ? AlignmentType::kOrigin
                                                   : AlignmentType::kNone;
  ev.alignment = align(ev.matched, type);
  if (!ev.alignment.problem.empty()) {
    return fail("--align " + o.align + " of " + o.est + " onto " + o.gt + ": " + ev.alignment.problem);
  }
  if (type != AlignmentType::kNone) ev.matched.est = apply(ev.alignment, std::move(ev.matched.est));
  const Matched& aligned = ev.matched;
  ev.ape = ape(aligned);
  RpeOptions rpe_options;
  rpe_options.delta = o.delta;
  rpe_options.unit = o.delta_unit == "m"     ? DeltaUnit::kMeters
                     : o.delta_unit == "s"   ? DeltaUnit::kSeconds
                     : o.delta_unit == "deg" ? DeltaUnit::kDegrees
                     : o.delta_unit == "rad" ? DeltaUnit::kRadians
                                             : DeltaUnit::kFrames;
  rpe_options.all_pairs = o.all_pairs;
  rpe_options.pairs_from_reference = o.pairs_from_reference;
  rpe_options.delta_tol = o.delta_tol;
  ev.rpe = rpe(aligned, rpe_options);
  ev.drift = drift(aligned, o.segments, static_cast<size_t>(o.segment_step));

  nlohmann::json j = to_json(o, ev);
  if (ev.relations) j["relations"] = relations_json(o, *ev.relations);
  j["notes"] = notes;
  if (!o.json.print) {
    print_table(o, ev);
    if (ev.relations) {
      std::printf("\n");
      print_relations(o, *ev.relations);
    }
  }
  if (o.json.wanted() && !o.json.emit(j.dump(2) + "\n")) return kExitFailure;
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
  const auto formats = CLI::IsMember({"auto", "tum", "kitti", "euroc"});
  cmd->add_option("--gt", o->gt, "Reference (ground truth): LOG:CHANNEL or a TUM, KITTI or EuRoC file");
  cmd->add_option("--est", o->est, "Estimate: LOG:CHANNEL or a TUM, KITTI or EuRoC file");
  cmd->add_option("--gt-format", o->gt_format, "Format of a --gt file")->capture_default_str()->check(formats);
  cmd->add_option("--est-format", o->est_format, "Format of an --est file")->capture_default_str()->check(formats);
  cmd->add_option("--gt-times", o->gt_times, "With KITTI --gt: its stamps, one a line [s]");
  cmd->add_option("--est-times", o->est_times, "With KITTI --est: its stamps, one a line [s]");
  cmd->add_option("--align", o->align,
                  "Alignment of the estimate onto the reference (Umeyama; posyaw: x, y, z, yaw; origin: the first "
                  "matched poses made equal, evo's --align_origin)")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "se3", "sim3", "posyaw", "origin"}));
  cmd->add_option("--max-dt", o->max_dt, "Largest stamp difference of a matched pair [s]")
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
  cmd->add_flag("--interpolate", o->interpolate, "Interpolate the reference at the estimate's stamps");
  cmd->add_option("--max-gap", o->max_gap,
                  "With --interpolate: largest gap between reference poses to interpolate across [s]")
      ->capture_default_str()
      ->check(in_range(config::above(0, 86400), "s"));
  cmd->add_option("--delta", o->delta, "RPE: distance between the poses of a pair")
      ->capture_default_str()
      ->check(in_range(config::above(0, 1e9)));
  cmd->add_option("--delta-unit", o->delta_unit, "RPE: unit of --delta (s: elapsed time, not in evo)")
      ->capture_default_str()
      ->check(CLI::IsMember({"frames", "m", "s", "deg", "rad"}));
  cmd->add_flag("--all-pairs", o->all_pairs, "RPE: every pair --delta apart, not consecutive ones");
  cmd->add_flag("--pairs-from-reference", o->pairs_from_reference,
                "RPE: choose the pairs along the reference, not the estimate (evo's --pairs_from_reference)");
  cmd->add_option("--delta-tol", o->delta_tol,
                  "RPE with --all-pairs in m, s, deg or rad: accepted miss of --delta, relative (evo's rel_delta_tol)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1)));
  cmd->add_option("--segments", o->segments,
                  "Drift: segment lengths [m], comma separated (default: 10..50% of the reference path)")
      ->delimiter(',')
      ->check(in_range(config::above(0, 1e7), "m"));
  cmd->add_option("--segment-step", o->segment_step, "Drift: a segment starts at every N-th matched pose")
      ->capture_default_str()
      ->check(in_range(config::between(1, 1e6)));
  cmd->add_option("--relations", o->relations,
                  "Relations file (t1 t2 x y z roll pitch yaw a line): the SLAM benchmark's relation error");
  cmd->add_option("--relations-max-dt", o->relations_max_dt,
                  "With --relations: largest stamp difference of a relation and the pose it takes [s]")
      ->capture_default_str()
      ->check(in_range(config::between(0, 86400), "s"));
  cmd->add_option("--relations-odometry", o->odometry,
                  "With --relations: raw odometry (LOG:CHANNEL or TUM file) to carry poses to stamps without one");
  cmd->add_option("--arm", o->arm,
                  "An arm's tracking error in LOG: per joint and at the end effector against ground truth");
  cmd->add_option("--arm-reference", o->arm_reference,
                  "With --arm: compare the joints with the commands' plans or the controller's desired state")
      ->capture_default_str()
      ->check(CLI::IsMember({"commanded", "desired"}));
  cmd->add_option("--arm-command", o->arm_command,
                  "With --arm: the channel of joint trajectory commands (default: the one with the most)");
  cmd->add_option("--arm-ee", o->arm_ee, "With --arm: the end effector's ground truth channel (default: found)");
  cmd->add_option("--arm-base", o->arm_base, "With --arm: the arm base's ground truth channel (default: found)");
  cmd->add_option("--arm-cutoff", o->arm_cutoff,
                  "With --arm: the end effector's motion above this frequency is reported as oscillation [Hz]")
      ->capture_default_str()
      ->check(in_range(config::above(0, 50), "Hz"));
  add_json_options(cmd, &o->json, "the results");
  cmd->callback([o, exit_code] {
    if (o->delta_unit == "frames" && std::floor(o->delta) != o->delta) {
      *exit_code = fail("--delta must be a whole number of frames, got " + short_number(o->delta));
      return;
    }
    // An angle between two rotations lies in [0, 180] degrees (evo refuses other deltas too).
    if ((o->delta_unit == "deg" && o->delta > 180) || (o->delta_unit == "rad" && o->delta > M_PI)) {
      *exit_code = fail("--delta in " + o->delta_unit + " must be at most " + (o->delta_unit == "deg" ? "180" : "pi") +
                        " (the largest angle between two rotations), got " + short_number(o->delta));
      return;
    }
    *exit_code = run_eval(*o);
  });
}

}  // namespace driftlab::apps
