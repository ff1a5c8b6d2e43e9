// Tests for analyzers/trajectory.h: evo's association rules, alignment, APE, RPE pairs and drift.
#include "analyzers/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

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

std::vector<std::pair<size_t, size_t>> pairs_of(const Matched& m, double delta, DeltaUnit unit, bool all,
                                                 bool from_reference = false, double tol = 0.1) {
  RpeOptions o;
  o.delta = delta;
  o.unit = unit;
  o.all_pairs = all;
  o.pairs_from_reference = from_reference;
  o.delta_tol = tol;
  return rpe(m, o).pairs;
}
using P = std::vector<std::pair<size_t, size_t>>;

TEST(Rpe, PairsByFramesAndDistanceFollowEvo) {
  const Trajectory ref = line({0, 1, 2, 3, 4, 5, 6});
  const Matched m{ref, ref};
  EXPECT_EQ(pairs_of(m, 2, DeltaUnit::kFrames, false), (P{{0, 2}, {2, 4}, {4, 6}}));
  EXPECT_EQ(pairs_of(m, 2, DeltaUnit::kFrames, true), (P{{0, 2}, {1, 3}, {2, 4}, {3, 5}, {4, 6}}));
  // Metres: ids where the path since the previous id reaches delta (the first id is not pose 0, as in evo).
  EXPECT_EQ(pairs_of(m, 2.0, DeltaUnit::kMeters, false), (P{{2, 4}, {4, 6}}));
  EXPECT_EQ(pairs_of(m, 2.0, DeltaUnit::kSeconds, false), (P{{2, 4}, {4, 6}}));
}

TEST(Rpe, AllPairsByDistanceTakeTheClosestWithinTheTolerance) {
  // Steps of 1, 1, 3, 0.5, 0.5, 0 (standing), 2 m.
  const Trajectory t = line({0, 1, 2, 5, 5.5, 6, 6, 8});
  const Matched m{t, t};
  // Within 10% of 2 m: from 0, pose 2 is exactly 2 m on; from 1, 2 and 3 are 1 and 4 m on; from 2, 3 m; from 3,
  // 1 m; from 4, 0.5 m; from 5 and 6 (standing at the same place), 7 is exactly 2 m on.
  EXPECT_EQ(pairs_of(m, 2.0, DeltaUnit::kMeters, true), (P{{0, 2}, {5, 7}, {6, 7}}));
  // Accepting misses of 1 m: from 1, 2 (1 m on) misses by 1 and 3 (4 m) by 2: the closer is taken; from 3, 5 and 6
  // (1 m on) and 7 (3 m) all miss by 1: the first; from 4, 7 (2.5 m on).
  EXPECT_EQ(pairs_of(m, 2.0, DeltaUnit::kMeters, true, false, 0.5),
            (P{{0, 2}, {1, 2}, {2, 3}, {3, 5}, {4, 7}, {5, 7}, {6, 7}}));
  // Ties: from 0 with delta 5.75 m, poses 4 (5.5 m on) and 5 (6 m) miss by 0.25 each: the first, 4.
  EXPECT_EQ(pairs_of(m, 5.75, DeltaUnit::kMeters, true, false, 0.05).front(), (std::pair<size_t, size_t>{0, 4}));
}

TEST(Rpe, PairsComeFromTheEstimateUnlessAskedForTheReference) {
  // The estimate covers twice the reference's distance: 2 m along it is 1 m along the reference.
  const Matched m{line({0, 1, 2, 3, 4, 5, 6}), line({0, 1, 2, 3, 4, 5, 6}, 2.0)};
  EXPECT_EQ(pairs_of(m, 2.0, DeltaUnit::kMeters, false), (P{{1, 2}, {2, 3}, {3, 4}, {4, 5}, {5, 6}}));
  EXPECT_EQ(pairs_of(m, 2.0, DeltaUnit::kMeters, false, true), (P{{2, 4}, {4, 6}}));
}

