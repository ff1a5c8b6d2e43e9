#include "analyzers/evaluate.h"

#include <cstdio>
#include <future>

#include "analyzers/correlation.h"
#include "core/config.h"

namespace driftlab::analyzers {
namespace {

/// Puts a loaded trajectory in stamp order and checks its stamps: out-of-order poses are sorted (said in a note),
/// poses sharing the stamp before them are kept (matching takes the first, as evo does; said in a note), and a
/// trajectory whose stamps mostly repeat is refused: frozen stamps, which no matching can tell apart.
Status put_in_order(const std::string& what, const std::string& src, Trajectory& t, Evaluation& ev) {
  if (!t.stamped) return {};
  const StampOrder order = sort_by_stamp(t);
  char buf[512];
  if (order.repeated * 2 > t.size()) {
    std::snprintf(buf, sizeof(buf),
                  "%s %s: %zu of %zu poses carry the stamp of the pose before them (the first at %.6f s): frozen "
                  "stamps (a stamp set once, or one time given to every pose), which leave nothing to match in time",
                  what.c_str(), src.c_str(), order.repeated, t.size(), order.first_repeated);
    return Error{buf};
  }
  if (order.out_of_order > 0) {
    const bool one = order.out_of_order == 1;
    std::snprintf(buf, sizeof(buf),
                  "%s %s: %zu pose%s stamped earlier than the pose before %s (the first at %.6f s); sorted by stamp",
                  what.c_str(), src.c_str(), order.out_of_order, one ? " was" : "s were", one ? "it" : "them",
                  order.first_out_of_order);
    ev.notes.emplace_back(buf);
    if (ev.options.on_note) ev.options.on_note(buf);
  }
  if (order.repeated > 0) {
    const bool one = order.repeated == 1;
    std::snprintf(buf, sizeof(buf),
                  "%s %s: %zu pose%s %s stamp with the pose before %s (the first at %.6f s); matching takes the first "
                  "of them, as evo does",
                  what.c_str(), src.c_str(), order.repeated, one ? "" : "s", one ? "shares its" : "share their",
                  one ? "it" : "them", order.first_repeated);
    ev.notes.emplace_back(buf);
    if (ev.options.on_note) ev.options.on_note(buf);
  }
  return {};
}

/// The relation error of the estimate.
Status evaluate_relations(const EvaluateOptions& o, const Trajectory& est, Evaluation& ev) {
  if (!est.stamped) {
    return Error{"--est " + o.est_name +
                 ": relations are found by stamp, and these poses have none (give --est-times)"};
  }
  auto pending_odometry = std::async(std::launch::async, [&]() -> Result<Trajectory> {
    if (o.odometry.empty()) return Trajectory{};
    return load_trajectory(o.odometry);
  });
  auto relations = load_relations(o.relations);
  auto odometry = pending_odometry.get();
  if (!relations) return relations.error();
  if (!odometry) return odometry.error();
  if (!odometry->stamped) return Error{"--relations-odometry " + o.odometry + ": odometry without stamps"};
  if (Status s = put_in_order("--relations-odometry", o.odometry, *odometry, ev); !s) return s;
  RelationOptions options;
  options.max_dt = o.relations_max_dt;
  options.odometry = o.odometry.empty() ? nullptr : &*odometry;
  ev.relations = relation_error(est, *relations, options);
  if (ev.relations->used == 0) {
    return Error{o.relations + ": no relation has estimate poses at both of its stamps (within --relations-max-dt " +
                 config::format_number(o.relations_max_dt) + " s" +
                 (o.odometry.empty() ? "; --relations-odometry can carry the nearest poses to them" : "") + ")"};
  }
  return {};
}

/// The pairs of an unstamped trajectory (KITTI poses without times) with another: pose for pose, as evo compares
/// them.
Status match_by_index(const EvaluateOptions& o, const Trajectory& gt, const Trajectory& est, Matched& m) {
  if (gt.stamped != est.stamped) {
    const bool gt_unstamped = !gt.stamped;
    return Error{std::string(gt_unstamped ? "--gt " + o.gt_name : "--est " + o.est_name) +
                 ": KITTI poses without stamps can only be compared pose for pose with another trajectory without "
                 "stamps; give " +
                 (gt_unstamped ? "--gt-times" : "--est-times") + " FILE (one stamp a line)"};
  }
  if (gt.size() != est.size()) {
    return Error{"--gt " + o.gt_name + " has " + std::to_string(gt.size()) + " poses and --est " + o.est_name + " " +
                 std::to_string(est.size()) +
                 ": without stamps they are compared pose for pose, so they must be as many"};
  }
  if (!o.offset || *o.offset != 0 || o.interpolate) {
    return Error{"--offset and --interpolate need stamps, and KITTI poses without --gt-times/--est-times have none"};
  }
  m.ref = gt;
  m.est = est;
  for (auto* t : {&m.ref, &m.est}) {
    for (auto& q : t->orientations) q.normalize();
  }
  return {};
}

/// The pairs of two stamped trajectories, at the offset given or found.
Status match_by_stamp(const EvaluateOptions& o, const Trajectory& gt, const Trajectory& est, Evaluation& ev) {
  if (!o.offset) {
    ev.offset_auto = estimate_time_offset(gt, est);
    const TimeOffset& a = *ev.offset_auto;
    if (!a.found)
      return Error{"--offset auto: no offset found between " + o.est_name + " and " + o.gt_name + ": " + a.problem};
    if (a.confidence < kConfidentCorrelation) {
      char buf[400];
      std::snprintf(buf, sizeof(buf),
                    "--offset auto: the motions of %s and %s do not line up clearly (best %+.4f s, from the %s, "
                    "confidence %.2f < %.1f): give --offset",
                    o.est_name.c_str(), o.gt_name.c_str(), a.offset_s, a.signal.c_str(), a.confidence,
                    kConfidentCorrelation);
      return Error{buf};
    }
    ev.offset = a.offset_s;
  } else {
    ev.offset = *o.offset;
  }
  ev.matched =
      o.interpolate ? match_interpolated(gt, est, o.max_gap, ev.offset) : match_nearest(gt, est, o.max_dt, ev.offset);
  if (ev.matched.ref.size() == 0) {
    return Error{o.est_name + " against " + o.gt_name + ": " +
                 explain_no_match(gt, est, o.interpolate ? o.max_gap : o.max_dt, ev.offset) +
                 (o.offset ? " (or --offset auto)" : "")};
  }
  return {};
}

}  // namespace

Result<Evaluation> evaluate(const EvaluateOptions& options) {
  Evaluation ev;
  ev.options = options;
  EvaluateOptions& o = ev.options;
  if (o.gt_name.empty()) o.gt_name = o.gt;
  if (o.est_name.empty()) o.est_name = o.est;
  ev.has_reference = !o.gt.empty();
  // The inputs load in parallel: parsing is most of the work on large trajectories.
  auto pending_gt = std::async(std::launch::async, [&]() -> Result<Trajectory> {
    if (!ev.has_reference) return Trajectory{};
    return load_trajectory(o.gt, o.gt_format, o.gt_times);
  });
  auto est = load_trajectory(o.est, o.est_format, o.est_times);
  auto gt = pending_gt.get();
  if (!gt) return gt.error();
  if (!est) return est.error();
  ev.est_poses = est->size();
  ev.gt_poses = gt->size();
  if (Status s = put_in_order("--est", o.est_name, *est, ev); !s) return s.error();
  if (ev.has_reference) {
    if (Status s = put_in_order("--gt", o.gt_name, *gt, ev); !s) return s.error();
  }
  if (!o.relations.empty()) {
    if (Status s = evaluate_relations(o, *est, ev); !s) return s.error();
  }
  if (!ev.has_reference) return ev;

  const Status matched =
      !gt->stamped || !est->stamped ? match_by_index(o, *gt, *est, ev.matched) : match_by_stamp(o, *gt, *est, ev);
  if (!matched) return matched.error();
  ev.alignment = align(ev.matched, o.align);
  if (!ev.alignment.problem.empty()) {
    return Error{std::string("--align ") + to_string(o.align) + " of " + o.est_name + " onto " + o.gt_name + ": " +
                 ev.alignment.problem};
  }
  if (o.align != AlignmentType::kNone) ev.matched.est = apply(ev.alignment, std::move(ev.matched.est));
  ev.ape = ape(ev.matched);
  ev.rpe = rpe(ev.matched, o.rpe);
  ev.drift = drift(ev.matched, o.segments, o.segment_step);
  return ev;
}

nlohmann::json to_json(const Stats& s) {
  if (s.count == 0) return nullptr;
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std}, {"min", s.min}, {"max", s.max}};
}

