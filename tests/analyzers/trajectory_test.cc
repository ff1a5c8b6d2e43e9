// Tests for analyzers/trajectory.h: evo's association rules, alignment, APE, RPE pairs and drift.
#include "analyzers/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>

#include "analyzers/trajectory_io.h"
#include "tests/test_util.h"

namespace driftlab::analyzers {
namespace {

Trajectory line(const std::vector<double>& stamps, double speed = 1.0) {
  Trajectory t;
  for (double s : stamps) t.push_back(s, Eigen::Vector3d(speed * s, 0, 0), Eigen::Quaterniond::Identity());
  return t;
}

std::vector<double> stamps_of(const Trajectory& t) { return {t.stamps.begin(), t.stamps.end()}; }

TEST(MatchNearest, IteratesTheShorterTrajectoryAndMayReuseAPoseOfTheLonger) {
  const Trajectory ref = line({0.0, 1.0, 2.0, 3.0});
  const Trajectory est = line({0.9, 1.1});
  const Matched m = match_nearest(ref, est, 0.2, 0.0);
  EXPECT_EQ(stamps_of(m.est), (std::vector<double>{0.9, 1.1}));
  EXPECT_EQ(stamps_of(m.ref), (std::vector<double>{1.0, 1.0}));  // used twice
}

TEST(MatchNearest, TakesTheFirstOnTiesAndRespectsMaxDtInclusively) {
  // 0.5 is exactly between 0.25 and 0.75: the first (lower index) wins.
  const Trajectory ref = line({0.25, 0.75, 2.0});
  const Trajectory est = line({0.5, 2.25});
  const Matched m = match_nearest(ref, est, 0.25, 0.0);
  EXPECT_EQ(stamps_of(m.ref), (std::vector<double>{0.25, 2.0}));
  // Ties by index also hold when the longer trajectory's stamps are out of order.
  const Trajectory unsorted = line({0.75, 0.25, 2.0});
  const Matched u = match_nearest(unsorted, est, 0.25, 0.0);
  EXPECT_EQ(stamps_of(u.ref), (std::vector<double>{0.75, 2.0}));
  // Duplicate stamps: the first of them.
  Trajectory dup = line({1.0, 1.0, 3.0});
  dup.positions[1].x() = 42;
  const Matched d = match_nearest(dup, line({1.0}), 0.01, 0.0);
  ASSERT_EQ(d.ref.size(), 1u);
  EXPECT_EQ(d.ref.positions[0].x(), 1.0);
}

TEST(MatchNearest, OffsetShiftsTheEstimateWhicheverIsLonger) {
  const Trajectory ref = line({10.0, 11.0});
  const Trajectory est_long = line({0.0, 1.0, 2.0});
  EXPECT_EQ(match_nearest(ref, est_long, 0.01, 10.0).ref.size(), 2u);
  const Trajectory est_short = line({0.0});
  EXPECT_EQ(match_nearest(ref, est_short, 0.01, 10.0).ref.size(), 1u);
  EXPECT_EQ(match_nearest(ref, est_short, 0.01, 0.0).ref.size(), 0u);
}

TEST(MatchInterpolated, InterpolatesPositionAndOrientation) {
  Trajectory ref;
  ref.push_back(0.0, {0, 0, 0}, Eigen::Quaterniond::Identity());
  ref.push_back(1.0, {2, 0, 0}, Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())));
  ref.push_back(5.0, {2, 0, 0}, Eigen::Quaterniond::Identity());
  const Trajectory est = line({0.25, 3.0, 7.0});
  const Matched m = match_interpolated(ref, est, 1.5, 0.0);
  ASSERT_EQ(m.ref.size(), 1u);  // 3.0 lies in a 4 s gap, 7.0 after the end
  EXPECT_NEAR(m.ref.positions[0].x(), 0.5, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(m.ref.orientations[0]).angle(), M_PI / 8, 1e-12);
}

TEST(ExplainNoMatch, GivesRangesTheClosestPairAndAnOffset) {
  const std::string why = explain_no_match(line({100, 101, 102}), line({0, 1, 2}), 0.01, 0.0);
  EXPECT_NE(why.find("do not overlap"), std::string::npos) << why;
  EXPECT_NE(why.find("--offset 100.000000"), std::string::npos) << why;
  EXPECT_NE(why.find("98.000000 s apart"), std::string::npos) << why;
  const std::string sparse = explain_no_match(line({0, 1, 2}), line({0.5, 1.5}), 0.01, 0.0);
  EXPECT_NE(sparse.find("--max-dt"), std::string::npos) << sparse;
}

