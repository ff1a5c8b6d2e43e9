// End-to-end tests of `driftlab info`: golden JSON for clean and damaged logs, and the exit codes.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/log_writer.h"
#include "driftlab/imu_t.hpp"
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

TEST(Info, SaysWhenLogTimesStepBackAndStampsAreFrozen) {
  // What MRPT 2.5's carmen2rawlog leaves: every observation given one stamp; and a log written out of time order.
  test::TempDir dir;
  {
    auto w = LogWriter::create(dir.file("t.lcm"));
    ASSERT_TRUE(w.ok());
    for (int64_t i = 0; i < 100; ++i) {
      driftlab::imu_t m{};
      m.header = {i, 1000000, "imu"};
      ASSERT_TRUE(w->write(1000000 + i * 10000, "FROZEN", test::encode(m)).ok());
      m.header.utime = 1000000 + i * 10000;
      ASSERT_TRUE(w->write(1000000 + i * 10000 - (i % 10 == 9 ? 50000 : 0), "BACK", test::encode(m)).ok());
    }
    ASSERT_TRUE(w->close().ok());
  }
  CmdResult r = driftlab("info " + dir.file("t.lcm"));
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("BACK: log times step back 10 times"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("FROZEN: 99 of 100 messages repeat the stamp before"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("BACK: 9"), std::string::npos) << r.out;  // BACK's stamps are all different
  EXPECT_NE(r.out.find("no framing problems"), std::string::npos) << r.out;
  const auto j = nlohmann::json::parse(driftlab("info --json " + dir.file("t.lcm")).out);
  EXPECT_EQ(j["channels"][0]["name"], "BACK");
  EXPECT_EQ(j["channels"][0]["times_back"], 10);
  EXPECT_EQ(j["channels"][1]["stamps_repeated"], 99);
  EXPECT_EQ(j["channels"][1]["stamped"], 100);
}

// Log times at the ends of int64_t (a corrupt time field): the duration and rates were subtracted in int64_t and came
// out negative, with "no problems". They are subtracted in doubles and the span is named; diagnose faults the channel.
TEST(Info, LogTimesAtTheEndsOfInt64AreNamedNotANegativeDuration) {
  test::TempDir dir;
  {
    auto w = LogWriter::create(dir.file("t.lcm"));
    ASSERT_TRUE(w.ok());
    for (int64_t i = 0; i < 100; ++i) {
      driftlab::imu_t m{};
      m.header = {i, 1000000 + i * 10000, "imu"};
      int64_t t = 1000000 + i * 10000;
      if (i == 0) t = INT64_MIN;
      if (i == 99) t = INT64_MAX;
      ASSERT_TRUE(w->write(t, "IMU", test::encode(m)).ok());
    }
    ASSERT_TRUE(w->close().ok());
  }
  CmdResult r = driftlab("info " + dir.file("t.lcm"));
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("100 events, 18446744073709.551 s"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("log times span 584,542 years"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("some events' times are corrupt (on IMU)"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("no problems"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("-0.0"), std::string::npos) << r.out;
  const auto j = nlohmann::json::parse(driftlab("info --json " + dir.file("t.lcm")).out);
  EXPECT_GT(j["duration_s"].get<double>(), 1.8e13);
  EXPECT_GE(j["channels"][0]["rate_hz"].get<double>(), 0.0);
  const auto d = nlohmann::json::parse(driftlab("diagnose --json " + dir.file("t.lcm")).out);
  EXPECT_GE(d["channels"][0]["rate_hz"].get<double>(), 0.0) << d["channels"][0].dump();
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
