// slam::Slam3d and slam::make_slam3d (3D point-cloud odometry with PCL registration) end to end on 25 s of the
// simulated 16 x 1800 lidar (sim/scenarios/indoor_3d.yaml), played in arrival order through the fake bus
// (tests/fakes/fake_bus.h, the replay host): the SLAM path of each method (icp, ndt, gicp) against ground truth,
// compared with what wrong answers score (standing still; an odometry 10% too long, alone); registration without
// odometry; dropped-cloud counts; the PCD map; config errors; the warnings when there are no clouds or no sensor pose
// in TF.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>

#include "analyzers/trajectory.h"
#include "core/log_reader.h"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "sim/scenario.h"
#include "sim/simulator.h"
#include "slam/slam3d.h"
#include "tests/doc_figures.h"
#include "tests/fakes/fake_bus.h"
#include "tests/test_util.h"

namespace driftlab::slam {
namespace {

Eigen::Quaterniond quat(const driftlab::quaternion_t& q) { return Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized(); }

/// pose_t or odometry_t messages of a channel as a trajectory, by header stamp.
template <typename T>
analyzers::Trajectory trajectory(const std::vector<std::pair<std::string, std::vector<uint8_t>>>& messages,
                                 const std::string& channel) {
  analyzers::Trajectory t;
  for (const auto& [ch, data] : messages) {
    T m;
    if (ch != channel || m.decode(data.data(), 0, static_cast<int>(data.size())) < 0) continue;
    t.push_back(static_cast<double>(m.header.utime) * 1e-6, {m.position.x, m.position.y, m.position.z},
                quat(m.orientation));
  }
  return t;
}

/// The estimate moved so that its first matched pose is ground truth's (SE(3)), and the matched pairs.
struct FirstPoseAligned {
  analyzers::Matched m;
  analyzers::Alignment a;
};
FirstPoseAligned align_first(const analyzers::Trajectory& gt, const analyzers::Trajectory& est) {
  FirstPoseAligned r;
  r.m = analyzers::match_nearest(gt, est, 0.006, 0);
  if (r.m.est.size() == 0) return r;
  r.a.type = analyzers::AlignmentType::kSe3;
  r.a.rotation = (r.m.ref.orientations[0] * r.m.est.orientations[0].conjugate()).toRotationMatrix();
  r.a.translation = r.m.ref.positions[0] - r.a.rotation * r.m.est.positions[0];
  r.m.est = analyzers::apply(r.a, std::move(r.m.est));
  return r;
}

/// Translation RMS error [m] after aligning the first pose.
double ate_first_pose(const analyzers::Trajectory& gt, const analyzers::Trajectory& est, size_t* matched = nullptr) {
  const FirstPoseAligned f = align_first(gt, est);
  if (matched != nullptr) *matched = f.m.est.size();
  return f.m.est.size() == 0 ? INFINITY : analyzers::ape(f.m).trans.rmse;
}

/// A rewrite that makes the wheel odometry wrong: its positions scaled by `scale` (a wheel radius off by as much).
test::FakeBus::Rewrite scale_odometry(double scale) {
  return [scale](const std::string& channel, std::vector<uint8_t>& bytes) {
    driftlab::odometry_t o;
    if (channel != "ODOM" || o.decode(bytes.data(), 0, static_cast<int>(bytes.size())) < 0) return;
    o.position.x *= scale;
    o.position.y *= scale;
    bytes.resize(static_cast<size_t>(o.getEncodedSize()));
    o.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  };
}

class Slam3dSession : public ::testing::Test {
 protected:
  /// 25 s of the 3D-lidar scenario, simulated once, and the ground truth and odometry read from it.
  static void SetUpTestSuite() {
    dir_ = new test::TempDir;
    auto scenario = sim::load_scenario(std::string(DRIFTLAB_SOURCE_DIR) + "/sim/scenarios/indoor_3d.yaml");
    ASSERT_TRUE(scenario) << scenario.error().message;
    scenario->duration = 25;
    auto simulation = sim::Simulation::create(*scenario);
    ASSERT_TRUE(simulation) << simulation.error().message;
    sim::SimOptions options;
    options.out = log();
    auto report = (*simulation)->run(options);
    ASSERT_TRUE(report) << report.error().message;
    ASSERT_EQ(report->messages["POINTS"], 250);
    std::vector<std::pair<std::string, std::vector<uint8_t>>> small;
    for (auto& e : test::read_all(log())) {
      if (e.channel == "GROUND_TRUTH" || e.channel == "ODOM") small.emplace_back(e.channel, std::move(e.data));
    }
    gt_ = new analyzers::Trajectory(trajectory<driftlab::pose_t>(small, "GROUND_TRUTH"));
    odom_ = new analyzers::Trajectory(trajectory<driftlab::odometry_t>(small, "ODOM"));
  }
  static void TearDownTestSuite() {
    delete gt_;
    delete odom_;
    delete dir_;
  }
  static std::string log() { return dir_->file("session.lcm"); }