namespace {

nlohmann::json to_json(const RelationStats& s) { return {{"mean", s.mean}, {"std", s.std}, {"max", s.max}}; }

nlohmann::json relations_json(const EvaluateOptions& o, const RelationResult& r) {
  return {{"source", o.relations},
          {"odometry", o.odometry.empty() ? nlohmann::json(nullptr) : nlohmann::json(o.odometry)},
          {"max_dt", o.relations_max_dt},
          {"relations", r.relations},
          {"used", r.used},
          {"bridged", r.bridged},
          {"max_bridge_s", r.max_bridge_s},
          {"trans_m", to_json(r.trans_m)},
          {"trans_sq_m2", to_json(r.trans_sq_m2)},
          {"rot_deg", to_json(r.rot_deg)},
          {"rot_sq_deg2", to_json(r.rot_sq_deg2)}};
}

}  // namespace

nlohmann::json to_json(const Evaluation& ev) {
  const EvaluateOptions& o = ev.options;
  nlohmann::json j;
  j["estimate"] = {{"source", o.est_name}, {"poses", ev.est_poses}};
  if (ev.has_reference) {
    nlohmann::json rotation = nlohmann::json::array();
    for (int r = 0; r < 3; ++r) {
      rotation.push_back({ev.alignment.rotation(r, 0), ev.alignment.rotation(r, 1), ev.alignment.rotation(r, 2)});
    }
    nlohmann::json segments = nlohmann::json::array();
    for (const auto& s : ev.drift.segments) {
      segments.push_back({{"length_m", s.length_m},
                          {"count", s.count},
                          {"trans_pct", s.trans_pct},
                          {"rot_deg_per_m", s.rot_deg_per_m}});
    }
    const TimeOffset* a = ev.offset_auto ? &*ev.offset_auto : nullptr;
    j["reference"] = {{"source", o.gt_name}, {"poses", ev.gt_poses}};
    j["matching"] = {{"method", !ev.matched.ref.stamped ? "index"
                                : o.interpolate         ? "interpolate"
                                                        : "nearest"},
                     {"max_dt", o.max_dt},
                     {"offset", ev.offset},
                     {"offset_auto", a ? nlohmann::json{{"offset_s", a->offset_s},
                                                        {"confidence", a->confidence},
                                                        {"signal", a->signal},
                                                        {"overlap_s", a->overlap_s}}
                                       : nlohmann::json(nullptr)}};
    j["matched"] = ev.matched.ref.size();
    j["alignment"] = {
        {"type", to_string(ev.alignment.type)},
        {"rotation", rotation},
        {"translation", {ev.alignment.translation.x(), ev.alignment.translation.y(), ev.alignment.translation.z()}},
        {"scale", ev.alignment.scale}};
    j["ate"] = to_json(ev.ape.trans);
    j["ate_rot_deg"] = to_json(ev.ape.rot_deg);
    j["rpe"] = {{"delta", ev.rpe.options.delta},
                {"unit", to_string(ev.rpe.options.unit)},
                {"all_pairs", ev.rpe.options.all_pairs},
                {"pairs_from", ev.rpe.options.pairs_from_reference ? "reference" : "estimate"},
                {"delta_tol", ev.rpe.options.delta_tol},
                {"pairs", ev.rpe.pairs.size()},
                {"trans", to_json(ev.rpe.trans)},
                {"rot_deg", to_json(ev.rpe.rot_deg)}};
    j["drift"] = {{"trans_pct", ev.drift.trans_pct},
                  {"rot_deg_per_m", ev.drift.rot_deg_per_m},
                  {"count", ev.drift.count},
                  {"step", o.segment_step},
                  {"segments", segments}};
  }
  if (ev.relations) j["relations"] = relations_json(o, *ev.relations);
  j["notes"] = ev.notes;
  return j;
}

