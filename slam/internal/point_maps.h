#pragma once
// Points maps for the 2D SLAM: keeping the ICP builder's maps honest about their nearest-neighbour index, and a
// points map whose ICP correspondences come from a grid instead of a kd-tree, with MRPT's classic ICP on it, step
// for step, for a caller that wants to stop it early.
#include <mrpt/maps/CMultiMetricMap.h>
#include <mrpt/maps/CPointsMap.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/slam/CICP.h>

#include <cstdint>
#include <functional>
#include <memory>
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

/// MRPT's classic ICP (CICP::ICP_Method_Classic: each point of `query` at the pose matched to its nearest point of
/// `reference` within the thresholds, the pose by least squares in closed form, the thresholds shrunk by ALFA
/// whenever a step moves less than minAbsStep, until smallestThresholdDist or maxIterations), step for step the same
/// floats as CICP::Align with these options: the pose it ends at. `settled`, if given, is asked after each
/// iteration whether the pose reached is all the caller needs to know; if it says so, the ICP stops there.
/// (ICP_algorithm, RANSAC, the covariance and the quality are not looked at: only the pose is returned.)
mrpt::poses::CPose2D icp_classic(const GridPointsMap& reference, const mrpt::maps::CSimplePointsMap& query,
                                 const mrpt::poses::CPose2D& start, const mrpt::slam::CICP::TConfigParams& options,
                                 const std::function<bool(const mrpt::poses::CPose2D&)>& settled = nullptr);

}  // namespace driftlab::slam::internal
