// Tests for analyzers/relations.h: the relations file, the relation error and its statistics, odometry bridging.
#include "analyzers/relations.h"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/test_util.h"

namespace driftlab::analyzers {
namespace {

Eigen::Quaterniond yaw(double a) { return Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ())); }

/// A planar path: pose k at stamp k / 4 [s], moving 1 m along its heading and turning 0.1 rad each step.
Trajectory planar(int n) {
  Trajectory t;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  double heading = 0;
  for (int k = 0; k < n; ++k) {
    t.push_back(0.25 * k, p, yaw(heading));
    p += Eigen::Vector3d(std::cos(heading), std::sin(heading), 0);
    heading += 0.1;
  }
  return t;
}

/// The relation between poses i and j of t, as the benchmark writes it.
Relation relation_of(const Trajectory& t, size_t i, size_t j) {
  Relation r;
  r.t1 = t.stamps[i];
  r.t2 = t.stamps[j];
  r.translation = t.orientations[i].conjugate() * (t.positions[j] - t.positions[i]);
  r.rotation = t.orientations[i].conjugate() * t.orientations[j];
  return r;
}

TEST(LoadRelations, ReadsTheBenchmarkFormatWithRollPitchYaw) {
  test::TempDir dir;
  const std::string text = "# t1 t2 x y z roll pitch yaw\n976052905.167303 976052911.885496 -0.05699 -0.12843 0 0 0 "
                           "-1.68221\n\n1 2 0 0 0 0.1 0.2 0.3\n";
  test::write_file(dir.file("r"), {text.begin(), text.end()});
  auto r = load_relations(dir.file("r"));
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->size(), 2u);
  EXPECT_DOUBLE_EQ((*r)[0].t1, 976052905.167303);
  EXPECT_DOUBLE_EQ((*r)[0].translation.y(), -0.12843);
  EXPECT_NEAR(rotation_angle((*r)[0].rotation), 1.68221, 1e-12);
  // Roll about x first, then pitch about y, then yaw about z (all about the fixed axes): Rz Ry Rx.
  const Eigen::Matrix3d want = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                                Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()))
                                   .toRotationMatrix();
  EXPECT_TRUE((*r)[1].rotation.toRotationMatrix().isApprox(want, 1e-12));
}

TEST(LoadRelations, ErrorsNameTheFileAndLine) {
  test::TempDir dir;
  const std::pair<std::string, std::string> cases[] = {
      {"1 2 0 0 0 0 0 0\n1 2 3\n", ":2: expected 8 numbers"},
      {"1 2 0 0 0 0 0 x\n", ":1: not a number"},
      {"1 2 0 0 0 0 0 nan\n", ":1: a number is not finite"},
      {"# nothing\n", ": no relations"},
  };
  for (const auto& [text, expected] : cases) {
    test::write_file(dir.file("bad"), {text.begin(), text.end()});
    auto r = load_relations(dir.file("bad"));
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_NE(r.error().message.find(dir.file("bad") + expected), std::string::npos) << r.error().message;
  }
  EXPECT_FALSE(load_relations(dir.file("missing")).ok());
}

TEST(RelationError, IsZeroForTheTrajectoryTheRelationsCameFrom) {
  const Trajectory truth = planar(30);
  std::vector<Relation> rels;
  for (size_t i = 0; i + 3 < truth.size(); ++i) rels.push_back(relation_of(truth, i, i + 3));
  const RelationResult r = relation_error(truth, rels);
  EXPECT_EQ(r.relations, rels.size());
  EXPECT_EQ(r.used, rels.size());
  EXPECT_LT(r.trans_m.max, 1e-12);
  EXPECT_LT(r.rot_deg.max, 1e-6);
}

