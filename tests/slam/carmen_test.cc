// The 2D SLAM module on the whole of two public real logs, the SLAM benchmark's Intel Research Lab and ACES
// building (../shared/data/carmen), end to end as a user runs it: the ROS bag imported, replayed through the slam
// module with its defaults, scored by `driftlab eval` against the benchmark's relations (Kuemmerle et al. 2009)
// and against GMapping's corrected trajectory, and against MRPT's icp-slam on the same data in the same run.
// About 30 s in the normal build; too slow under the sanitizers, so its own binary whose label scripts/test leaves
// out there (slam_tests runs the first 500 s of Intel, sanitizers included).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "analyzers/trajectory_io.h"
#include "core/log_reader.h"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "lcmtypes/validate.h"
#include "tests/carmen_reference.h"
#include "tests/slam/carmen_slam.h"
#include "tests/slam/icp_slam.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

/// icp-slam's path on a rawlog `driftlab export rawlog` made from `log` (one step per scan or odometry message,
/// in the log's order), at the scans' stamps, as a TUM file.
void icp_slam_tum(const std::string& log, const std::string& path_txt, const std::string& tum) {
  std::vector<int64_t> scan_stamp;  // per step: the scan's stamp, or -1 for an odometry step
  auto reader = LogReader::open(log);
  ASSERT_TRUE(reader);
  Event e;
  while (reader->next(e)) {
    laser_scan_t scan;
    odometry_t odometry;
    if (lcmtypes::decode(e.data, scan) && scan.nranges >= 2) {
      scan_stamp.push_back(scan.header.utime);
    } else if (lcmtypes::decode(e.data, odometry)) {
      scan_stamp.push_back(-1);
    }
  }
  std::ifstream in(path_txt);
  std::ofstream out(tum);
  size_t step;
  double x, y, yaw;
  int scans = 0;
  while (in >> step >> x >> y >> yaw) {
    ASSERT_LT(step, scan_stamp.size());
    if (scan_stamp[step] < 0) continue;
    char line[200];
    std::snprintf(line, sizeof(line), "%.6f %.6f %.6f 0 0 0 %.9f %.9f\n", static_cast<double>(scan_stamp[step]) * 1e-6,
                  x, y, std::sin(yaw / 2), std::cos(yaw / 2));
    out << line;
    ++scans;
  }
  EXPECT_GT(scans, 1000);
}

struct Dataset {
  const char* name;
  size_t relations;
};

class SlamOnTheBenchmark : public ::testing::TestWithParam<Dataset> {};

TEST_P(SlamOnTheBenchmark, ClosesLoopsToCentimetresAndBeatsIcpSlam) {
  const Dataset& run = GetParam();
  const auto files = test::carmen_run(run.name);
  if (files.empty()) return;
  const std::string& relations = files.relations;
  test::TempDir dir;
  const std::string raw = dir.file("raw.lcm"), out = dir.file("slam.lcm");
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + files.bag + " -o " + raw + " >/dev/null"), 0);
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + files.corrected + " -o " + dir.file("corrected.lcm") +
                      " >/dev/null"),
            0);
  const std::string config = test::carmen_slam_config(dir);

  const auto replay = test::driftlab_json("replay " + raw + " --modules slam --config " + config + " --json -o " + out);
  const auto& metrics = replay["modules"][0]["metrics"];
  std::printf("%s: %s\n", run.name, metrics.dump().c_str());
  EXPECT_GT(metrics["loop_closures"].get<double>(), 20);
  EXPECT_TRUE(replay["modules"][0]["warnings"].empty()) << replay["modules"][0]["warnings"];

  // The trajectory as last optimised, against the benchmark's relations: loop-closing SLAM reaches 0.02-0.07 m
  // on these logs in the literature, scan matching alone about 0.2 m; 0.10 m is the bar (ours: 0.032 m
  // on Intel, 0.045 m on ACES).
  const auto ours = test::relation_error(out + ":SLAM_TRAJECTORY", relations);
  EXPECT_EQ(ours["used"].get<size_t>(), run.relations);
  const double mean = ours["trans_m"]["mean"].get<double>();
  EXPECT_LT(mean, 0.10);

  // Against GMapping's corrected trajectory (its scans matched to ours by their readings), aligned in the plane:
  // below 0.3 m (ours: 0.16 m on Intel, 0.12 m on ACES; plain scan matching is off by metres after a loop).
  auto gmapping = test::corrected_at_raw_stamps(raw, dir.file("corrected.lcm"));
  ASSERT_TRUE(gmapping) << gmapping.error().message;
  ASSERT_TRUE(analyzers::write_tum(dir.file("corrected.tum"), *gmapping).ok());
  const auto ate = test::driftlab_json("eval --gt " + dir.file("corrected.tum") + " --est " + out +
                                       ":SLAM_TRAJECTORY --align posyaw --max-dt 0.0001 --json -")["ate"];
  EXPECT_LT(ate["rmse"].get<double>(), 0.3);
  // The poses as published scan by scan carry the drift since the last loop closure, no jumps: before the loop
  // closures, a stale index in the map sent them 7-40 m back to the start (ours now: 0.24 m on Intel, 0.43 m on
  // ACES).
  const auto online = test::driftlab_json("eval --gt " + dir.file("corrected.tum") + " --est " + out +
                                          ":SLAM_POSE --align posyaw --max-dt 0.0001 --json -")["ate"];
  EXPECT_LT(online["rmse"].get<double>(), 1.0);
  EXPECT_LT(online["max"].get<double>(), 3.0);

  // --restamp auto applies only corrections the diagnosis is sure of: on these logs it leaves SLAM within 2%.
  const auto restamped = test::driftlab_json("replay " + raw + " --modules slam --config " + config +
                                             " --restamp auto --json -o " + dir.file("restamped.lcm"));
  ASSERT_FALSE(restamped.is_null());
  const double restamped_mean =
      test::relation_error(dir.file("restamped.lcm") + ":SLAM_TRAJECTORY", relations)["trans_m"]["mean"].get<double>();
  EXPECT_NEAR(restamped_mean, mean, 0.02 * mean);

  // MRPT's icp-slam, its demo configuration, on the same scans and odometry (`driftlab export rawlog`).
  ASSERT_EQ(
      test::run(test::kDriftlabProgram + " export rawlog " + raw + " -o " + dir.file("raw.rawlog") + " >/dev/null"), 0);
  ASSERT_EQ(test::run_icp_slam(dir, dir.file("raw.rawlog")), 0);
  ASSERT_NO_FATAL_FAILURE(icp_slam_tum(raw, dir.file("icp/log_estimated_path.txt"), dir.file("icp.tum")));
  const double peer = test::relation_error(dir.file("icp.tum"), relations)["trans_m"]["mean"].get<double>();
  std::printf("%s: relation error %.4f m (icp-slam %.4f m), ATE %.4f m, as published %.4f m\n", run.name, mean, peer,
              ate["rmse"].get<double>(), online["rmse"].get<double>());
  EXPECT_LT(mean, peer);
}

INSTANTIATE_TEST_SUITE_P(Carmen, SlamOnTheBenchmark, ::testing::Values(Dataset{"intel", 2984}, Dataset{"aces", 1279}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace driftlab
