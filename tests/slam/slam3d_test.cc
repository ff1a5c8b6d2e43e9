// The 3D point-cloud odometry (PCL registration) on a simulated 16 x 1800 lidar session: its path against ground
// truth for NDT and ICP, the PCD map, settings errors, and the warning when there are no clouds.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "analyzers/trajectory.h"
#include "analyzers/trajectory_io.h"
#include "replayer/replayer.h"
#include "slam/slam3d.h"
#include "tests/test_util.h"

namespace driftlab::slam {
namespace {

class Slam3dSession : public ::testing::Test {
 protected:
  /// 20 s of the 3D-lidar scenario, made once.
  static void SetUpTestSuite() {
    dir_ = new test::TempDir;
    ASSERT_EQ(test::run(std::string(DRIFTLAB_BIN_DIR) + "/driftlab sim " + DRIFTLAB_SOURCE_DIR +
                        "/sim/scenarios/indoor_3d.yaml --duration 20 -o " + log() + " >/dev/null"),
              0);
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string log() { return dir_->file("session.lcm"); }

  /// Replays the session through Slam3d with the given settings; the report and the ATE of SLAM_POSE [m].
  static std::pair<replay::ReplayReport, double> run(const std::string& yaml, const std::string& out) {
    auto config = parse_slam3d_config(YAML::Load(yaml), "test");
    EXPECT_TRUE(config) << config.error().message;
    replay::ReplayOptions o;
    o.logs = {log()};
    o.out = dir_->file(out);
    replay::Replayer r(o);
    r.add_module(std::make_unique<Slam3d>(*config));
    auto report = r.run();
    EXPECT_TRUE(report) << report.error().message;
    auto gt = analyzers::load_log_channel(log(), "GROUND_TRUTH");
    auto est = analyzers::load_log_channel(dir_->file(out), "SLAM_POSE");
    EXPECT_TRUE(gt && est);
    analyzers::Matched m = analyzers::match_nearest(*gt, *est, 0.01, 0);
    const auto alignment = analyzers::align(m, analyzers::AlignmentType::kPosYaw);
    m.est = analyzers::apply(alignment, std::move(m.est));
    return {*report, analyzers::ape(m).trans.rmse};
  }

  static test::TempDir* dir_;
};
test::TempDir* Slam3dSession::dir_ = nullptr;

TEST_F(Slam3dSession, NdtFollowsTheRobotAndWritesTheMap) {
  auto gt = analyzers::load_log_channel(log(), "GROUND_TRUTH");
  ASSERT_TRUE(gt);
  ASSERT_GT(gt->path_length(), 6.0);  // a still estimate would be metres off
  const auto [report, ate] = run("method: ndt", "ndt.lcm");
  const auto& m = report.modules[0];
  EXPECT_EQ(m.outputs, 200);  // a pose per cloud (10 Hz)
  EXPECT_TRUE(m.warnings.empty());
  EXPECT_LT(ate, 0.05);
  std::printf("NDT: ATE %.4f m over %.1f m\n", ate, gt->path_length());
  // A binary PCD of the keyframes, voxel-filtered.
  std::ifstream pcd(dir_->file("ndt-map.pcd"), std::ios::binary);
  ASSERT_TRUE(pcd);
  std::string line, fields;
  long points = 0;
  while (std::getline(pcd, line) && line.rfind("DATA", 0) != 0) {
    if (line.rfind("FIELDS", 0) == 0) fields = line;
    if (line.rfind("POINTS", 0) == 0) points = std::stol(line.substr(7));
  }
  EXPECT_EQ(fields, "FIELDS x y z");
  EXPECT_EQ(line, "DATA binary");
  EXPECT_GT(points, 5000);
}

TEST_F(Slam3dSession, IcpFollowsTheRobotToo) {
  const auto [report, ate] = run("method: icp\nvoxel: 0.3\n", "icp.lcm");
  EXPECT_EQ(report.modules[0].outputs, 200);
  EXPECT_LT(ate, 0.2);
  std::printf("ICP: ATE %.4f m\n", ate);
}

TEST(Slam3dConfig, BadSettingsNameTheFileLineAndKey) {
  auto method = parse_slam3d_config(YAML::Load("voxel: 0.3\nmethod: lsq\n"), "s.yaml");
  ASSERT_FALSE(method);
  EXPECT_EQ(method.error().message, "s.yaml:2: slam.3d.method = lsq must be icp, ndt or gicp");
  auto key = parse_slam3d_config(YAML::Load("ndt_res: 1\n"), "s.yaml");
  ASSERT_FALSE(key);
  EXPECT_EQ(key.error().message.rfind("s.yaml:1: unknown key 'slam.3d.ndt_res'", 0), 0u) << key.error().message;
}

TEST(Slam3d, WarnsWhenThereAreNoClouds) {
  test::TempDir dir;
  ASSERT_EQ(test::run(std::string(DRIFTLAB_BIN_DIR) + "/driftlab sim --duration 1 -o " + dir.file("s.lcm") +
                      " >/dev/null"),
            0);
  replay::ReplayOptions o;
  o.logs = {dir.file("s.lcm")};
  replay::Replayer r(o);
  r.add_module(std::make_unique<Slam3d>(Slam3dConfig{}));
  auto report = r.run();
  ASSERT_TRUE(report);
  ASSERT_EQ(report->modules[0].warnings.size(), 1u);
  EXPECT_EQ(report->modules[0].warnings[0], "slam: no driftlab.point_cloud_t on POINTS: no map built");
}

}  // namespace
}  // namespace driftlab::slam