Trajectory curve(int n) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    const double s = 0.1 * i;
    t.push_back(s, Eigen::Vector3d(3 * std::cos(0.3 * s), 2 * std::sin(0.5 * s), 0.1 * s),
                Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * s, Eigen::Vector3d(0.1, 0.2, 1).normalized())));
  }
  return t;
}

TEST(Align, RecoversAKnownSimilarityTransform) {
  const Trajectory ref = curve(200);
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(1, -2, 0.5);
  // est = inverse of (scale 2, r, t) applied to ref, so aligning est onto ref must find (2, r, t).
  Alignment truth{AlignmentType::kSim3, r.transpose(), -r.transpose() * t / 2, 0.5};
  const Trajectory est = apply(truth, ref);
  const Alignment a = align({ref, est}, AlignmentType::kSim3);
  EXPECT_NEAR(a.scale, 2.0, 1e-9);
  EXPECT_TRUE(a.rotation.isApprox(r, 1e-9));
  EXPECT_TRUE(a.translation.isApprox(t, 1e-9));
  const ApeResult e = ape({ref, apply(a, est)});
  EXPECT_LT(e.trans.max, 1e-9);
  EXPECT_LT(e.rot_deg.max, 1e-6);
  // se3 cannot undo a scale: error remains, and the scale stays 1.
  EXPECT_EQ(align({ref, est}, AlignmentType::kSe3).scale, 1.0);
}

TEST(Align, PosYawRotatesOnlyAboutZ) {
  const Trajectory ref = curve(100);
  Alignment truth{AlignmentType::kPosYaw, Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                  {0.5, 0.5, 1.0}, 1.0};
  const Trajectory est = apply(truth, ref);
  const Alignment a = align({ref, est}, AlignmentType::kPosYaw);
  EXPECT_NEAR(Eigen::AngleAxisd(a.rotation).angle(), 1.0, 1e-9);
  EXPECT_NEAR(std::abs(Eigen::AngleAxisd(a.rotation).axis().z()), 1.0, 1e-9);
  EXPECT_LT(ape({ref, apply(a, est)}).trans.max, 1e-9);
}

TEST(ComputeStats, MatchesNumpyConventions) {
  const Stats s = compute_stats({1, 2, 3, 4});
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));  // population
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(s.min, 1);
  EXPECT_DOUBLE_EQ(s.max, 4);
  EXPECT_DOUBLE_EQ(compute_stats({5, 1, 3}).median, 3);
}

TEST(Rpe, PairsFollowEvo) {
  const Trajectory ref = line({0, 1, 2, 3, 4, 5, 6});
  const Matched m{ref, ref};
  auto pairs = [&](double d, DeltaUnit u, bool all) { return rpe(m, d, u, all).pairs; };
  using P = std::vector<std::pair<size_t, size_t>>;
  EXPECT_EQ(pairs(2, DeltaUnit::kFrames, false), (P{{0, 2}, {2, 4}, {4, 6}}));
  EXPECT_EQ(pairs(2, DeltaUnit::kFrames, true), (P{{0, 2}, {1, 3}, {2, 4}, {3, 5}, {4, 6}}));
  // Metres: ids where the path since the previous id reaches delta (the first id is not pose 0, as in evo).
  EXPECT_EQ(pairs(2.0, DeltaUnit::kMeters, false), (P{{2, 4}, {4, 6}}));
  EXPECT_EQ(pairs(2.0, DeltaUnit::kSeconds, false), (P{{2, 4}, {4, 6}}));
}

TEST(Rpe, MeasuresTheRelativeMotionError) {
  // The estimate moves 1.1 m per step where the truth moves 1 m: 0.1 m error per consecutive pair.
  const Matched m{line({0, 1, 2, 3}), line({0, 1, 2, 3}, 1.1)};
  const RpeResult r = rpe(m, 1, DeltaUnit::kFrames, false);
  EXPECT_EQ(r.trans.count, 3u);
  EXPECT_NEAR(r.trans.mean, 0.1, 1e-12);
  EXPECT_NEAR(r.rot_deg.max, 0.0, 1e-12);
}