TEST(RelationError, MeasuresTheRelativeMotionNotTheFrame) {
  const Trajectory truth = planar(10);
  // The estimate in another frame (rotated and moved: no alignment needed) and with one pose displaced by 0.1 m
  // sideways and turned by 2 degrees: only the relations touching that pose see an error.
  Trajectory est;
  const Eigen::Quaterniond frame = yaw(1.0);
  for (size_t k = 0; k < truth.size(); ++k) {
    Eigen::Vector3d p = truth.positions[k];
    Eigen::Quaterniond q = truth.orientations[k];
    if (k == 5) {
      p += q * Eigen::Vector3d(0, 0.1, 0);
      q = q * yaw(2.0 * M_PI / 180);
    }
    est.push_back(truth.stamps[k], frame * p + Eigen::Vector3d(5, -3, 0), frame * q);
  }
  std::vector<Relation> rels = {relation_of(truth, 0, 1), relation_of(truth, 4, 5), relation_of(truth, 5, 6)};
  const RelationResult r = relation_error(est, rels);
  ASSERT_EQ(r.used, 3u);
  EXPECT_NEAR(r.trans_errors_m[0], 0.0, 1e-12);
  EXPECT_NEAR(r.rot_errors_deg[0], 0.0, 1e-6);
  // 4 -> 5: the displacement, seen from pose 4's frame: still 0.1 m; the rotation 2 degrees.
  EXPECT_NEAR(r.trans_errors_m[1], 0.1, 1e-12);
  EXPECT_NEAR(r.rot_errors_deg[1], 2.0, 1e-9);
  EXPECT_NEAR(r.rot_errors_deg[2], 2.0, 1e-9);
  // Statistics: mean, sample standard deviation, max, and the same of the squares.
  const double m = (0 + 2 * 2.0) / 3.0;
  EXPECT_NEAR(r.rot_deg.mean, m, 1e-9);
  EXPECT_NEAR(r.rot_deg.std, std::sqrt((m * m + 2 * (2 - m) * (2 - m)) / 2), 1e-9);
  EXPECT_NEAR(r.rot_deg.max, 2.0, 1e-9);
  EXPECT_NEAR(r.rot_sq_deg2.mean, 8.0 / 3, 1e-8);
  EXPECT_NEAR(r.rot_sq_deg2.max, 4.0, 1e-8);
  EXPECT_NEAR(r.trans_sq_m2.max, r.trans_m.max * r.trans_m.max, 1e-15);
}

TEST(RelationError, StampsMustMatchWithinMaxDtElseOdometryCarriesTheNearestPose) {
  const Trajectory truth = planar(40);
  // The estimate holds every 4th pose only (as GMapping's corrected logs hold only the scans it integrated);
  // the odometry is the truth itself, so carrying poses with it adds no error.
  Trajectory sparse;
  for (size_t k = 0; k < truth.size(); k += 4) sparse.push_back(truth.stamps[k], truth.positions[k], truth.orientations[k]);
  std::vector<Relation> rels = {relation_of(truth, 0, 4), relation_of(truth, 1, 6), relation_of(truth, 8, 10)};
  RelationOptions options;
  options.max_dt = 1e-4;
  const RelationResult only_exact = relation_error(sparse, rels, options);
  EXPECT_EQ(only_exact.used, 1u);
  EXPECT_EQ(only_exact.index, std::vector<size_t>{0});
  options.odometry = &truth;
  const RelationResult bridged = relation_error(sparse, rels, options);
  EXPECT_EQ(bridged.used, 3u);
  EXPECT_EQ(bridged.bridged, 2u);
  EXPECT_DOUBLE_EQ(bridged.max_bridge_s, 0.5);  // pose 6 from pose 4 (8 is as near: the earlier wins)
  EXPECT_LT(bridged.trans_m.max, 1e-9);
  EXPECT_LT(bridged.rot_deg.max, 1e-6);
  // Odometry interpolated between its poses: at pose 9's stamp, halfway between the odometry's poses 8 and 10.
  Trajectory coarse_odometry;
  for (size_t k = 0; k < truth.size(); k += 2) {
    coarse_odometry.push_back(truth.stamps[k], truth.positions[k], truth.orientations[k]);
  }
  Relation half;
  half.t1 = truth.stamps[8];
  half.t2 = truth.stamps[9];
  const Eigen::Vector3d p9 = 0.5 * (truth.positions[8] + truth.positions[10]);
  const Eigen::Quaterniond q9 = truth.orientations[8].slerp(0.5, truth.orientations[10]);
  half.translation = truth.orientations[8].conjugate() * (p9 - truth.positions[8]);
  half.rotation = truth.orientations[8].conjugate() * q9;
  options.odometry = &coarse_odometry;
  const RelationResult interpolated = relation_error(sparse, {half}, options);
  ASSERT_EQ(interpolated.used, 1u);
  EXPECT_LT(interpolated.trans_m.max, 1e-12);
  // Odometry poses more than kMaxOdometryGap apart are not interpolated across.
  Trajectory gappy;
  gappy.push_back(0, truth.positions[0], truth.orientations[0]);
  gappy.push_back(truth.stamps[39], truth.positions[39], truth.orientations[39]);
  options.odometry = &gappy;
  EXPECT_EQ(relation_error(sparse, rels, options).used, 1u);
}

}  // namespace
}  // namespace driftlab::analyzers
