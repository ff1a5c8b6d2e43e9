// The fused points map's kd-tree: after MRPT's fuseWith (the insertion the ICP builder does with fuse_points) the
// index still describes the map before the insertion until mark_point_maps_modified is called. The grid points
// map: the same correspondences as MRPT's kd-tree matching, and so the same ICP results.
#include <gtest/gtest.h>

#include <mrpt/maps/CMultiMetricMap.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/slam/CICP.h>

#include <cmath>
#include <random>

#include "slam/internal/point_maps.h"

namespace driftlab::slam {
namespace {

TEST(PointMaps, NewGroundIsFoundAfterAFusingInsertion) {
  mrpt::maps::CMultiMetricMap maps;
  auto points = mrpt::maps::CSimplePointsMap::Create();
  maps.maps.push_back(points);
  for (int i = 0; i <= 2; ++i) {  // a 1 m x 1 m grid of 9 points
    for (int j = 0; j <= 2; ++j) points->insertPoint(0.5f * i, 0.5f * j);
  }

  // One scan point inside the map's bounding box (so fuseWith's matching queries, and builds, the kd-tree) that is
  // too far (0.35 m) from any map point to fuse, and new ground 5 m away: both are appended.
  mrpt::maps::CSimplePointsMap scan;
  scan.insertPoint(0.25f, 0.25f);
  scan.insertPoint(5.f, 0.f);
  points->fuseWith(&scan, 0.2f);
  ASSERT_EQ(points->size(), 11u);

  float x = 0, y = 0, d2 = 0;
  // What MRPT leaves behind (if this starts failing, MRPT marks the map itself and the workaround can go): the
  // index built while fuseWith matched still holds the 9 grid points, so the nearest point to (5, 0) is the grid's corner (1, 0), 4 m away.
  points->kdTreeClosestPoint2D(5.f, 0.f, x, y, d2);
  EXPECT_GT(d2, 1.f) << "the kd-tree was not stale after fuseWith";

  internal::mark_point_maps_modified(maps);
  points->kdTreeClosestPoint2D(5.f, 0.f, x, y, d2);
  EXPECT_FLOAT_EQ(x, 5.f);
  EXPECT_FLOAT_EQ(d2, 0.f);
}

// A building's walls as a scanner sees them: segments sampled every few centimetres with a little noise, seen from
// a pose, and a few stray points far out (a reflection through a window) that stretch the map's extent.
mrpt::maps::CSimplePointsMap walls(std::mt19937& rng, double stray) {
  std::normal_distribution<float> noise(0.f, 0.01f);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  mrpt::maps::CSimplePointsMap m;
  const float segments[][4] = {{-4, -3, 6, -3},  {6, -3, 6, 4},       {6, 4, -4, 4}, {-4, 4, -4, -3},
                               {1, -3, 1, 0.5f}, {-2, 1, 2.5f, 1.5f}, {3, 2, 3, 4}};
  for (const auto& seg : segments) {
    const float length = std::hypot(seg[2] - seg[0], seg[3] - seg[1]);
    for (float t = 0; t < length; t += 0.03f + 0.02f * std::abs(u(rng))) {
      const float a = t / length;
      m.insertPoint(seg[0] + a * (seg[2] - seg[0]) + noise(rng), seg[1] + a * (seg[3] - seg[1]) + noise(rng));
    }
  }
  for (int i = 0; i < 3; ++i) m.insertPoint(static_cast<float>(stray * u(rng)), static_cast<float>(stray * u(rng)));
  return m;
}

void expect_same_matching(const mrpt::maps::CPointsMap& kdtree, const mrpt::maps::CPointsMap& grid,
                          const mrpt::maps::CPointsMap& other, const mrpt::poses::CPose2D& pose,
                          const mrpt::maps::TMatchingParams& params, size_t* pairs_seen) {
  mrpt::tfest::TMatchingPairList want, got;
  mrpt::maps::TMatchingExtraResults want_extra, got_extra;
  kdtree.determineMatching2D(&other, pose, want, params, want_extra);
  grid.determineMatching2D(&other, pose, got, params, got_extra);
  ASSERT_EQ(got.size(), want.size()) << pose;
  for (size_t i = 0; i < want.size(); ++i) {
    ASSERT_EQ(got[i].localIdx, want[i].localIdx) << pose << " pair " << i;
    ASSERT_EQ(got[i].globalIdx, want[i].globalIdx) << pose << " pair " << i;
    ASSERT_EQ(got[i].errorSquareAfterTransformation, want[i].errorSquareAfterTransformation) << pose << " pair " << i;
    ASSERT_EQ(got[i].global, want[i].global);
    ASSERT_EQ(got[i].local, want[i].local);
  }
  EXPECT_EQ(got_extra.correspondencesRatio, want_extra.correspondencesRatio) << pose;
  EXPECT_EQ(got_extra.sumSqrDist, want_extra.sumSqrDist) << pose;
  *pairs_seen += want.size();
}

TEST(GridPointsMap, MatchesAsMrptsKdTreeDoes) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  size_t pairs = 0, calls = 0;
  for (const double stray : {10.0, 400.0}) {  // 400 m: the grid's cells grow to keep it small
    const auto reference = walls(rng, stray);
    internal::GridPointsMap grid;
    grid.insertAnotherMap(&reference, mrpt::poses::CPose3D());
    auto scan = walls(rng, 10);
    for (int trial = 0; trial < 60; ++trial) {
      // Poses from the ICP's last steps (centimetres off) to a failed guess (metres off, or beside the map).
      const double reach = trial < 20 ? 0.05 : trial < 50 ? 1.0 : 12.0;
      const mrpt::poses::CPose2D pose(reach * u(rng), reach * u(rng), 0.3 * u(rng));
      mrpt::maps::TMatchingParams params;
      params.maxDistForCorrespondence = static_cast<float>(0.05 + 2 * std::abs(u(rng)));
      params.maxAngularDistForCorrespondence = trial % 2 ? 0.f : static_cast<float>(0.2 * std::abs(u(rng)));
      params.angularDistPivotPoint = {pose.x(), pose.y(), 0};
      params.onlyUniqueRobust = trial % 3 != 0;
      params.decimation_other_map_points = 1 + trial % 4;
      params.offset_other_map_points = trial % params.decimation_other_map_points;
      expect_same_matching(reference, grid, scan, pose, params, &pairs);
      ++calls;
    }
  }
  // About 1,100 points a map; decimated by 1-4, and a third of the poses metres off: about 35,000 pairs.
  EXPECT_GT(pairs, 20'000u) << "the trials should match many points";
  EXPECT_EQ(calls, 120u);
}

TEST(GridPointsMap, EmptyMapsAndQueriesOutside) {
  std::mt19937 rng(3);
  internal::GridPointsMap grid;
  const mrpt::maps::CSimplePointsMap empty;
  mrpt::tfest::TMatchingPairList out;
  mrpt::maps::TMatchingExtraResults extra;
  grid.determineMatching2D(&empty, mrpt::poses::CPose2D(), out, {}, extra);  // both empty
  EXPECT_TRUE(out.empty());
  const auto points = walls(rng, 10);
  grid.insertAnotherMap(&points, mrpt::poses::CPose3D());
  float d2 = 0;
  EXPECT_EQ(grid.nearest(500.f, 500.f, 2.0, d2), -1);  // far outside: nothing within the limit
  EXPECT_GE(grid.nearest(-4.05f, 0.f, 0.2, d2), 0);    // just outside the wall at x = -4
  EXPECT_LT(d2, 0.2f * 0.2f);
  EXPECT_EQ(grid.nearest(0.f, 0.f, 0.0, d2), -1);  // a zero limit finds nothing

  // Cleared and refilled, the grid follows the points.
  grid.clear();
  grid.insertPoint(100.f, 100.f);
  EXPECT_EQ(grid.nearest(100.1f, 100.f, 0.5, d2), 0);
  EXPECT_EQ(grid.nearest(-4.05f, 0.f, 0.2, d2), -1);
}

// Points at exactly the same distance from a query: the first in the map is its match, whether the search starts
// from the other one (the hint left by the previous matching of the same two maps, as the ICP's iterations leave
// it) or from nothing. Before, the hint won such ties, so a matching's answer depended on what was matched before
// it, and (with the hints kept per thread) on the thread.
TEST(GridPointsMap, EqualDistancesGoToTheFirstPointWhateverCameBefore) {
  for (const bool reversed : {false, true}) {
    internal::GridPointsMap grid;
    const float xs[2] = {reversed ? 1.f : -1.f, reversed ? -1.f : 1.f};
    for (const float x : xs) grid.insertPoint(x, 0.f);
    grid.insertPoint(0.f, 5.f);  // a third point, so the two are not at the grid's corners
    mrpt::maps::CSimplePointsMap query;
    query.insertPoint(0.f, 0.f);
    mrpt::maps::TMatchingParams params;
    params.maxDistForCorrespondence = 2;
    params.maxAngularDistForCorrespondence = 0;
    params.onlyKeepTheClosest = true;
    params.decimation_other_map_points = 1;
    const auto match = [&](const mrpt::poses::CPose2D& pose) {
      mrpt::tfest::TMatchingPairList pairs;
      mrpt::maps::TMatchingExtraResults extra;
      grid.determineMatching2D(&query, pose, pairs, params, extra);
      EXPECT_EQ(pairs.size(), 1u);
      return pairs.empty() ? -1 : static_cast<int64_t>(pairs[0].globalIdx);
    };
    const int64_t fresh = match(mrpt::poses::CPose2D(0, 0, 0));  // the first matching of the two: no hint
    EXPECT_EQ(fresh, 0) << "reversed " << reversed;
    // The point at x = 0.1 matches the second point (x = 1 or -1); that is the hint at the next matching, at x = 0.
    EXPECT_EQ(match(mrpt::poses::CPose2D(xs[1] > 0 ? 0.1 : -0.1, 0, 0)), 1);
    EXPECT_EQ(match(mrpt::poses::CPose2D(0, 0, 0)), 0) << "reversed " << reversed;
    float d2 = 0;
    EXPECT_EQ(grid.nearest(0.f, 0.f, 2.0, d2), 0);
    EXPECT_EQ(d2, 1.f);
  }
}

TEST(GridPointsMap, IcpGivesMrptsPoseBitForBit) {
  std::mt19937 rng(11);
  const auto reference = walls(rng, 10);
  internal::GridPointsMap grid;
  grid.insertAnotherMap(&reference, mrpt::poses::CPose3D());
  mrpt::maps::CSimplePointsMap scan;  // the walls seen from 0.4 m, 0.2 m and 5 degrees away, every other point
  const auto seen = walls(rng, 10);
  scan.insertAnotherMap(&seen, mrpt::poses::CPose3D(-0.4, 0.2, 0, -0.087, 0, 0));
  mrpt::slam::CICP icp;
  icp.options.thresholdDist = 0.75, icp.options.thresholdAng = 0.15 * M_PI / 180, icp.options.ALFA = 0.5;
  icp.options.onlyUniqueRobust = true, icp.options.corresponding_points_decimation = 2;
  for (const auto& guess : {mrpt::poses::CPose2D(0, 0, 0), mrpt::poses::CPose2D(0.5, -0.3, 0.1)}) {
    mrpt::slam::CICP::TReturnInfo want_info, got_info;
    const auto want = icp.Align(&reference, &scan, guess, want_info);
    const auto got = icp.Align(&grid, &scan, guess, got_info);
    const auto w = want->getMeanVal(), g = got->getMeanVal();
    EXPECT_EQ(w.x(), g.x());
    EXPECT_EQ(w.y(), g.y());
    EXPECT_EQ(w.phi(), g.phi());
    EXPECT_EQ(want_info.goodness, got_info.goodness);
    EXPECT_EQ(want_info.nIterations, got_info.nIterations);
    const auto truth = mrpt::poses::CPose2D() - mrpt::poses::CPose2D(-0.4, 0.2, -0.087);
    EXPECT_NEAR(g.x(), truth.x(), 0.05) << "the ICP should find the walls' offset";
    EXPECT_NEAR(g.y(), truth.y(), 0.05);
    EXPECT_NEAR(g.phi(), truth.phi(), 0.01);
  }
}

}  // namespace
}  // namespace driftlab::slam