TEST(Rpe, PairsByAngleFollowEvo) {
  // Turning 10 degrees per pose about z: consecutive pairs from pose 0 where the turns add up to 25 degrees.
  Trajectory t;
  for (int i = 0; i < 8; ++i) {
    t.push_back(i, Eigen::Vector3d::Zero(), Eigen::Quaterniond(Eigen::AngleAxisd(i * 10 * M_PI / 180, Eigen::Vector3d::UnitZ())));
  }
  const Matched m{t, t};
  EXPECT_EQ(pairs_of(m, 25, DeltaUnit::kDegrees, false), (P{{0, 3}, {3, 6}}));
  EXPECT_EQ(pairs_of(m, 25 * M_PI / 180, DeltaUnit::kRadians, false), (P{{0, 3}, {3, 6}}));
  // All pairs: every pair whose direct angle is within 10% of delta: 20 degrees +/- 2 is every (i, i + 2).
  EXPECT_EQ(pairs_of(m, 20, DeltaUnit::kDegrees, true), (P{{0, 2}, {1, 3}, {2, 4}, {3, 5}, {4, 6}, {5, 7}}));
  EXPECT_TRUE(pairs_of(m, 25, DeltaUnit::kDegrees, true).empty());
  // 25 +/- 7.5 degrees: the pairs 20 and 30 degrees apart, 6 + 5.
  EXPECT_EQ(pairs_of(m, 25, DeltaUnit::kDegrees, true, false, 0.3).size(), 11u);
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
      // Poses that are no poses.
      {"1 2 3 4 0 0 0 0.5\n", ":1: the quaternion's norm is 0.5, not 1"},
      {"1 2 3 4 0 0 0 1\n2 inf 3 4 0 0 0 1\n", ":2: a number is not finite"},
      {"1 2 3 4 0 0 0 1\n2 nan 3 4 0 0 0 1\n", ":2: a number is not finite"},
  };
  for (const auto& [text, expected] : cases) {
    test::write_file(dir.file("bad.tum"), {text.begin(), text.end()});
    auto t = load_tum(dir.file("bad.tum"));
    ASSERT_FALSE(t.ok()) << text;
    EXPECT_NE(t.error().message.find(dir.file("bad.tum") + expected), std::string::npos) << t.error().message;
  }
}

TEST(LoadTum, KeepsQuaternionsRoundedToPrintedDigits) {
  test::TempDir dir;
  // Quaternions printed with 4 decimals (the TUM benchmark's own files) are unit within rounding: kept.
  const std::string rounded = "1 0 0 0 0.6132 0.5962 -0.3311 -0.3986\n";
  test::write_file(dir.file("ok.tum"), {rounded.begin(), rounded.end()});
  EXPECT_TRUE(load_tum(dir.file("ok.tum")).ok());
}

