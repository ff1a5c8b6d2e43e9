// The 2D SLAM module on a ROS 2 bag of a real robot, as a user of a ROS 2 robot brings one: the benchmark's ACES log
// (../shared/data/carmen) read from its ROS 1 bag by Foxglove's reader (@foxglove/rosbag) and written as a ROS 2
// MCAP file (CDR, zstd chunks, ros2msg schemas) by Foxglove's writers (@mcap/core, @foxglove/rosmsg2-serialization;
// tests/oracle), with the laser and odometry on topics of other names, the way a robot's launch files name them.
// `driftlab replay` takes the file as it is, with no config.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <map>
#include <string>

#include "tests/formats/oracle.h"
#include "tests/slam/carmen_slam.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using nlohmann::json;

/// A ROS 1 message as the oracle dumped it, made the ROS 2 message of the same type: a header has no seq, a time's
/// nanoseconds are `nanosec`.
void to_ros2(json& m) {
  if (m.is_array()) {
    for (json& e : m) to_ros2(e);
    return;
  }
  if (!m.is_object()) return;
  if (m.contains("stamp") && m.contains("frame_id")) m.erase("seq");
  if (m.contains("sec") && m.contains("nsec") && m.size() == 2) {
    m["nanosec"] = m["nsec"];
    m.erase("nsec");
  }
  for (auto& [key, value] : m.items()) to_ros2(value);
}

TEST(SlamOnARos2Bag, FindsItsTopicsByTypeAndGivesTheRos1BagsRun) {
  const auto files = test::carmen_run("aces");
  if (files.empty()) return;
  const auto ros1 = test::oracle_messages(files.bag);
  if (!ros1) return;
  ASSERT_GT(ros1->size(), 22000u);
  json spec = {{"profile", "ros2"}, {"compression", "zstd"}, {"messages", json::array()}};
  const std::map<std::string, std::string> renamed = {{"/scan", "/base_scan"}, {"/odom", "/wheel/odometry"}};
  int64_t sequence = 0;
  for (json m : *ros1) {
    const std::string topic = m["topic"].get<std::string>(), type = m["type"].get<std::string>();
    if (const auto r = renamed.find(topic); r != renamed.end()) m["topic"] = r->second;
    const size_t slash = type.find('/');
    ASSERT_NE(slash, std::string::npos) << type;
    m["type"] = type.substr(0, slash) + "/msg" + type.substr(slash);
    m["sequence"] = sequence++;
    m.erase("encoding");
    to_ros2(m["msg"]);
    spec["messages"].push_back(std::move(m));
  }
  test::TempDir dir;
  const std::string mcap = dir.file("aces.mcap");
  if (!test::oracle_write_mcap(spec, mcap)) return;

  // The ROS 2 bag as it is: converted once, its laser, odometry and mounting found by their types, and said.
  const auto replay = test::driftlab_json("replay " + mcap + " --modules slam --json -o " + dir.file("ros2.lcm"));
  const std::string notes = replay["notes"].dump();
  for (const char* found : {"scans from /base_scan", "odometry from /wheel/odometry", "mounting from /tf_static"}) {
    EXPECT_NE(notes.find(found), std::string::npos) << notes;
  }
  EXPECT_TRUE(replay["modules"][0]["warnings"].empty()) << replay["modules"][0]["warnings"];
  const auto& metrics = replay["modules"][0]["metrics"];
  test::check_loop_records(dir.file("ros2.lcm"), metrics);
  const auto error = test::relation_error(dir.file("ros2.lcm") + ":SLAM_TRAJECTORY", files.relations);
  std::printf("aces as a ROS 2 bag: relation error %.4f m, max %.3f m, %g loop closures\n",
              error["trans_m"]["mean"].get<double>(), error["trans_m"]["max"].get<double>(),
              metrics["loop_closures"].get<double>());
  // The bar of issue 30 (mean under 0.10 m, no relation 1.5 m or more off), over all of ACES's 1,279 relations.
  EXPECT_EQ(error["used"].get<size_t>(), 1279u);
  EXPECT_LT(error["trans_m"]["mean"].get<double>(), 0.10);
  EXPECT_LT(error["trans_m"]["max"].get<double>(), 1.5);

  // And the run the ROS 1 bag gives: the same messages at the same stamps in the same order, so the same poses,
  // loop records and map, byte for byte.
  ASSERT_EQ(
      test::run(test::kDriftlabProgram + " import " + files.bag + " -o " + dir.file("ros1-raw.lcm") + " >/dev/null"),
      0);
  ASSERT_EQ(test::run(test::kDriftlabProgram + " replay " + dir.file("ros1-raw.lcm") + " --modules slam -o " +
                      dir.file("ros1.lcm") + " >/dev/null 2>&1"),
            0);
  const auto from_ros1 = test::messages_on(dir.file("ros1.lcm"), "SLAM_");
  EXPECT_GT(from_ros1.size(), 7000u);
  EXPECT_TRUE(test::messages_on(dir.file("ros2.lcm"), "SLAM_") == from_ros1);
}

}  // namespace
}  // namespace driftlab