  struct Run {
    analyzers::Trajectory path;  ///< SLAM_POSE
    ModuleCounters counters;
    double ate = INFINITY;       ///< first pose aligned [m]
    size_t matched = 0;          ///< poses matched to ground truth
  };
  /// Plays the session through a Slam3d made from `yaml`; artifacts under `prefix` when non-empty.
  static Run run(const std::string& yaml, const std::string& prefix = {}, const test::FakeBus::Rewrite& rewrite = {}) {
    Run r;
    auto module = make_slam3d(YAML::Load(yaml), "test.yaml");
    EXPECT_TRUE(module) << module.error().message;
    if (!module) return r;
    test::FakeBus bus({.artifact_prefix = prefix});
    bus.add(**module);
    const Status played = bus.run(log(), "POINTS|ODOM|TF_STATIC", rewrite);
    EXPECT_TRUE(played) << played.message();
    std::vector<std::pair<std::string, std::vector<uint8_t>>> out;
    for (auto& p : bus.published()) out.emplace_back(p.channel, std::move(p.data));
    r.path = trajectory<driftlab::pose_t>(out, "SLAM_POSE");
    r.counters = (*module)->counters();
    r.ate = ate_first_pose(*gt_, r.path, &r.matched);
    return r;
  }
  static double metric(const ModuleCounters& c, const std::string& name) {
    for (const auto& [k, v] : c.metrics) {
      if (k == name) return v;
    }
    ADD_FAILURE() << "no metric " << name;
    return NAN;
  }

  /// What wrong answers score, at the SLAM path's stamps: standing still at the first pose, and the wheel
  /// odometry (the module's prior) alone.
  static double still_ate(const Run& r) {
    analyzers::Trajectory still;
    for (size_t i = 0; i < r.path.size(); ++i) still.push_back(r.path.stamps[i], r.path.positions[0], r.path.orientations[0]);
    return ate_first_pose(*gt_, still);
  }
  static double odometry_ate(const Run& r) {
    // The odometry at each cloud stamp (nearest sample, 50 Hz), so both are scored on the same poses.
    const analyzers::Matched m = analyzers::match_nearest(r.path, *odom_, 0.011, 0);
    return ate_first_pose(*gt_, m.est);
  }

  /// Checks one method's run against the truth and the wrong answers; returns its ATE.
  static double check(const std::string& yaml, double bound, const char* label) {
    const Run r = run(yaml);
    EXPECT_EQ(r.path.size(), 250u) << label;  // a pose per cloud
    EXPECT_GE(r.matched, 245u) << label;
    EXPECT_EQ(r.counters.dropped, 0) << label;
    EXPECT_TRUE(r.counters.warnings.empty()) << label << ": " << r.counters.warnings.front();
    const double still = still_ate(r), odo = odometry_ate(r);
    std::printf("%-28s ATE %.4f m (first pose aligned); standing still %.3f m, odometry alone %.4f m; %g keyframes, "
                "mean fitness %.4f m2, max %.4f m2\n",
                label, r.ate, still, odo, metric(r.counters, "keyframes"), metric(r.counters, "mean_fitness_m2"),
                metric(r.counters, "max_fitness_m2"));
    EXPECT_LT(r.ate, bound) << label;
    EXPECT_LT(r.ate, 0.03 * still) << label;
    expect_doc_row(label, {r.ate});
    return r.ate;
  }

