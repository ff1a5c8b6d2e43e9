// The 2D SLAM module on the first 500 s of the SLAM benchmark's Intel Research Lab log (2,527 scans; the robot
// is back in corridors it mapped before, so loops close), imported and replayed as a user does, scored against the
// benchmark's relations that fall in that stretch. Short enough for the sanitizer build; the whole Intel and ACES
// logs, with GMapping's trajectory and icp-slam beside them, are in carmen_test.cc.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

#include "tests/slam/carmen_slam.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

TEST(SlamOnIntel, TheFirst500SecondsCloseLoopsToCentimetres) {
  const std::string bag = test::shared_data("carmen/intel.orig.bag");
  const std::string relations = test::shared_data("carmen/intel.relations");
  if (bag.empty() || relations.empty()) return;
  test::TempDir dir;
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + bag + " -o " + dir.file("raw.lcm") + " >/dev/null"), 0);
  const auto replay = test::driftlab_json("replay " + dir.file("raw.lcm") + " --end 500 --modules slam --config " +
                                          test::carmen_slam_config(dir) + " --json -o " + dir.file("slam.lcm"));
  const auto& metrics = replay["modules"][0]["metrics"];
  EXPECT_GT(metrics["scans"].get<double>(), 2500);
  EXPECT_GT(metrics["loop_closures"].get<double>(), 10);  // 39 here
  test::check_loop_records(dir.file("slam.lcm"), metrics);  // SLAM_LOOPS: each test's outcome, as counted
  EXPECT_GT(std::filesystem::file_size(dir.file("slam-map.png")), 10000u);
  // The 405 relations between scans of the stretch; the whole log's bar (0.10 m) holds here too (0.028 m).
  const auto ours = test::relation_error(dir.file("slam.lcm") + ":SLAM_TRAJECTORY", relations);
  EXPECT_GT(ours["used"].get<double>(), 350);
  EXPECT_LT(ours["trans_m"]["mean"].get<double>(), 0.10);
}

}  // namespace
}  // namespace driftlab
