#include "analyzers/evaluate_text.h"

#include <cmath>
#include <cstdio>

#include "core/number_text.h"

namespace driftlab::analyzers {
namespace {

void relations_text(std::string& out, const Evaluation& ev) {
  const RelationResult& r = *ev.relations;
  appendf(out, "relation error (Kuemmerle et al. 2009) of %s over %s of %s relations", ev.options.est_name.c_str(),
          thousands(static_cast<int64_t>(r.used)).c_str(), thousands(static_cast<int64_t>(r.relations)).c_str());
  if (r.bridged > 0) {
    appendf(out, " (%s with a pose carried by odometry, at most %.3f s)",
            thousands(static_cast<int64_t>(r.bridged)).c_str(), r.max_bridge_s);
  }
  appendf(out, "\n%-20s %12s %12s %12s\n", "", "mean", "std", "max");
  const std::pair<const char*, const RelationStats*> rows[] = {{"translation [m]", &r.trans_m},
                                                               {"translation^2 [m^2]", &r.trans_sq_m2},
                                                               {"rotation [deg]", &r.rot_deg},
                                                               {"rotation^2 [deg^2]", &r.rot_sq_deg2}};
  for (const auto& [label, st] : rows) appendf(out, "%-20s %12.6f %12.6f %12.6f\n", label, st->mean, st->std, st->max);
}

void stats_row(std::string& out, const char* label, const Stats& s) {
  appendf(out, "%-16s %10.6f %10.6f %10.6f %10.6f %10.6f %10.6f\n", label, s.rmse, s.mean, s.median, s.std, s.min,
          s.max);
}

void reference_text(std::string& out, const Evaluation& ev) {
  const EvaluateOptions& o = ev.options;
  const std::string matched = thousands(static_cast<int64_t>(ev.matched.ref.size()));
  if (!ev.matched.ref.stamped) {
    appendf(out, "matched %s poses pose for pose (no stamps)\n", matched.c_str());
  } else {
    appendf(out, "matched %s of %s estimated poses with %s reference poses (%s, max dt %g s, offset %.6g s",
            matched.c_str(), thousands(static_cast<int64_t>(ev.est_poses)).c_str(),
            thousands(static_cast<int64_t>(ev.gt_poses)).c_str(), o.interpolate ? "interpolated" : "nearest stamp",
            o.interpolate ? o.max_gap : o.max_dt, ev.offset);
    if (ev.offset_auto) {
      appendf(out, " found from the %s: confidence %.2f over %.1f s", ev.offset_auto->signal.c_str(),
              ev.offset_auto->confidence, ev.offset_auto->overlap_s);
    }
    appendf(out, ")\n");
  }
  const Alignment& a = ev.alignment;
  const Eigen::AngleAxisd aa(a.rotation);
  appendf(out,
          "alignment %s: rotation %.3f deg about (%.3f, %.3f, %.3f), translation (%.4f, %.4f, %.4f) m, scale %.6f\n\n",
          to_string(a.type), aa.angle() * 180 / M_PI, aa.axis().x(), aa.axis().y(), aa.axis().z(), a.translation.x(),
          a.translation.y(), a.translation.z(), a.scale);
  appendf(out, "%-16s %10s %10s %10s %10s %10s %10s\n", "", "rmse", "mean", "median", "std", "min", "max");
  stats_row(out, "ATE [m]", ev.ape.trans);
  stats_row(out, "ATE [deg]", ev.ape.rot_deg);
  const RpeOptions& r = ev.rpe.options;
  const bool one_frame = r.unit == DeltaUnit::kFrames && r.delta == 1;
  char how[160];
  std::snprintf(how, sizeof(how), "%g %s apart along the %s%s", r.delta, one_frame ? "frame" : to_string(r.unit),
                r.pairs_from_reference ? "reference" : "estimate",
                !r.all_pairs                   ? ""
                : r.unit == DeltaUnit::kFrames ? ", all pairs"
                                               : ", all pairs within the tolerance");
  if (ev.rpe.pairs.empty()) {
    appendf(out, "RPE: no pair of poses is %s: try a smaller --delta%s\n\n", how,
            r.all_pairs && r.unit != DeltaUnit::kFrames ? " or a larger --delta-tol" : "");
  } else {
    stats_row(out, "RPE [m]", ev.rpe.trans);
    stats_row(out, "RPE [deg]", ev.rpe.rot_deg);
    appendf(out, "(RPE over %s pairs %s)\n\n", thousands(static_cast<int64_t>(ev.rpe.pairs.size())).c_str(), how);
  }
  if (ev.drift.count == 0) {
    appendf(out, "drift: no segment fits in the reference path (%.3f m)\n", ev.matched.ref.path_length());
    return;
  }
  appendf(out, "drift: %.3f %% of distance, %.5f deg/m (KITTI style: %s segments, one from every %zu poses)\n",
          ev.drift.trans_pct, ev.drift.rot_deg_per_m, thousands(static_cast<int64_t>(ev.drift.count)).c_str(),
          o.segment_step);
  appendf(out, "%12s %10s %10s %12s\n", "length [m]", "segments", "trans [%]", "rot [deg/m]");
  for (const auto& s : ev.drift.segments) {
    appendf(out, "%12.3f %10zu %10.3f %12.5f\n", s.length_m, s.count, s.trans_pct, s.rot_deg_per_m);
  }
}

}  // namespace

std::string evaluation_text(const Evaluation& ev) {
  std::string out;
  if (ev.has_reference) reference_text(out, ev);
  if (ev.relations) {
    if (ev.has_reference) out += "\n";
    relations_text(out, ev);
  }
  return out;
}

std::string arm_tracking_text(const ArmTracking& a) {
  std::string out;
  constexpr double kDeg = 180.0 / M_PI;
  appendf(out, "arm tracking of %s: %s against the %s (%s commands on %s), %.3f to %.3f s\n", a.log.c_str(),
          a.state_channel.c_str(),
          a.reference == ArmReference::kCommanded ? "commanded plans" : "controller's desired state",
          thousands(a.commands).c_str(), a.command_channel.c_str(), a.start_s, a.end_s);
  if (a.reference == ArmReference::kDesired) appendf(out, "(desired state from %s)\n", a.controller_channel.c_str());
  appendf(out, "\n%-16s %10s %10s %10s %22s %22s %16s\n", "joint [deg]", "rmse", "max", "mean", "reached", "limits",
          "speed max/limit");
  for (const JointTracking& j : a.joints) {
    char reached[64], limits[64] = "-", speed[64];
    std::snprintf(reached, sizeof(reached), "%.1f .. %.1f", j.min * kDeg, j.max * kDeg);
    if (j.has_position_limits) std::snprintf(limits, sizeof(limits), "%.1f .. %.1f", j.lower * kDeg, j.upper * kDeg);
    std::snprintf(speed, sizeof(speed), j.velocity_limit > 0 ? "%.2f/%.2f" : "%.2f/-", j.max_speed, j.velocity_limit);
    appendf(out, "%-16s %10.4f %10.4f %+10.4f %22s %22s %16s%s\n", j.name.c_str(), j.error_rad.rmse * kDeg,
            j.error_rad.max * kDeg, j.mean_signed_rad * kDeg, reached, limits, speed,
            j.beyond_position + j.beyond_velocity > 0 ? "  beyond its limits" : "");
  }
  if (a.ee_position_m.count == 0) {
    appendf(out, "\nend effector: %s\n", a.ee_problem.c_str());
    return out;
  }
  appendf(out, "\nend effector %s in %s: FK of the %s joints against %s and %s, %s poses\n", a.tip_link.c_str(),
          a.base_link.c_str(), to_string(a.reference), a.ee_channel.c_str(), a.base_channel.c_str(),
          thousands(static_cast<int64_t>(a.ee_position_m.count)).c_str());
  appendf(out, "%-16s %10s %10s %10s %10s %10s %10s\n", "", "rmse", "mean", "median", "std", "min", "max");
  const Stats& p = a.ee_position_m;
  appendf(out, "%-16s %10.3f %10.3f %10.3f %10.3f %10.3f %10.3f\n", "position [mm]", p.rmse * 1e3, p.mean * 1e3,
          p.median * 1e3, p.std * 1e3, p.min * 1e3, p.max * 1e3);
  stats_row(out, "rotation [deg]", a.ee_rotation_deg);
  appendf(out, "oscillation (the end effector's motion above %g Hz): %.3f mm RMS, strongest at %.2f Hz\n",
          a.oscillation.cutoff_hz, a.oscillation.rms_m * 1e3, a.oscillation.peak_hz);
  return out;
}

}  // namespace driftlab::analyzers