TEST(LoadKitti, ReadsPoseMatricesWithOrWithoutTimes) {
  test::TempDir dir;
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  std::string text;
  char line[512];
  for (int i = 0; i < 3; ++i) {
    std::snprintf(line, sizeof(line), "%.9e %.9e %.9e %d %.9e %.9e %.9e %d %.9e %.9e %.9e %d\n", r(0, 0), r(0, 1),
                  r(0, 2), i, r(1, 0), r(1, 1), r(1, 2), 2 * i, r(2, 0), r(2, 1), r(2, 2), -i);
    text += line;
  }
  test::write_file(dir.file("poses.txt"), {text.begin(), text.end()});
  auto t = load_kitti(dir.file("poses.txt"));
  ASSERT_TRUE(t.ok()) << t.error().message;
  ASSERT_EQ(t->size(), 3u);
  EXPECT_FALSE(t->stamped);
  EXPECT_EQ(t->positions[2], Eigen::Vector3d(2, 4, -2));
  EXPECT_TRUE(t->orientations[1].toRotationMatrix().isApprox(r, 1e-8));
  const std::string times = "0.0\n0.103\n0.2071\n";
  test::write_file(dir.file("times.txt"), {times.begin(), times.end()});
  auto stamped = load_kitti(dir.file("poses.txt"), dir.file("times.txt"));
  ASSERT_TRUE(stamped.ok()) << stamped.error().message;
  EXPECT_TRUE(stamped->stamped);
  EXPECT_EQ(stamped->stamps[2], 0.2071);
  // Auto-detected by its 12 numbers a line.
  auto detected = load_trajectory(dir.file("poses.txt"), TrajectoryFormat::kAuto, dir.file("times.txt"));
  ASSERT_TRUE(detected.ok()) << detected.error().message;
  EXPECT_EQ(detected->stamps[1], 0.103);
  // Errors: times not one per pose, a matrix that is no rotation, a times file with a TUM file.
  const std::string two = "0\n1\n";
  test::write_file(dir.file("two.txt"), {two.begin(), two.end()});
  auto short_times = load_kitti(dir.file("poses.txt"), dir.file("two.txt"));
  ASSERT_FALSE(short_times.ok());
  EXPECT_NE(short_times.error().message.find("2 stamps for the 3 poses"), std::string::npos) << short_times.error().message;
  const std::string skew = "1 0 0 0 0 2 0 0 0 0 1 0\n";
  test::write_file(dir.file("skew.txt"), {skew.begin(), skew.end()});
  auto bad = load_kitti(dir.file("skew.txt"));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find(":1: the 3x3 part is not a rotation"), std::string::npos) << bad.error().message;
  const std::string tum = "1 0 0 0 0 0 0 1\n";
  test::write_file(dir.file("t.tum"), {tum.begin(), tum.end()});
  EXPECT_FALSE(load_trajectory(dir.file("t.tum"), TrajectoryFormat::kAuto, dir.file("times.txt")).ok());
}

TEST(LoadEuroc, ReadsNanosecondStampsAndWxyzQuaternions) {
  test::TempDir dir;
  // The head of a real EuRoC ground truth file (MH_01_easy), 17 columns.
  const std::string text =
      "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], v_RS_R_x [m "
      "s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad "
      "s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n"
      "1403636580838555648,4.688319,-1.786938,0.783338,0.534108,-0.153029,-0.827383,-0.082152,-0.027876,0.033207,"
      "0.800006,-0.003172,0.021267,0.078502,-0.025266,0.136696,0.075593\n"
      "1403636580843555328,4.688177,-1.786770,0.787350,0.534640,-0.152990,-0.826976,-0.082863,-0.029272,0.033992,"
      "0.804030,-0.003172,0.021267,0.078502,-0.025266,0.136696,0.075593\n";
  test::write_file(dir.file("data.csv"), {text.begin(), text.end()});
  for (const auto format : {TrajectoryFormat::kEuroc, TrajectoryFormat::kAuto}) {
    auto t = load_trajectory(dir.file("data.csv"), format);
    ASSERT_TRUE(t.ok()) << t.error().message;
    ASSERT_EQ(t->size(), 2u);
    EXPECT_EQ(t->stamps[0], 1403636580838555648.0 / 1e9);  // as evo: the nanoseconds as a double, divided
    EXPECT_EQ(t->positions[1], Eigen::Vector3d(4.688177, -1.786770, 0.787350));
    EXPECT_EQ(t->orientations[0].w(), 0.534108);
    EXPECT_EQ(t->orientations[0].z(), -0.082152);
  }
  const std::string eight = "#timestamp\n1,0,0,0,1,0,0\n";
  test::write_file(dir.file("short.csv"), {eight.begin(), eight.end()});
  auto bad = load_euroc(dir.file("short.csv"));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find(":2: expected at least 8 numbers"), std::string::npos) << bad.error().message;
  const std::string odd = "1 2 3\n";
  test::write_file(dir.file("odd.txt"), {odd.begin(), odd.end()});
  auto unknown = load_trajectory(dir.file("odd.txt"));
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.error().message.find(":1: 3 numbers on the first data line"), std::string::npos)
      << unknown.error().message;
}