Result<EvaluationHeadline> evaluation_headline(const nlohmann::json& eval) {
  try {
    EvaluationHeadline h;
    eval.at("matched").get_to(h.matched);
    eval.at("ate").at("rmse").get_to(h.ate_rmse);
    eval.at("ate").at("max").get_to(h.ate_max);
    eval.at("rpe").at("trans").at("rmse").get_to(h.rpe_rmse);
    return h;
  } catch (const nlohmann::json::exception& e) {
    return Error{std::string("not an evaluation against a reference (driftlab eval --json): ") + e.what()};
  }
}

nlohmann::json to_json(const ArmTracking& a) {
  auto or_null = [](const std::string& s) { return s.empty() ? nlohmann::json() : nlohmann::json(s); };
  nlohmann::json joints = nlohmann::json::array();
  for (const JointTracking& jt : a.joints) {
    joints.push_back(
        {{"name", jt.name},
         {"error_rad", to_json(jt.error_rad)},
         {"mean_signed_rad", jt.mean_signed_rad},
         {"limits", jt.has_position_limits
                        ? nlohmann::json{{"lower", jt.lower}, {"upper", jt.upper}, {"velocity", jt.velocity_limit}}
                        : nlohmann::json()},
         {"reached", {{"min", jt.min}, {"max", jt.max}, {"max_speed", jt.max_speed}}},
         {"beyond", {{"position", jt.beyond_position}, {"velocity", jt.beyond_velocity}}}});
  }
  nlohmann::json ee;
  if (a.ee_position_m.count > 0) {
    ee = {
        {"base_link", a.base_link},
        {"tip_link", a.tip_link},
        {"position_m", to_json(a.ee_position_m)},
        {"rotation_deg", to_json(a.ee_rotation_deg)},
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

}  // namespace driftlab::analyzers