TEST(Drift, IsThePercentOfDistanceForAScaleError) {
  std::vector<double> stamps;
  for (int i = 0; i <= 1000; ++i) stamps.push_back(0.1 * i);
  const Matched m{line(stamps), line(stamps, 1.02)};
  const DriftResult d = drift(m, {}, 10);
  ASSERT_EQ(d.segments.size(), 5u);
  EXPECT_DOUBLE_EQ(d.segments[0].length_m, 10.0);  // 10% of the 100 m path
  EXPECT_DOUBLE_EQ(d.segments[4].length_m, 50.0);
  for (const auto& s : d.segments) EXPECT_GT(s.count, 0u);
  // Segments end at the first pose strictly beyond L, so slightly longer than L: 2% of a bit more than L.
  EXPECT_NEAR(d.trans_pct, 2.0, 0.05);
  EXPECT_NEAR(d.rot_deg_per_m, 0.0, 1e-9);
}

TEST(RotationAngle, IsAccurateNearZeroAndPi) {
  for (double angle : {1e-9, 1e-4, 1.0, M_PI - 1e-7}) {
    EXPECT_NEAR(rotation_angle(Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d(1, 1, 0).normalized()))),
                angle, 1e-12);
  }
}

TEST(LoadTum, ReadsSpacesTabsCommasAndComments) {
  test::TempDir dir;
  const std::string text = "# t x y z qx qy qz qw\n\n1.0 1 2 3 0 0 0 1\n2.0\t4\t5\t6\t0\t0\t0\t1\r\n3.0,7,8,9,0,0,0,1";
  test::write_file(dir.file("t.tum"), {text.begin(), text.end()});
  auto t = load_tum(dir.file("t.tum"));
  ASSERT_TRUE(t.ok()) << t.error().message;
  ASSERT_EQ(t->size(), 3u);
  EXPECT_EQ(t->positions[2], Eigen::Vector3d(7, 8, 9));
  EXPECT_EQ(t->stamps[1], 2.0);
}

TEST(LoadTum, ErrorsNameTheFileAndLine) {
  test::TempDir dir;
  const std::pair<std::string, std::string> cases[] = {
      {"1 2 3 4 0 0 0 1\n1 2 3\n", ":2: expected 8 numbers"},
      {"1 2 3 4 0 0 0 1\n1 2 x 4 0 0 0 1\n", ":2: not a number"},
      {"1 2 3 4 0 0 0 0\n", ":1: the quaternion is zero"},
      {"1 2 3 4 0 0 0 1 9\n", ":1: expected 8 numbers"},
      {"# only a comment\n", ": no poses"},
  };
  for (const auto& [text, expected] : cases) {
    test::write_file(dir.file("bad.tum"), {text.begin(), text.end()});
    auto t = load_tum(dir.file("bad.tum"));
    ASSERT_FALSE(t.ok()) << text;
    EXPECT_NE(t.error().message.find(dir.file("bad.tum") + expected), std::string::npos) << t.error().message;
  }
}

TEST(LoadTrajectory, ReadsPoseAndOdometryChannelsOfALog) {
  const std::string log = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";
  auto gt = load_trajectory(log + ":GROUND_TRUTH");
  ASSERT_TRUE(gt.ok()) << gt.error().message;
  EXPECT_EQ(gt->size(), 101u);
  EXPECT_DOUBLE_EQ(gt->stamps[0], 1763776800.0);
  auto odom = load_trajectory(log + ":ODOM");
  ASSERT_TRUE(odom.ok());
  EXPECT_EQ(odom->size(), 51u);
  auto imu = load_trajectory(log + ":IMU");
  ASSERT_FALSE(imu.ok());
  EXPECT_NE(imu.error().message.find("neither driftlab.pose_t nor driftlab.odometry_t"), std::string::npos);
  auto missing = load_trajectory(log + ":NOPE");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("channels: CMD_VEL, GROUND_TRUTH"), std::string::npos);
}

TEST(WriteTum, RoundTripsExactly) {
  test::TempDir dir;
  const Trajectory t = curve(50);
  ASSERT_TRUE(write_tum(dir.file("c.tum"), t).ok());
  auto back = load_tum(dir.file("c.tum"));
  ASSERT_TRUE(back.ok());
  for (size_t i = 0; i < t.size(); ++i) {
    EXPECT_EQ(back->positions[i], t.positions[i]);
    EXPECT_EQ(back->orientations[i].coeffs(), t.orientations[i].coeffs());
  }
}

}  // namespace
}  // namespace driftlab::analyzers
