// 2D lidar SLAM as a pose graph over keyframes (the 2D SLAM module's default method; docs/slam.md):
//   front end: each scan matched with MRPT's ICP against a local map (the points of the last keyframes at their
//              graph poses), starting from the previous pose moved by the wheel odometry; with match_odometry,
//              the match and that prediction combined by the information of each (combine);
//   keyframes: a scan becomes a graph node when the robot has moved far enough from the last one; consecutive
//              nodes are joined by the front end's relative pose;
//   loops:     each new keyframe is matched against the old keyframe the graph places nearest, if the drift since
//              the graph last tied the two places together can explain the distance (a radius growing with the
//              graph distance between them). Near, ICP from the estimate; far, a correlative search of the whole
//              window (correlative_matcher.h), widened once when its best pose lies near the window's edge (the
//              place may lie beyond it). A match is kept when it overlaps the old place, has a unique optimum
//              in the directions the geometry pins down, and, if it moves the estimate much, a second match from
//              one of the next keyframes agrees with it; its information comes from what the geometry pins down
//              (little along a corridor). After optimising, a loop edge the rest of the graph contradicts is
//              taken out again;
//   back end:  the pose graph, optimised (pose_graph.h) when a loop edge disagrees with the estimate,
//              and once more at the end, when the closures the others then contradict are undone.
// A scan's pose is kept relative to the keyframe it was matched after, so the whole trajectory follows the
// keyframes whenever the graph is optimised. Deterministic. Not thread-safe: one caller.
#pragma once

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/poses/CPose2D.h>

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <optional>
#include <queue>
#include <string>
#include <utility>
#include <vector>

#include "core/quantile.h"
#include "slam/internal/point_maps.h"
#include "slam/internal/pose_graph.h"

