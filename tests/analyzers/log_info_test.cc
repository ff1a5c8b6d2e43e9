// analyzers/log_info.h, what `driftlab info` says of a log, called as a library: our own log's channels and its
// text, a PX4 flight log imported (the types in the recording it came from, the flight's time of day from its GNSS
// receiver), and a file that is not a log refused in one line.
#include "analyzers/log_info.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "formats/import.h"
#include "tests/test_util.h"

namespace driftlab::analyzers {
namespace {

TEST(LogInfo, ChannelsRatesAndTextOfARecordedLog) {
  const std::string path = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";
  auto info = log_info(path);
  ASSERT_TRUE(info) << info.error().message;
  EXPECT_TRUE(info->source_types.empty());  // recorded by driftlab: no other tool's types
  EXPECT_FALSE(info->recorder);
  EXPECT_FALSE(info->utc.known);
  const nlohmann::json j = to_json(*info);
  ASSERT_EQ(j["channels"].size(), 7u);
  for (const auto& c : j["channels"]) {
    if (c["name"] == "IMU") {
      EXPECT_EQ(c["type"], "driftlab.imu_t");
      EXPECT_EQ(c["count"], 201);
      EXPECT_NEAR(c["rate_hz"].get<double>(), 200, 1e-6);  // 201 messages over exactly 1 s
    }
  }
  const std::string text = log_info_text(*info, 20);
  EXPECT_EQ(text.rfind(path + ": ", 0), 0u) << text;
  EXPECT_NE(text.find("\nIMU           driftlab.imu_t"), std::string::npos) << text;
  EXPECT_EQ(text.substr(text.size() - 13), "\nno problems\n");
}

TEST(LogInfo, AnImportedFlightLogSaysItsTypesAndTimeOfDay) {
  const std::string ulog = std::string(DRIFTLAB_SHARED_DATA) + "/ulog/sample_log_small.ulg";
  if (!std::filesystem::exists(ulog)) GTEST_SKIP() << ulog << " absent (../shared/data)";
  test::TempDir dir;
  const std::string log = dir.file("flight.lcm");
  ASSERT_TRUE(formats::import_log(ulog, log, [](const std::string&) {}));
  auto info = log_info(log);
  ASSERT_TRUE(info) << info.error().message;
  // Each channel keeps the ULog topic it was (pyulog finds vehicle_gps_position in this log: expected.json).
  EXPECT_EQ(info->source_types.at("vehicle_gps_position"), "vehicle_gps_position");
  ASSERT_TRUE(info->utc.known);
  EXPECT_EQ(info->utc.channel, "vehicle_gps_position");
  // The log's start in UTC is its boot time plus the receiver's offset: a flight of April 2021.
  EXPECT_EQ(info->utc.start_utc_us, info->utc.start_utime + info->utc.boot_to_utc_us);
  EXPECT_EQ(to_json(*info)["utc"]["start"].get<std::string>().rfind("2021-04-21 ", 0), 0u);
  EXPECT_NE(log_info_text(*info, 20).find("\nUTC (GNSS time, vehicle_gps_position"), std::string::npos);
}

TEST(LogInfo, AFileThatIsNotALogIsRefusedInOneLine) {
  test::TempDir dir;
  std::ofstream(dir.file("notes.lcm")) << "these are notes, not events\n";
  auto info = log_info(dir.file("notes.lcm"));
  ASSERT_FALSE(info);
  EXPECT_EQ(info.error().message.rfind(dir.file("notes.lcm") + ": ", 0), 0u) << info.error().message;
  EXPECT_EQ(info.error().message.find('\n'), std::string::npos);
}

}  // namespace
}  // namespace driftlab::analyzers
