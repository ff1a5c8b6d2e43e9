// A trajectory's error against a reference, as `driftlab eval` computes it (docs/trajectory-evaluation.md): the
// inputs loaded and put in stamp order, matched (by stamp, or pose for pose without stamps), aligned, and measured
// (ATE, RPE, KITTI-style drift, the SLAM benchmark's relation error); and the JSON `driftlab eval --json` prints.
// The command parses options and prints; the tests and the Python module call this.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "analyzers/arm_tracking.h"
#include "analyzers/relations.h"
#include "analyzers/time_offset.h"
#include "analyzers/trajectory.h"
#include "analyzers/trajectory_io.h"
#include "core/result.h"

namespace driftlab::analyzers {

struct EvaluateOptions {
  /// The reference (empty: the relation error alone) and the estimate: a trajectory file or LOG:CHANNEL of an LCM
  /// log (load_trajectory).
  std::string gt, est;
  /// The inputs as the user named them, in messages and the JSON (default: gt and est).
  std::string gt_name, est_name;
  TrajectoryFormat gt_format = TrajectoryFormat::kAuto, est_format = TrajectoryFormat::kAuto;
  std::string gt_times, est_times;  ///< with KITTI files: their stamps, one a line [s]
  /// Largest stamp difference of a matched pair [s] (nearest-stamp matching, as evo).
  double max_dt = 0.01;
  /// Added to the estimate's stamps before matching [s]; none: found from the motions (estimate_time_offset),
  /// refused below kConfidentCorrelation.
  std::optional<double> offset = 0.0;
  bool interpolate = false;  ///< the reference interpolated at the estimate's stamps, across gaps up to max_gap [s]
  double max_gap = 0.1;
  AlignmentType align = AlignmentType::kNone;
  RpeOptions rpe;
  std::vector<double> segments;  ///< drift's segment lengths [m] (empty: 10..50% of the reference path)
  size_t segment_step = 10;
  /// The SLAM benchmark's relations file (empty: none), the largest stamp difference of a relation and its pose
  /// [s], and raw odometry (a file or LOG:CHANNEL; empty: none) to carry poses to stamps without one.
  std::string relations;
  double relations_max_dt = 1e-4;
  std::string odometry;
  /// Called with each note as it is found (before a later step can fail), besides Evaluation::notes.
  std::function<void(const std::string&)> on_note;
};

struct Evaluation {
  EvaluateOptions options;  ///< as given
  size_t gt_poses = 0, est_poses = 0;
  double offset = 0;  ///< applied to the estimate's stamps [s]
  std::optional<TimeOffset> offset_auto;
  /// What was done to the inputs (sorted, repeated stamps), a line each.
  std::vector<std::string> notes;
  std::optional<RelationResult> relations;
  bool has_reference = false;  ///< false: the relation error alone; the rest is empty
  Matched matched;             ///< after alignment
  Alignment alignment;
  ApeResult ape;
  RpeResult rpe;
  DriftResult drift;
};

/// Errors (ErrorCode::kBadInput), one line naming the input: an input that does not load; frozen stamps (most poses
/// share the stamp before them: nothing to match in time); trajectories that cannot be matched (unstamped against
/// stamped, unequal counts without stamps, no pair within max_dt, no confident offset); an alignment without a
/// solution; relations of which none has estimate poses at both stamps. Out-of-order poses are sorted and poses
/// sharing a stamp kept (matching takes the first, as evo does), each said in `notes`.
Result<Evaluation> evaluate(const EvaluateOptions& options);

/// What `driftlab eval --json` prints: "reference", "estimate", "matching", "matched", "alignment", "ate",
/// "ate_rot_deg", "rpe", "drift" (with a reference), "relations" (with relations) and "notes".
nlohmann::json to_json(const Evaluation& ev);

/// The headline of what to_json gave (`driftlab eval --json-out`), for the demo's summary: poses matched, the
/// ATE's RMSE and maximum and the RPE's translation RMSE [m]. Errors: one line when the JSON is not an evaluation
/// against a reference trajectory.
struct EvaluationHeadline {
  size_t matched = 0;
  double ate_rmse = 0, ate_max = 0, rpe_rmse = 0;
};
Result<EvaluationHeadline> evaluation_headline(const nlohmann::json& eval);

/// What `driftlab eval --arm LOG --json` prints under "arm".
nlohmann::json to_json(const ArmTracking& a);

/// Statistics as JSON: rmse, mean, median, std, min and max; null when there is nothing to take them over.
nlohmann::json to_json(const Stats& s);

}  // namespace driftlab::analyzers
