// Trajectory evaluation against a reference: association by time, alignment, absolute and relative pose error,
// and KITTI-style drift. The semantics follow evo (evo_ape / evo_rpe) so that numbers agree with it; where evo
// has no equivalent (posyaw alignment, interpolated matching, RPE in seconds, drift), docs/cli.md says what
// driftlab does. Thread-safety: pure functions over values.
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "core/huge_page_allocator.h"

namespace driftlab::analyzers {

/// Arrays of poses can hold millions of entries: they live on huge pages.
template <typename T>
using PoseArray = HugeVector<T>;

/// Poses of a body over time.
struct Trajectory {
  PoseArray<double> stamps;                      ///< [s]
  PoseArray<Eigen::Vector3d> positions;          ///< [m]
  PoseArray<Eigen::Quaterniond> orientations;    ///< unit quaternions
  /// False for poses without stamps (a KITTI file without its times): stamps are then the pose indices.
  bool stamped = true;
  size_t size() const { return stamps.size(); }
  void push_back(double stamp, const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
    stamps.push_back(stamp);
    positions.push_back(p);
    orientations.push_back(q);
  }
  /// Length of the path through all positions [m].
  double path_length() const;
};

/// How a trajectory's stamps were ordered before sort_by_stamp.
struct StampOrder {
  size_t out_of_order = 0;      ///< poses stamped earlier than the pose before them [count]
  double first_out_of_order = 0;  ///< the stamp of the first of them [s]
  size_t repeated = 0;          ///< poses stamped exactly as the pose before them (after sorting) [count]
  double first_repeated = 0;    ///< the stamp of the first of them [s]
};
/// Sorts t's poses by stamp, keeping the file order among equal stamps (so matching still takes the first of
/// them, as evo does), and says what it found.
StampOrder sort_by_stamp(Trajectory& t);

/// Error statistics; std is the population standard deviation, median the 0.5 quantile of core/quantile.h (numpy's
/// np.quantile; evo's np.median averages the two middle errors instead, which can differ in the last bit).
struct Stats {
  size_t count = 0;
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0;
};
Stats compute_stats(PoseArray<double> errors);

/// Two trajectories of equal length whose poses i belong together; match_* and apply() give unit orientations,
/// which ape, rpe and drift expect.
struct Matched {
  Trajectory ref;
  Trajectory est;
};

/// evo's association: for each stamp of the trajectory with fewer poses, the nearest stamp of the other (the first
/// on ties; a pose of the longer one may be used twice), kept when at most max_dt [s] apart. offset [s] is added
/// to the estimate's stamps. A linear merge over stamps sorted once: O((n + m) log m) for unsorted input.
Matched match_nearest(const Trajectory& ref, const Trajectory& est, double max_dt, double offset);

/// The reference interpolated at each estimate stamp (+ offset): linear in position, slerp in orientation,
/// between the two reference poses around it when they are at most max_gap [s] apart.
Matched match_interpolated(const Trajectory& ref, const Trajectory& est, double max_gap, double offset);

/// Why nothing matched, in one line: both time ranges, the closest pair, and a suggested --offset.
std::string explain_no_match(const Trajectory& ref, const Trajectory& est, double max_dt, double offset);

/// kOrigin: evo's --align_origin (the estimate moved rigidly so that its first matched pose is the reference's).
enum class AlignmentType { kNone, kSe3, kSim3, kPosYaw, kOrigin };
const char* to_string(AlignmentType type);

/// est -> ref: p' = scale * rotation * p + translation.
struct Alignment {
  AlignmentType type = AlignmentType::kNone;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double scale = 1.0;
  /// Why no alignment could be found, with the identity kept: the matched positions are too few, or all on one
  /// point or one line (evo refuses these: "degenerate covariance rank"); empty when aligned.
  std::string problem;
};

/// Least-squares alignment of est's positions onto ref's (Umeyama; posyaw: translation and yaw about z only), or
/// (origin) the rigid motion T_ref0 T_est0^-1 of the first matched poses, as evo's align_origin (needs one pose).
/// Needs at least 3 matched poses (2 for posyaw) spanning more than a line (for posyaw, not all on one vertical);
/// otherwise the identity with `problem` set. posyaw with one side standing still in x and y (a frozen estimate)
/// matches the means with yaw 0: the position error is the same for every yaw.
Alignment align(const Matched& m, AlignmentType type);
/// est with the alignment applied: positions scaled, rotated and moved; orientations rotated.
Trajectory apply(const Alignment& a, Trajectory t);

/// Absolute pose error per matched pose: translation distance [m] and rotation angle of Q^-1 P [deg].
struct ApeResult {
  Stats trans;
  Stats rot_deg;
  PoseArray<double> trans_errors;
  PoseArray<double> rot_errors_deg;
};
ApeResult ape(const Matched& aligned);

enum class DeltaUnit { kFrames, kMeters, kSeconds, kDegrees, kRadians };
const char* to_string(DeltaUnit unit);

/// How the pairs of poses of the relative pose error are chosen, as evo's RPE does (evo.core.filters).
struct RpeOptions {
  double delta = 1;                       ///< in `unit`
  DeltaUnit unit = DeltaUnit::kFrames;
  bool all_pairs = false;                 ///< every pair delta apart, not consecutive ones
  bool pairs_from_reference = false;      ///< choose pairs along the reference's path (evo's default: the estimate's)
  double delta_tol = 0.1;                 ///< all pairs by distance or angle: accepted miss, relative to delta
};

/// Relative pose error of (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) over pairs (i, j) chosen along the estimate's poses (or the
/// reference's) as evo does:
/// - frames: (0, d), (d, 2d), ...; all pairs: every (i, i + d);
/// - metres (path travelled) and seconds (time, not in evo): the poses where the distance since the previous one
///   reaches d, taken as consecutive pairs (so the first pair need not start at pose 0); all pairs: from each pose
///   i, the later pose j whose distance from i is closest to d (the first on ties), kept when it misses d by at most
///   delta_tol * d;
/// - degrees and radians: consecutive pairs from pose 0 where the rotation angles between consecutive poses add up
///   to d; all pairs: every (i, j > i) whose direct rotation angle is within delta_tol * d of d (O(n^2), as evo).
struct RpeResult {
  RpeOptions options;
  std::vector<std::pair<size_t, size_t>> pairs;
  Stats trans;    ///< count 0 when there is no pair
  Stats rot_deg;
};
RpeResult rpe(const Matched& aligned, const RpeOptions& options);

/// KITTI-style drift: from every step-th pose, the first pose at least L metres further along the reference
/// path; error of that segment relative to L.
struct DriftSegment {
  double length_m = 0;
  size_t count = 0;
  double trans_pct = 0;        ///< mean translation error [% of distance travelled]
  double rot_deg_per_m = 0;    ///< mean rotation error [deg per metre travelled]
};
struct DriftResult {
  std::vector<DriftSegment> segments;
  size_t count = 0;            ///< segments over all lengths
  double trans_pct = 0;        ///< mean over all segments [%]
  double rot_deg_per_m = 0;    ///< mean over all segments [deg/m]
};
/// lengths [m]; empty: 10, 20, 30, 40 and 50% of the reference path, to two significant digits.
DriftResult drift(const Matched& aligned, std::vector<double> lengths, size_t step = 10);

/// Angle of the rotation a unit quaternion represents [rad], in [0, pi], accurate near 0 and pi.
double rotation_angle(const Eigen::Quaterniond& q);

}  // namespace driftlab::analyzers