TEST(SortByStamp, SortsStablyAndCountsWhatItFound) {
  Trajectory t = line({3, 1, 2, 2, 5, 4});
  t.positions[3].y() = 7;  // the second pose stamped 2
  const StampOrder o = sort_by_stamp(t);
  EXPECT_EQ(o.out_of_order, 2u);  // 1 after 3, 4 after 5
  EXPECT_EQ(o.first_out_of_order, 1.0);
  EXPECT_EQ(o.repeated, 1u);
  EXPECT_EQ(o.first_repeated, 2.0);
  EXPECT_EQ(stamps_of(t), (std::vector<double>{1, 2, 2, 3, 4, 5}));
  EXPECT_EQ(t.positions[2].y(), 7);  // equal stamps keep their order
  EXPECT_EQ(t.positions[1].y(), 0);
}

TEST(Align, RefusesPositionsOnOneLineOrPoint) {
  const Trajectory straight = line({0, 1, 2, 3, 4});
  for (auto type : {AlignmentType::kSe3, AlignmentType::kSim3}) {
    const Alignment a = align({straight, straight}, type);
    EXPECT_NE(a.problem.find("one point or one line"), std::string::npos) << a.problem;
    EXPECT_EQ(a.scale, 1.0);
  }
  Trajectory still;
  for (int i = 0; i < 5; ++i) still.push_back(i, Eigen::Vector3d(1, 2, 3), Eigen::Quaterniond::Identity());
  EXPECT_FALSE(align({still, still}, AlignmentType::kPosYaw).problem.empty());
  // A still estimate against a moving reference: posyaw's position error is the same for every yaw, so the means
  // are matched (yaw 0) rather than refused.
  const Trajectory moving = curve(10);
  Trajectory frozen;
  for (size_t i = 0; i < moving.size(); ++i) frozen.push_back(moving.stamps[i], Eigen::Vector3d(1, 2, 3), Eigen::Quaterniond::Identity());
  const Alignment a = align({moving, frozen}, AlignmentType::kPosYaw);
  EXPECT_TRUE(a.problem.empty()) << a.problem;
  EXPECT_TRUE(a.rotation.isIdentity());
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : moving.positions) mean += p / static_cast<double>(moving.size());
  EXPECT_TRUE((a.translation - (mean - Eigen::Vector3d(1, 2, 3))).norm() < 1e-9);
  EXPECT_FALSE(align({curve(2), curve(2)}, AlignmentType::kSe3).problem.empty());
  EXPECT_TRUE(align({curve(10), curve(10)}, AlignmentType::kSim3).problem.empty());
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
  EXPECT_NE(imu.error().message.find("not a driftlab.pose_t, odometry_t or trajectory_setpoint_t"), std::string::npos);
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

TEST(SplitLogChannel, SplitsAtTheLastColonWhenTheLogExists) {
  test::TempDir dir;
  std::ofstream(dir.file("a.lcm")) << "x";
  std::filesystem::create_directories(dir.file("bag"));
  std::string log = "unchanged", channel = "unchanged";
  ASSERT_TRUE(split_log_channel(dir.file("a.lcm") + ":/tf", &log, &channel));
  EXPECT_EQ(log, dir.file("a.lcm"));
  EXPECT_EQ(channel, "/tf");
  // A bag folder is a log; the last ':' splits, so a log's name may hold ':' and a channel's may not.
  ASSERT_TRUE(split_log_channel(dir.file("bag") + ":odom", &log, &channel));
  EXPECT_EQ(channel, "odom");
  log = channel = "unchanged";
  EXPECT_FALSE(split_log_channel(dir.file("bag") + ":ns:odom", &log, &channel));
  // A source whose part before the last ':' is no file is not split (a TUM file named with a ':').
  EXPECT_FALSE(split_log_channel(dir.file("absent.lcm") + ":IMU", &log, &channel));
  EXPECT_FALSE(split_log_channel(dir.file("a.lcm") + ":", &log, &channel));
  EXPECT_FALSE(split_log_channel(":IMU", &log, &channel));
  EXPECT_EQ(log, "unchanged");
  // The output may alias the input.
  std::string src = dir.file("a.lcm") + ":SCAN";
  ASSERT_TRUE(split_log_channel(src, &src, &channel));
  EXPECT_EQ(src, dir.file("a.lcm"));
  EXPECT_EQ(channel, "SCAN");
}

}  // namespace
}  // namespace driftlab::analyzers