namespace driftlab::slam::internal {

/// Distances in m, angles in rad. The values here are the module's defaults; docs/slam.md says why.
struct ScanGraphOptions {
  // Front end.
  double keyframe_distance = 0.5;         ///< a new keyframe after this much travel since the last ...
  double keyframe_angle = 0.35;           ///< ... or this much turning
  int local_map_keyframes = 10;           ///< keyframes in the local map the front end matches against
  double min_icp_goodness = 0.4;          ///< below it the front end keeps the odometry's prediction [0, 1]
  double min_dist_between_points = 0.05;  ///< points closer than this in a scan are merged
  /// The odometry weighed into each match (slam.2d.match_odometry; docs/slam.md, "Odometry in the match"): the
  /// match and the odometry's prediction combined by their information, so that along a featureless corridor,
  /// where the match pins nothing down, the odometry's motion stands.
  bool match_odometry = false;
  double match_sigma = 0.15;  ///< the noise of a point's distance to its wall that a match's information assumes
  /// The odometry's noise over a step: m per m of travel, m, rad per rad of turn, rad (standard deviations).
  std::array<double, 4> odometry_noise = {0.05, 0.01, 0.05, 0.005};
  double still_distance = 0.005;          ///< odometry moving less than this since the last matched scan ...
  double still_angle = 0.005;             ///< ... and turning less: standing still, the scan is not matched
  IcpOptions icp;                         ///< the front end's ICP (also the loop matches' final step)
  // Loop closure: which old place.
  bool loop_closure = true;
  double loop_min_travel = 10;        ///< path between two keyframes before they may close a loop
  double loop_radius = 1.5;           ///< the old keyframe must be within this of the estimate ...
  double loop_drift = 0.05;           ///< ... plus this share of the graph distance between the two ...
  double loop_max_radius = 16;        ///< ... and never further
  double loop_far_radius = 2.5;       ///< beyond this radius, a correlative search instead of ICP from the estimate
  double loop_far_yaw = 0.35;         ///< the correlative search's turn window (+-)
  bool loop_rescue_near = false;      ///< a near test whose ICP left the reach searches its window correlatively
  bool loop_seen_only = false;        ///< a near test's ICP takes only the current points an old scan could see
  double loop_edge = 0.8;             ///< its best pose beyond this share of the window (in x, y or turn) ...
  double loop_widen = 1.5;            ///< ... searches again in a window this much wider (at most loop_max_radius)
  double loop_grid_resolution = 0.1;  ///< of its likelihood grid ...
  int loop_grid_levels = 4;           ///< ... and coarse levels above it (the top one 2^4 cells: 1.6 m)
  int loop_search_points = 200;       ///< current points it scores per pose
  double loop_ambiguity = 0.9;        ///< another place 0.5 m away scoring this share of the best: ambiguous
  int loop_submap_keyframes = 4;      ///< near: keyframes on either side of the candidate in the old place
  int loop_query_keyframes = 3;       ///< the last keyframes matched against it
  double loop_threshold_ang = 0.087;  ///< near: the first ICP's angular correspondence threshold
  // Loop closure: when a match counts.
  double loop_min_goodness = 0.65;  ///< share of the current points with an old point within loop_match_distance
  double loop_match_distance = 0.15;
  double loop_min_points = 60;          ///< matched points a loop match needs
  double loop_min_constraint = 0.1;     ///< the weakest direction's share of the point-to-line information; below:
                                        ///< a corridor (0.15 and 0.2 let a corridor's lookalikes in: docs/slam.md,
                                        ///< "Where MIT Killian Court misses the bar")
  double loop_uniqueness = 0.3;         ///< restarts this far off must come back to the same pose
  double loop_confirm_xy = 0.5;         ///< a match moving the estimate further ...
  double loop_confirm_yaw = 0.09;       ///< ... or turning it more waits for a second one ...
  int loop_confirm_keyframes = 5;       ///< ... from one of the next keyframes ...
  double loop_consistency_xy = 0.2;     ///< ... that places this stretch within this ...
  double loop_consistency_yaw = 0.035;  ///< ... and this of where the first one put it
  double loop_max_chi2 = 20;            ///< a loop edge left with a larger error after optimising is taken out
  // Back end.
  double edge_sigma_xy = 0.02;           ///< standard deviation of an edge's x and y
  double edge_sigma_yaw = 0.007;         ///< and of its yaw (0.4 degrees)
  double optimize_threshold_xy = 0.05;   ///< a loop edge off by more than this triggers optimisation ...
  double optimize_threshold_yaw = 0.02;  ///< ... or by more than this
};

/// Every loop test ends in one of accepted, low_overlap, ambiguous, not_unique, refused_chi2 and unconfirmed, so
/// loop_tests = loop_closures + loop_undone + loop_rejected_goodness + loop_rejected_unique + loop_rejected_chi2 +
/// loop_unconfirmed.
struct ScanGraphStats {
  int64_t scans = 0, matched = 0, unmatched = 0, still = 0, keyframes = 0;
  int64_t loop_tests = 0, loop_closures = 0, loop_rejected_goodness = 0, loop_rejected_unique = 0,
          loop_rejected_chi2 = 0, loop_undone = 0, loop_unconfirmed = 0, optimisations = 0;
  int64_t weighed = 0;  ///< matches with the odometry weighed in (match_odometry)
};

/// What became of one loop test, and why (published by the module as driftlab.loop_closure_t). A test's record
/// comes when it is decided; a match waiting for its second one gives a `waiting` record first, then its final
/// one; an accepted closure undone at the end gives an `undone` record.
struct LoopRecord {
  enum class Outcome { accepted, waiting, low_overlap, ambiguous, not_unique, refused_chi2, unconfirmed, undone };
  size_t keyframe = 0, old_keyframe = 0;  ///< current and old keyframe
  bool far = false;                       ///< a correlative search of the window, not ICP from the estimate
  bool rescued = false;                   ///< far: a near test's, its ICP having left the reach (loop_rescue_near)
  double radius = 0;                      ///< the search's reach [m]
  Outcome outcome = Outcome::accepted;
  std::string reason;               ///< the figures that decided it (one line, no commas)
  mrpt::poses::CPose2D correction;  ///< the match's pose seen from the graph's estimate of the current keyframe
  mrpt::poses::CPose2D measured;    ///< the current keyframe seen from the old one (the edge)
  double overlap = 0;               ///< share of the current points with an old point within loop_match_distance
  int64_t pairs = 0;                ///< those points
  double chi2 = 0;                  ///< refused_chi2, undone: the edge's error at the optimum
};
const char* outcome_name(LoopRecord::Outcome outcome);

/// The points of `query` (in the frame of `pose`) that at least one of `scans`, each at its base's pose in the map,
/// could have seen: within its aperture, and not further than its beam at that bearing, or the one either side, hit
/// plus `margin` (a beam with no return sees as far as the scanner's range). A loop test's old place seen from the
/// other way along a corridor saw only part of what the current scans see (ScanGraphOptions::loop_seen_only).
mrpt::maps::CSimplePointsMap seen_points(
    const std::vector<std::pair<const mrpt::obs::CObservation2DRangeScan*, mrpt::poses::CPose2D>>& scans,
    const mrpt::maps::CSimplePointsMap& query, const mrpt::poses::CPose2D& pose, double margin);

/// The information (inverse covariance; x, y, yaw) of an odometry step, from its noise model
/// (ScanGraphOptions::odometry_noise): the same in x and y.
Eigen::Matrix3d odometry_information(const mrpt::poses::CPose2D& step, const std::array<double, 4>& noise);

/// One pose from two estimates of it, each with its information (x, y, yaw in the map frame; yaw about the pose's
/// position): the minimum of the two quadratic costs, linearised at `a`. Where a's information is large b moves it
/// little; where it is next to none (a corridor's axis for a scan match) b's value stands.
mrpt::poses::CPose2D combine(const mrpt::poses::CPose2D& a, const Eigen::Matrix3d& a_information,
                             const mrpt::poses::CPose2D& b, const Eigen::Matrix3d& b_information);

class ScanGraph {
 public:
  explicit ScanGraph(const ScanGraphOptions& options);

  /// Adds a scan (sensor pose inside `scan`), with the wheel odometry's pose at its stamp when there is one.
  /// Returns the base's pose in the map frame (the first scan's base is the origin) and the front end's
  /// covariance of it (x, y, yaw; zero when the scan could not be matched).
  mrpt::poses::CPose2D add(int64_t stamp, const mrpt::obs::CObservation2DRangeScan::Ptr& scan,
                           const std::optional<mrpt::poses::CPose2D>& odometry,
                           mrpt::math::CMatrixDouble33* covariance = nullptr);

