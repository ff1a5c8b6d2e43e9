// The fused points map's kd-tree: after MRPT's fuseWith (the insertion the ICP builder does with fuse_points) the
// index still describes the map before the insertion until mark_point_maps_modified is called. The grid points
// map: the same correspondences as MRPT's kd-tree matching, and so the same ICP results.
#include <gtest/gtest.h>

#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/maps/CMultiMetricMap.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/slam/CICP.h>

#include <array>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

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

// The surface test's 8 nearest points (constraint_of in scan_graph.cc) from the grid: the kd-tree's points in the
// kd-tree's order wherever the grid answers, so the loop tests' information is the same to the last bit; where two of
// the 9 nearest are equally far (which of them the kd-tree gives, and first, is its tree's), no answer.
TEST(GridPointsMap, NearestKAreTheKdTreesOrNone) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  size_t answered = 0, queries = 0;
  for (const double stray : {10.0, 400.0}) {  // 400 m: the grid's cells grow, so more points share a cell
    const auto reference = walls(rng, stray);
    internal::GridPointsMap grid;
    grid.insertAnotherMap(&reference, mrpt::poses::CPose3D());
    std::vector<size_t> want, got;
    std::vector<float> d2;
    for (size_t i = 0; i < reference.size(); i += 3) {  // at map points, as the surface test asks
      float x = 0, y = 0;
      reference.getPoint(i, x, y);
      for (const float dx : {0.f, static_cast<float>(0.3 * u(rng))}) {  // and beside them
        ++queries;
        reference.kdTreeNClosestPoint2DIdx(x + dx, y, 8, want, d2);
        if (grid.nearest_k(x + dx, y, 8, got)) {
          ++answered;
          ASSERT_EQ(got, want) << "at " << x + dx << " " << y;
        } else {
          EXPECT_TRUE(got.empty());
        }
      }
    }
  }
  // Noisy walls have no two points at exactly the same distance from a point: the grid answers (nearly) all.
  EXPECT_GT(answered, queries * 99 / 100) << answered << " of " << queries;

  // Equal distances: none, whichever of them comes first in the map; the rest is answered.
  internal::GridPointsMap ring;
  // 12 points on a circle of 1 m, 30 degrees apart: from (0, 0) the four on the axes tie to the last bit.
  for (int i = 0; i < 12; ++i) {
    ring.insertPoint(static_cast<float>(std::cos(i * M_PI / 6)), static_cast<float>(std::sin(i * M_PI / 6)));
  }
  std::vector<size_t> got;
  EXPECT_FALSE(ring.nearest_k(0.f, 0.f, 8, got));
  EXPECT_TRUE(got.empty());
  mrpt::maps::CSimplePointsMap pair;  // two points equally far from (0, 0) but 2 nearer ones: the 3rd and 4th tie
  for (const auto& p : std::vector<std::array<float, 2>>{{0.1f, 0}, {0, 0.2f}, {1, 0}, {-1, 0}, {5, 5}}) {
    pair.insertPoint(p[0], p[1]);
  }
  internal::GridPointsMap tie;
  tie.insertAnotherMap(&pair, mrpt::poses::CPose3D());
  EXPECT_FALSE(tie.nearest_k(0.f, 0.f, 3, got));  // which of the two is 3rd is the kd-tree's
  EXPECT_TRUE(tie.nearest_k(0.f, 0.f, 1, got));   // the nearest and the next (0.2 m) are not equally far
  EXPECT_EQ(got, std::vector<size_t>{0});
  EXPECT_FALSE(tie.nearest_k(0.f, 0.f, 6, got));  // more asked than the map holds: the kd-tree's answer is its own
}