  /// docs/slam.md's table of these runs (3D, "Accuracy"): the row `label` holds `values`.
  static void expect_doc_row(const std::string& label, const std::vector<double>& values) {
    test::expect_doc_figures("docs/slam.md", "`tests/slam/slam3d_test.cc` simulates 25 s", label, 1, values);
  }

  static test::TempDir* dir_;
  static analyzers::Trajectory* gt_;
  static analyzers::Trajectory* odom_;
};
test::TempDir* Slam3dSession::dir_ = nullptr;
analyzers::Trajectory* Slam3dSession::gt_ = nullptr;
analyzers::Trajectory* Slam3dSession::odom_ = nullptr;

TEST_F(Slam3dSession, GroundTruthMovesEnoughToTellRightFromWrong) {
  ASSERT_GT(gt_->size(), 2000u);
  EXPECT_GT(gt_->path_length(), 8.0);
  ASSERT_GT(odom_->size(), 1000u);
}

TEST_F(Slam3dSession, NdtFollowsTheRobotAndWritesAPcdMap) {
  const Run r = run("method: ndt", dir_->file("ndt"));
  ASSERT_EQ(r.path.size(), 250u);
  const double still = still_ate(r), odo = odometry_ate(r);
  std::printf("ndt: ATE %.4f m, still %.3f m, odometry %.4f m, %g keyframes, %g map points\n", r.ate, still, odo,
              metric(r.counters, "keyframes"), metric(r.counters, "map_points"));
  EXPECT_LT(r.ate, 0.05);
  EXPECT_LT(r.ate, 0.02 * still);
  EXPECT_EQ(r.counters.dropped, 0);
  EXPECT_TRUE(r.counters.warnings.empty());
  expect_doc_row("ndt", {r.ate});
  expect_doc_row("standing still (a wrong answer)", {still});
  expect_doc_row("the wheel odometry alone", {odo});
  // Poses are stamped with their cloud's stamp, base_link in map, the first at the origin.
  EXPECT_NEAR(r.path.positions[0].norm(), 0, 1e-9);

  // The map: a binary PCD that PCL loads, of a sane size, and lying in the 20 m x 12 m building once the first
  // pose is put where ground truth says it was.
  const std::string pcd = dir_->file("ndt-map.pcd");
  EXPECT_FALSE(std::filesystem::exists(pcd + ".partial"));
  pcl::PointCloud<pcl::PointXYZ> map;
  ASSERT_EQ(pcl::io::loadPCDFile(pcd, map), 0);
  EXPECT_EQ(static_cast<double>(map.size()), metric(r.counters, "map_points"));
  EXPECT_GT(map.size(), 20000u);
  EXPECT_LT(map.size(), 2000000u);
  const FirstPoseAligned f = align_first(*gt_, r.path);
  size_t inside = 0;
  for (const auto& p : map) {
    ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    const Eigen::Vector3d w = f.a.rotation * Eigen::Vector3d(p.x, p.y, p.z) + f.a.translation;
    inside += w.x() > -0.3 && w.x() < 20.3 && w.y() > -0.3 && w.y() < 12.3 && w.z() > -0.3 && w.z() < 10;
  }
  EXPECT_GT(static_cast<double>(inside), 0.99 * static_cast<double>(map.size()));
  // Written as PCL writes it (slam3d.cc writes it itself, not to link libpcl_io and VTK): PCL's writer gives the
  // same bytes.
  const std::string by_pcl = dir_->file("ndt-map-by-pcl.pcd");
  ASSERT_EQ(pcl::io::savePCDFileBinary(by_pcl, map), 0);
  EXPECT_EQ(test::read_file(pcd), test::read_file(by_pcl));
  std::ifstream in(pcd);
  std::string line;
  while (std::getline(in, line) && line.rfind("DATA", 0) != 0) {
  }
  EXPECT_EQ(line, "DATA binary");
}

TEST_F(Slam3dSession, IcpFollowsTheRobot) { check("method: icp", 0.15, "icp"); }

TEST_F(Slam3dSession, GicpFollowsTheRobot) { check("method: gicp", 0.05, "gicp"); }

TEST_F(Slam3dSession, NdtFollowsTheRobotWithoutOdometry) {
  // Registration alone, the last motion as the guess: no help from the wheels.
  const Run r = run("method: ndt\nodom_channel: ''\n");
  ASSERT_EQ(r.path.size(), 250u);
  const double still = still_ate(r);
  std::printf("ndt without odometry: ATE %.4f m, still %.3f m\n", r.ate, still);
  EXPECT_LT(r.ate, 0.05);
  EXPECT_LT(r.ate, 0.02 * still);
  EXPECT_EQ(r.counters.dropped, 0);
  EXPECT_TRUE(r.counters.warnings.empty());  // odom_channel "" asks for no odometry: nothing to warn about
  expect_doc_row("ndt without odometry (registration alone)", {r.ate});
}

TEST_F(Slam3dSession, RegistrationCorrectsAWrongPrior) {
  // The wheel odometry made 10% too long (a wheel radius off by as much): alone it ends about a metre off.
  const Run r = run("method: ndt", {}, scale_odometry(1.1));
  ASSERT_EQ(r.path.size(), 250u);
  analyzers::Trajectory wrong;
  for (size_t i = 0; i < odom_->size(); ++i) {
    wrong.push_back(odom_->stamps[i], {odom_->positions[i].x() * 1.1, odom_->positions[i].y() * 1.1, 0},
                    odom_->orientations[i]);
  }
  const double prior = ate_first_pose(*gt_, analyzers::match_nearest(r.path, wrong, 0.011, 0).est);
  std::printf("ndt with odometry 10%% too long: ATE %.4f m; that odometry alone %.3f m\n", r.ate, prior);
  EXPECT_GT(prior, 0.3);
  EXPECT_LT(r.ate, 0.05);
  EXPECT_LT(r.ate, 0.1 * prior);
  EXPECT_EQ(r.counters.dropped, 0);
  expect_doc_row("ndt with the odometry made 10% too long", {r.ate, prior});
}

TEST_F(Slam3dSession, CountsRejectedAndUnusableCloudsAsDropped) {
  // A fitness bound no match meets: every registration is rejected, the guess (odometry) stands in, and no cloud
  // after the first becomes a keyframe.
  const Run strict = run("method: icp\nmax_fitness: 0.0001\n");
  EXPECT_EQ(strict.path.size(), 250u);
  EXPECT_EQ(strict.counters.dropped, 249);
  EXPECT_EQ(metric(strict.counters, "rejected"), 249);
  EXPECT_EQ(metric(strict.counters, "keyframes"), 1);
  EXPECT_LT(strict.ate, 0.1);  // the wheel odometry's path

  // No return in range: nothing to register, no pose, and a warning saying so.
  const Run empty = run("min_range: 500\nmax_range: 1000\n");
  EXPECT_EQ(empty.path.size(), 0u);
  EXPECT_EQ(empty.counters.dropped, 250);
  ASSERT_EQ(empty.counters.warnings.size(), 1u);
  EXPECT_EQ(empty.counters.warnings[0],
            "slam3d: no cloud on POINTS had 100 returns within [min_range, max_range]: no poses, no map");
}

TEST_F(Slam3dSession, WarnsWhenTheLogHasNoClouds) {
  const std::string prefix = dir_->file("none");
  auto module = make_slam3d(YAML::Node(), "test.yaml");
  ASSERT_TRUE(module);
  test::FakeBus bus({.artifact_prefix = prefix});
  bus.add(**module);
  ASSERT_TRUE(bus.run(log(), "ODOM|TF_STATIC|GROUND_TRUTH"));
  EXPECT_TRUE(bus.published().empty());
  const ModuleCounters c = (*module)->counters();
  ASSERT_EQ(c.warnings.size(), 1u);
  EXPECT_EQ(c.warnings[0], "slam3d: no driftlab.point_cloud_t on POINTS: no poses, no map");
  EXPECT_EQ(c.dropped, 0);
  EXPECT_FALSE(std::filesystem::exists(prefix + "-map.pcd"));

  // Messages of another type on the cloud channel are counted and named.
  auto wrong = make_slam3d(YAML::Load("cloud_channel: GROUND_TRUTH\nodom_channel: ''\n"), "test.yaml");
  ASSERT_TRUE(wrong);
  test::FakeBus bus2;
  bus2.add(**wrong);
  ASSERT_TRUE(bus2.run(log(), "GROUND_TRUTH|TF_STATIC"));
  const ModuleCounters w = (*wrong)->counters();
  ASSERT_EQ(w.warnings.size(), 1u);
  EXPECT_EQ(w.warnings[0], "slam3d: no driftlab.point_cloud_t on GROUND_TRUTH (2501 messages of another type): "
                           "no poses, no map");
  EXPECT_EQ(w.dropped, 2501);  // 25 s at 100 Hz, both ends
}

TEST_F(Slam3dSession, WarnsWhenTheSensorPoseIsNotInTf) {
  const Run r = run("method: ndt\ntf_static_channel: NOWHERE\nsensor_pose: [0, 0, 0.4, 0]\n");
  ASSERT_EQ(r.counters.warnings.size(), 1u);
  EXPECT_EQ(r.counters.warnings[0],
            "slam3d: no base_link -> velodyne on NOWHERE before the first cloud: the sensor_pose setting was used");
  EXPECT_LT(r.ate, 0.05);  // the right pose, from the config
}

TEST(Slam3dConfig, BadSettingsAreOneLineNamingTheFileLineAndKey) {
  auto key = make_slam3d(YAML::Load("method: ndt\nvoxle: 0.3\n"), "slam.yaml");
  ASSERT_FALSE(key);
  EXPECT_EQ(key.error().message.rfind(
                "slam.yaml:2: unknown key 'slam.3d.voxle': did you mean 'voxel'? (known: cloud_channel, ", 0),
            0u)
      << key.error().message;
  EXPECT_EQ(key.error().message.find('\n'), std::string::npos);

  auto method = make_slam3d(YAML::Load("voxel: 0.3\nmethod: lsq\n"), "slam.yaml");
  ASSERT_FALSE(method);
  EXPECT_EQ(method.error().message, "slam.yaml:2: slam.3d.method = lsq must be icp, ndt or gicp");

  auto type = make_slam3d(YAML::Load("method: icp\nmax_iterations: lots\n"), "slam.yaml");
  ASSERT_FALSE(type);
  EXPECT_EQ(type.error().message.rfind("slam.yaml:2: slam.3d.max_iterations", 0), 0u) << type.error().message;

  auto negative = make_slam3d(YAML::Load("voxel: -1\n"), "slam.yaml");
  ASSERT_FALSE(negative);
  EXPECT_EQ(negative.error().message.rfind("slam.yaml:1: slam.3d.voxel", 0), 0u) << negative.error().message;

  auto defaults = parse_slam3d_config(YAML::Node(), "slam.yaml");
  ASSERT_TRUE(defaults);
  EXPECT_EQ(defaults->method, "ndt");
  EXPECT_TRUE(defaults->deskew);
}

}  // namespace
}  // namespace driftlab::slam