  /// Optimises the whole graph once more (call at the end).
  void finish();

  /// Every scan's pose after the latest optimisation, in stamp order.
  std::vector<std::pair<int64_t, mrpt::poses::CPose2D>> trajectory() const;

  struct Keyframe {
    int64_t stamp = 0;
    mrpt::obs::CObservation2DRangeScan::Ptr scan;
    mrpt::maps::CSimplePointsMap points;  ///< the scan's points in the base frame
    double path = 0;                      ///< distance travelled (keyframe to keyframe) when it was made [m]
  };
  const std::vector<Keyframe>& keyframes() const { return keyframes_; }
  mrpt::poses::CPose2D keyframe_pose(size_t i) const;
  const ScanGraphStats& stats() const { return stats_; }
  /// Whether the odometry's heading is as good as its noise model (odometry_noise) says, from every scan matched
  /// with an odometry step: z = |the match's heading - the odometry's prediction's| over the heading noise the model
  /// gives that step (5% of its turn + 0.005 rad). Were the model true, z would be half-normal, 90% of it under
  /// 1.645. Their 90th percentile, once kMinHeadingChecks scans are in; how many there are.
  static constexpr size_t kMinHeadingChecks = 100;
  std::optional<double> odometry_heading_q90() const;
  size_t odometry_heading_checks() const { return heading_z_.size(); }
  /// The loop records since the last call, in the order they were decided.
  std::vector<LoopRecord> take_loop_records() { return std::exchange(records_, {}); }

 private:
  struct ScanRecord {
    int64_t stamp;
    uint32_t keyframe;
    mrpt::poses::CPose2D relative;  ///< the scan's pose in its keyframe's frame
  };
  struct LoopEdge {
    LoopRecord record;  ///< its keyframes (old_keyframe, keyframe) and the edge (measured)
    PoseGraph2d::Information information;
  };
  struct Closure {
    size_t edge;  ///< the edge in the graph
    LoopRecord record;
  };
  void add_keyframe(int64_t stamp, const mrpt::obs::CObservation2DRangeScan::Ptr& scan,
                    const mrpt::maps::CSimplePointsMap& points, const mrpt::poses::CPose2D& pose);
  void rebuild_local_map();
  /// The matched pose with the odometry's prediction weighed in (match_odometry).
  mrpt::poses::CPose2D weigh_in_odometry(const mrpt::poses::CPose2D& matched,
                                         const mrpt::maps::CSimplePointsMap& points,
                                         const mrpt::poses::CPose2D& predicted, const mrpt::poses::CPose2D& step);
  void close_loops();
  /// j: the candidate keyframe; widened: the far search's window (radius, turn) is loop_widen times the usual;
  /// rescue: a near test's window searched as a far one (loop_rescue_near).
  bool try_loop(size_t j, double radius, bool widened = false, bool rescue = false);
  bool add_loops(std::vector<LoopEdge> loops);
  void record(LoopRecord r, LoopRecord::Outcome outcome, std::string reason);
  /// The length of the shortest path through the graph from one keyframe to others (loop edges counting as the
  /// short links they are), or, where that is long enough to give the loop search its largest reach, some length at
  /// least that long: Dijkstra's, run only as far as each question needs.
  class GraphDistances {
   public:
    GraphDistances(const ScanGraph& graph, size_t from);
    double to(uint32_t target);

   private:
    using Item = std::pair<double, uint32_t>;
    const ScanGraph& g_;
    std::vector<double> d_;
    std::vector<uint8_t> done_;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue_;
  };
  mrpt::maps::CSimplePointsMap points_of(const mrpt::obs::CObservation2DRangeScan& scan) const;

  ScanGraphOptions o_;
  PoseGraph2d graph_;
  std::vector<Keyframe> keyframes_;
  std::vector<std::vector<std::pair<uint32_t, double>>> adjacency_;  ///< neighbour, length of the edge [m]
  std::vector<ScanRecord> scans_;
  GridPointsMap local_map_;  ///< in the map frame
  uint32_t current_keyframe_ = 0;
  mrpt::poses::CPose2D relative_;  ///< the last scan's pose in its keyframe's frame
  uint32_t matched_keyframe_ = 0;  ///< the last matched scan's keyframe ...
  mrpt::poses::CPose2D matched_;   ///< ... and its pose in that keyframe's frame
  std::optional<mrpt::poses::CPose2D> last_odometry_;
  std::vector<LoopEdge> pending_;  ///< large corrections waiting for a second match
  std::vector<Closure> closures_;  ///< every loop edge accepted
  std::vector<LoopRecord> records_;
  ScanGraphStats stats_;
  /// odometry_heading_q90's z, one per scan matched with an odometry step: the figure is asked for at every
  /// statistics message, and a selection over them all each time made a long log's replay quadratic.
  RunningQuantile<float> heading_z_{0.9};
};

}  // namespace driftlab::slam::internal