// Each scan point matched to its nearest map point within 2 m, whatever the angle.
mrpt::maps::TMatchingParams nearest_within_2m() {
  mrpt::maps::TMatchingParams params;
  params.maxDistForCorrespondence = 2;
  params.maxAngularDistForCorrespondence = 0;
  params.onlyKeepTheClosest = true;
  params.decimation_other_map_points = 1;
  return params;
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
    const auto params = nearest_within_2m();
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

// icp_align is MRPT's classic ICP step for step (the SLAM's front end and loop tests run it instead of CICP, so that
// the graph method needs no part of MRPT's SLAM library; the restarts stop it early): the same pose, goodness,
// iterations and covariance to the bit as CICP::Align on the same grid, each read from the same .ini text by
// CICP::TConfigParams::loadFromConfigFile and IcpOptions::load. The settings: the test above's, the SLAM's front
// end's (decimation 5, ALFA 0.8, 80 iterations), a cap of 6 iterations that ends it mid-way (the cap's own
// threshold rule), a threshold limit that float rounds down (0.07), and the other covariance method and kernel.
// Asked to stop once within 5 cm and 0.01 rad of the truth, it stops at the first such pose, sooner than the full run.
TEST(GridPointsMap, IcpAlignIsMrptsIcpStepForStep) {
  std::mt19937 rng(11);
  const auto reference = walls(rng, 10);
  internal::GridPointsMap grid;
  grid.insertAnotherMap(&reference, mrpt::poses::CPose3D());
  mrpt::maps::CSimplePointsMap scan;
  const auto seen = walls(rng, 10);
  scan.insertAnotherMap(&seen, mrpt::poses::CPose3D(-0.4, 0.2, 0, -0.087, 0, 0));
  const auto truth = mrpt::poses::CPose2D() - mrpt::poses::CPose2D(-0.4, 0.2, -0.087);
  const std::string test =
      "thresholdDist=0.75\nthresholdAng_DEG=0.15\nALFA=0.5\nonlyUniqueRobust=true\n"
      "corresponding_points_decimation=2\n";
  const std::string front =
      "maxIterations=80\nthresholdDist=0.3\nthresholdAng_DEG=1\nALFA=0.8\n"
      "smallestThresholdDist=0.05\ncorresponding_points_decimation=5\nonlyUniqueRobust=true\n"
      "minAbsStep_trans=1e-6\nminAbsStep_rot=1e-6\nICP_algorithm=icpClassic\n";
  const std::vector<std::string> settings = {
      test,
      front,
      front + "maxIterations=6\n",
      front + "ALFA=0.7\nsmallestThresholdDist=0.07\n",
      test + "ICP_covariance_method=icpCovLinealMSE\ncovariance_varPoints=0.001\n",
      front + "use_kernel=false\nkernel_rho=0.1\n",
      front + "skip_cov_calculation=true\n"};
  for (const auto& text : settings) {
    SCOPED_TRACE(text);
    const mrpt::config::CConfigFileMemory ini("[ICP]\n" + text);
    mrpt::slam::CICP::TConfigParams mrpts;
    mrpts.loadFromConfigFile(ini, "ICP");
    internal::IcpOptions ours;
    ours.load(ini, "ICP");
    EXPECT_EQ(ours.thresholdAng, mrpts.thresholdAng);
    EXPECT_EQ(ours.smallestThresholdDist, mrpts.smallestThresholdDist);
    mrpt::slam::CICP icp(mrpts);
    for (const auto& guess : {mrpt::poses::CPose2D(0, 0, 0), mrpt::poses::CPose2D(0.5, -0.3, 0.1)}) {
      mrpt::slam::CICP::TReturnInfo info;
      const auto pdf = icp.Align(&grid, &scan, guess, info);
      const auto want = pdf->getMeanVal();
      const auto got = internal::icp_align(grid, scan, guess, ours);
      EXPECT_EQ(want.x(), got.pose.x());
      EXPECT_EQ(want.y(), got.pose.y());
      EXPECT_EQ(want.phi(), got.pose.phi());
      EXPECT_EQ(info.goodness, got.goodness);
      EXPECT_EQ(info.nIterations, got.iterations);
      const auto& cov = dynamic_cast<const mrpt::poses::CPosePDFGaussian&>(*pdf).cov;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) EXPECT_EQ(cov(r, c), got.covariance(r, c)) << r << "," << c;
      }
      if (text.find("skip_cov") == std::string::npos) {
        EXPECT_GT(got.covariance(0, 0), 0) << "a covariance is computed";
      }
      const auto pose_only = internal::icp_classic(grid, scan, guess, ours);
      EXPECT_EQ(pose_only.x(), want.x());
      EXPECT_EQ(pose_only.phi(), want.phi());

      unsigned int asked = 0;
      mrpt::poses::CPose2D first_near;
      bool near_seen = false;
      const auto stopped = internal::icp_classic(grid, scan, guess, ours, [&](const mrpt::poses::CPose2D& p) {
        ++asked;
        const bool near = std::hypot(p.x() - truth.x(), p.y() - truth.y()) <= 0.05 &&
                          std::abs(mrpt::math::wrapToPi(p.phi() - truth.phi())) <= 0.01;
        if (near && !near_seen) first_near = p, near_seen = true;
        return near;
      });
      if (ours.maxIterations == 6 && !near_seen) continue;  // six iterations may not get there
      ASSERT_TRUE(near_seen);
      EXPECT_EQ(stopped.x(), first_near.x());
      EXPECT_EQ(stopped.phi(), first_near.phi());
      EXPECT_LT(asked, info.nIterations) << "it should stop before the end";
    }
  }
}

// What only another ICP does is refused by name, not run as the classic one: the Levenberg-Marquardt method (by name
// or number), RANSAC; and what MRPT refuses (an unknown method, ALFA of 1 or more) too.
TEST(IcpOptions, RefusesWhatTheClassicIcpDoesNot) {
  for (const char* text : {"ICP_algorithm=icpLevenbergMarquardt", "ICP_algorithm=1", "doRANSAC=true",
                           "ICP_covariance_method=icpCovSomething", "ICP_covariance_method=7", "ALFA=1"}) {
    const mrpt::config::CConfigFileMemory ini("[ICP]\n" + std::string(text) + "\n");
    internal::IcpOptions o;
    try {
      o.load(ini, "ICP");
      ADD_FAILURE() << text << " was taken";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      const std::string key = std::string(text).substr(0, std::string(text).find('='));
      EXPECT_NE(what.find(key), std::string::npos) << what;
    }
  }
}

