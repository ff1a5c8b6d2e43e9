#pragma once
// Points maps for the 2D SLAM: keeping the ICP builder's maps honest about their nearest-neighbour index, and a
// points map whose ICP correspondences come from a grid instead of a kd-tree, with MRPT's classic ICP on it, step
// for step, for a caller that wants to stop it early.
#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/maps/CMultiMetricMap.h>
#include <mrpt/maps/CPointsMap.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/poses/CPose2D.h>

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace driftlab::slam::internal {

/// Tells every points map in `maps` that its points changed, so its kd-tree is rebuilt at the next query.
/// Needed after an insertion with fuseWithExisting: MRPT's CPointsMap::fuseWith marks the map modified *before*
/// it matches the new scan against the map (which builds the kd-tree from the old points), then moves fused points
/// and appends new ones with the unchecked setters and never marks it again. The index stays the one of the map
/// before the insertion, so the ground just added is invisible to the next scan's ICP and fused points are found at
/// their old places. Rebuilding costs one kd-tree build per map update (keyframe), not per scan.
inline void mark_point_maps_modified(const mrpt::maps::CMultiMetricMap& maps) {
  for (const auto& m : maps.maps) {
    if (const auto* points = dynamic_cast<const mrpt::maps::CPointsMap*>(m.get())) points->mark_as_modified();
  }
}

/// A points map whose 2D matching (what MRPT's ICP calls once per iteration, with this map as the reference) finds
/// each point's nearest neighbour in a uniform grid of the map's points instead of MRPT's kd-tree: the same
/// correspondences, distances and ratios as CPointsMap::determineMatching2D (the same float arithmetic; of points
/// at exactly the same distance, the one first in the map, where the kd-tree takes the first it reaches: a pure
/// function of the two maps and the pose, whatever was matched before), faster: the search stops at the matching's
/// distance limit instead of finding the nearest point however far, and the index is built in one counting pass
/// instead of a kd-tree's sorting. The 2D SLAM's front end matches every scan against such a map, and its loop
/// tests too; their kd-trees are no longer built for it. A point that moved little since the last matching against
/// the same grid (the ICP's next iteration) keeps its nearest map point without a search when the bounds found
/// then prove it (determineMatching2D).
///
/// The grid is built at the first matching after the points change size (or the map is cleared): fill the map,
/// then match. Changing points in place (setPoint) without changing the count is not seen; nothing here does.
class GridPointsMap : public mrpt::maps::CSimplePointsMap {
 public:
  void determineMatching2D(const mrpt::maps::CMetricMap* other, const mrpt::poses::CPose2D& other_pose,
                           mrpt::tfest::TMatchingPairList& pairs, const mrpt::maps::TMatchingParams& params,
                           mrpt::maps::TMatchingExtraResults& extra) const override;

  /// The map's point nearest to (x, y) if its squared distance (in float, as nanoflann's) is below limit², else -1.
  int64_t nearest(float x, float y, double limit, float& distance2) const;

  /// The map's `k` points nearest to (x, y), nearest first, into `out` (indices in the map), when MRPT's kd-tree
  /// (kdTreeNClosestPoint2DIdx, nanoflann) gives exactly these: the same squared distances in float, so the same
  /// points in the same order whenever none of the k + 1 nearest lie at exactly the same distance as another. When
  /// two do, which of them the kd-tree returns, and in which order, depends on its tree: then false, `out` empty,
  /// and the caller asks the kd-tree (as it does for a map with fewer than k points). Faster than the kd-tree for a
  /// map queried a few hundred times: its grid is built already, where the kd-tree would be built for them.
  bool nearest_k(float x, float y, size_t k, std::vector<size_t>& out) const;

  /// How the matchings on this thread found their points' nearest map points so far: searched in the grid, or
  /// proved without a search (the point had moved too little since its last search to have another nearest).
  struct Lookups {
    uint64_t searched = 0, proved = 0;
  };
  static Lookups lookups();

  struct Grid;  ///< the index (point_maps.cc)

 protected:
  void internal_clear() override;

 private:
  const Grid& grid() const;
  mutable std::shared_ptr<const Grid> grid_;  ///< built lazily; shared by copies until either changes
};

/// The settings of MRPT's classic ICP (mrpt::slam::CICP::TConfigParams' members of the same names and defaults, the
/// ones its classic method reads), so that the graph method needs no part of MRPT's SLAM library.
struct IcpOptions {
  unsigned int maxIterations = 40;
  double minAbsStep_trans = 1e-6, minAbsStep_rot = 1e-6;          ///< a step smaller than both shrinks the thresholds
  double thresholdDist = 0.75, thresholdAng = 0.15 * M_PI / 180;  ///< the first matching's limits (m, rad)
  double ALFA = 0.5;                                              ///< the thresholds' shrink factor
  double smallestThresholdDist = 0.1;                             ///< thresholds shrunk below this: converged
  bool onlyUniqueRobust = false;                                  ///< a map point matched by one query point at most
  uint32_t corresponding_points_decimation = 5;
  enum class Covariance { linear_mse = 0, finite_differences = 1 };
  Covariance covariance_method = Covariance::finite_differences;
  double covariance_varPoints = 0.02 * 0.02;  ///< linear_mse: a point's variance
  double kernel_rho = 0.07;                   ///< finite_differences: the robust kernel's scale (m) ...
  bool use_kernel = true;                     ///< ... and whether it is applied
  bool skip_cov_calculation = false;

  /// Reads `section` of an MRPT .ini file as CICP::TConfigParams::loadFromConfigFile does: the same keys, the
  /// same parsing (numbers read as float, thresholdAng_DEG in degrees), a key absent keeping its value. Throws
  /// std::runtime_error naming the key for what only another ICP would do (ICP_algorithm other than icpClassic,
  /// doRANSAC) and for a value MRPT would reject.
  void load(const mrpt::config::CConfigFileBase& ini, const std::string& section);
};

/// What icp_align found: the pose, the last matching's share of query points matched (CICP's `goodness`), the
/// iterations, and the pose's covariance as CICP computes it (zero when skipped or when nothing matched).
struct IcpResult {
  mrpt::poses::CPose2D pose;
  float goodness = 1;
  unsigned int iterations = 0;
  mrpt::math::CMatrixDouble33 covariance;
};

/// MRPT's classic ICP (CICP::ICP_Method_Classic: each point of `query` at the pose matched to its nearest point of
/// `reference` within the thresholds, the pose by least squares in closed form, the thresholds shrunk by ALFA
/// whenever a step moves less than minAbsStep, until smallestThresholdDist or maxIterations), step for step the same
/// floats as CICP::Align with these options, goodness and covariance included. `settled`, if given, is asked after
/// each iteration whether the pose reached is all the caller needs to know; if it says so, the ICP stops there.
IcpResult icp_align(const GridPointsMap& reference, const mrpt::maps::CSimplePointsMap& query,
                    const mrpt::poses::CPose2D& start, const IcpOptions& options,
                    const std::function<bool(const mrpt::poses::CPose2D&)>& settled = nullptr);

/// icp_align without the covariance: only the pose.
mrpt::poses::CPose2D icp_classic(const GridPointsMap& reference, const mrpt::maps::CSimplePointsMap& query,
                                 const mrpt::poses::CPose2D& start, const IcpOptions& options,
                                 const std::function<bool(const mrpt::poses::CPose2D&)>& settled = nullptr);

}  // namespace driftlab::slam::internal
