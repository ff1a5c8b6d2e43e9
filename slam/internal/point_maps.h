#pragma once
// Keeping the ICP builder's points maps honest about their nearest-neighbour index.
#include <mrpt/maps/CMultiMetricMap.h>
#include <mrpt/maps/CPointsMap.h>

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

}  // namespace driftlab::slam::internal