// A point that moved little since its last search against the same grid keeps its nearest map point without a
// search, but only when the bounds found at that search prove it. Walked across the perpendicular bisector of two
// map points in steps of 0.1 mm, a scan point must change its match exactly where MRPT's kd-tree does (at the
// bisector itself, the first of the two). And on a building's walls, with every seventh point doubled a millimetre
// away (a second nearest about as near as the nearest), a scan walked in steps from a micrometre to 5 cm (the ICP's
// last iterations to a new scan's first) is matched as MRPT matches it at every step, many points proved, many
// searched: a bound that ignored the way moved, or missed a cell not looked at, would keep a stale match. (No
// exact duplicates here: of points at exactly the same distance, the kd-tree takes the one it reaches first, the
// grid the first in the map; EqualDistancesGoToTheFirstPointWhateverCameBefore.)
TEST(GridPointsMap, PointsThatMovedLittleKeepTheirMatchOnlyWhenProved) {
  {
    internal::GridPointsMap grid;
    mrpt::maps::CSimplePointsMap kdtree;
    for (const float x : {-1.f, 1.f, 0.f}) {
      grid.insertPoint(x, x == 0.f ? 5.f : 0.f);
      kdtree.insertPoint(x, x == 0.f ? 5.f : 0.f);
    }
    mrpt::maps::CSimplePointsMap query;
    query.insertPoint(0.f, 0.f);
    const auto params = nearest_within_2m();
    const auto before = internal::GridPointsMap::lookups();
    size_t pairs = 0;
    for (int step = -20; step <= 20; ++step) {
      const mrpt::poses::CPose2D pose(1e-4 * step, 0, 0);
      expect_same_matching(kdtree, grid, query, pose, params, &pairs);
      mrpt::tfest::TMatchingPairList got;
      mrpt::maps::TMatchingExtraResults extra;
      grid.determineMatching2D(&query, pose, got, params, extra);
      ASSERT_EQ(got.size(), 1u);
      EXPECT_EQ(got[0].globalIdx, step <= 0 ? 0u : 1u) << "at x = " << pose.x();
    }
    const auto after = internal::GridPointsMap::lookups();
    // Two matchings a step, 82 look-ups: far from the bisector the match is proved; near it (within the way moved
    // since the last search) it is searched.
    EXPECT_GT(after.proved - before.proved, 40u);
    EXPECT_GT(after.searched - before.searched, 4u);
  }

  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  auto reference = walls(rng, 10);
  for (size_t i = 0, n = reference.size(); i < n; i += 7) {
    float x = 0, y = 0, z = 0;
    reference.getPoint(i, x, y, z);
    const double a = M_PI * u(rng);
    reference.insertPoint(x + static_cast<float>(1e-3 * std::cos(a)), y + static_cast<float>(1e-3 * std::sin(a)));
  }
  internal::GridPointsMap grid;
  grid.insertAnotherMap(&reference, mrpt::poses::CPose3D());
  const auto scan = walls(rng, 10);
  const auto before = internal::GridPointsMap::lookups();
  size_t pairs = 0;
  double x = 0.1, y = -0.05, yaw = 0.02;
  for (int step = 0; step < 300; ++step) {
    const double scale = std::array{1e-6, 1e-4, 1e-3, 1e-2, 0.05}[static_cast<size_t>(step) % 5];
    x += scale * u(rng), y += scale * u(rng), yaw += scale / 3 * u(rng);
    const mrpt::poses::CPose2D pose(x, y, yaw);
    mrpt::maps::TMatchingParams params;
    params.maxDistForCorrespondence = static_cast<float>(0.05 + 0.3 * std::abs(u(rng)));
    params.maxAngularDistForCorrespondence = step % 2 ? 0.f : 0.02f;
    params.angularDistPivotPoint = {pose.x(), pose.y(), 0};
    params.onlyUniqueRobust = step % 3 != 0;
    params.decimation_other_map_points = step % 4 == 0 ? 2 : 1;
    params.offset_other_map_points = step % 8 == 0 ? 1 : 0;
    expect_same_matching(reference, grid, scan, pose, params, &pairs);
  }
  const auto after = internal::GridPointsMap::lookups();
  const auto proved = after.proved - before.proved, searched = after.searched - before.searched;
  // One matching a step, about 290,000 look-ups in all: a third proved (most of those after steps of a micrometre
  // to a millimetre), the rest searched. Both must happen, or this test does not test the proof.
  EXPECT_GT(proved, 50'000u) << searched << " searched";
  EXPECT_GT(searched, 50'000u) << proved << " proved";
  EXPECT_GT(pairs, 50'000u);
}

}  // namespace
}  // namespace driftlab::slam
