// End-to-end tests of `driftlab info`: golden JSON for clean and damaged logs, and the exit codes.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "tests/test_util.h"

namespace driftlab {
namespace {

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kData = DRIFTLAB_TEST_DATA;

using test::CmdResult;
CmdResult driftlab(const std::string& args) { return test::run_capture(kDriftlab + " " + args); }

nlohmann::json golden(const std::string& name) {
  auto bytes = test::read_file(kData + "/" + name);
  return nlohmann::json::parse(bytes.begin(), bytes.end());
}

class InfoGolden : public ::testing::TestWithParam<const char*> {};

TEST_P(InfoGolden, JsonMatchesTheExpectedFile) {
  const std::string name = GetParam();
  // CmdResult from the data folder so "file" in the JSON is the bare name.
  CmdResult r;
  r.code = test::run("cd " + kData + " && " + kDriftlab + " info --json " + name + ".lcm", &r.out);
  ASSERT_EQ(r.code, 0);
  const auto actual = nlohmann::json::parse(r.out);
  const auto expected = golden(name + ".json");
  EXPECT_EQ(actual, expected) << "diff: " << nlohmann::json::diff(expected, actual).dump(2);
}

INSTANTIATE_TEST_SUITE_P(Logs, InfoGolden,
                         ::testing::Values("sample", "truncated", "garbage", "bad_lengths", "empty"));

TEST(Info, NamesTheTypeOfEveryChannelOfTheSample) {
  const auto j = golden("sample.json");
  std::map<std::string, std::string> types;
  for (const auto& c : j["channels"]) types[c["name"]] = c["type"].is_null() ? "" : c["type"].get<std::string>();
  EXPECT_EQ(types["IMU"], "driftlab.imu_t");
  EXPECT_EQ(types["SCAN"], "driftlab.laser_scan_t");
  EXPECT_EQ(types["ODOM"], "driftlab.odometry_t");
  EXPECT_EQ(types["GROUND_TRUTH"], "driftlab.pose_t");
  EXPECT_EQ(types["TF"], "driftlab.tf_t");
  EXPECT_EQ(types["CMD_VEL"], "driftlab.velocity_command_t");
}

TEST(Info, DamagedLogsKeepEveryIntactEvent) {
  const int64_t clean = golden("sample.json")["events"];
  EXPECT_EQ(golden("truncated.json")["events"].get<int64_t>(), clean - 1);
  EXPECT_EQ(golden("garbage.json")["events"].get<int64_t>(), clean);
  EXPECT_EQ(golden("bad_lengths.json")["events"].get<int64_t>(), clean - 2);
}

TEST(Info, TableShowsChannelsAndProblems) {
  CmdResult r = driftlab("info " + kData + "/bad_lengths.lcm");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("driftlab.imu_t"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("2 problems"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("bad_channel_length"), std::string::npos) << r.out;
}

TEST(Info, MissingFileDirectoryAndNonLogExitWithCode2AndOneLine) {
  for (const std::string& target : {std::string("/nonexistent/x.lcm"), kData, kData + "/not_a_log.txt"}) {
    CmdResult r = driftlab("info " + target);
    EXPECT_EQ(r.code, 2) << target;
    EXPECT_TRUE(r.out.empty()) << target;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(target), std::string::npos) << r.err;
  }
}

TEST(Info, UsageErrorsExitWithCode2) {
  EXPECT_EQ(driftlab("info").code, 2);
  EXPECT_EQ(driftlab("info --bogus x.lcm").code, 2);
  EXPECT_EQ(driftlab("no-such-command").code, 2);
  CmdResult help = driftlab("info --help");
  EXPECT_EQ(help.code, 0);
  EXPECT_NE(help.out.find("--json"), std::string::npos);
}

}  // namespace
}  // namespace driftlab
