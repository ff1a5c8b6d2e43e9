// A real PX4 flight log beside a MAVROS-style bag of the same flight written by Foxglove's own MCAP writer
// (tests/oracle/write_mcap.mjs): `driftlab import BAG FLIGHT.ulg` and `driftlab diagnose BAG FLIGHT.ulg` put the
// flight log on the bag's clock (analyzers/flight_log_pair.h), and refuse a bag whose IMU is not the flight's.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <regex>
#include <set>

#include "driftlab/imu_t.hpp"
#include "formats/import.h"
#include "lcmtypes/validate.h"
#include "tests/formats/oracle.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using nlohmann::json;

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";

/// The FMUv4-Pro flight (9.6 s, hand-held motion: the CubeOrange and SITL flights sit still, so their rates are the
/// gyros' noise alone).
constexpr char kFlight[] = "ulog/sample_appended_multiple.ulg";
/// The bag's clock: the wall clock at the flight controller's boot (2023-11-14) plus an extra offset, as a companion
/// computer stamping MAVROS's messages with its own time sees it.
constexpr int64_t kBootOnWallClockUs = 1'700'000'000'000'000 + 12'345'678;

struct Sample {
  int64_t utime;
  double x, y, z;
};

/// The flight log's sensor_combined (imported by driftlab: its stamps are timestamp, checked against pyulog by
/// ulog_test).
std::vector<Sample> flight_imu(const std::string& ulog, const test::TempDir& dir) {
  const std::string log = dir.file("flight.lcm");
  auto r = formats::import_log(ulog, log, [](const std::string& p) { ADD_FAILURE() << p; });
  EXPECT_TRUE(r.ok()) << r.error().message;
  std::vector<Sample> out;
  for (const auto& e : test::read_all(log)) {
    if (e.channel != "sensor_combined") continue;
    const auto m = test::decode<imu_t>(e);
    out.push_back({m.header.utime, m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z});
  }
  return out;
}

/// A MAVROS bag of the flight: /mavros/imu/data every fifth sample of the flight controller's (250 Hz -> 50 Hz, as
/// MAVROS streams it by default), in ROS's forward-left-up frame, with 0.005 rad/s of Gaussian noise (a MEMS
/// gyro's at 50 Hz), stamped on the wall clock, arriving 3 ms later; `shuffled`: the same values in another order
/// (another motion, the same statistics).
json mavros_bag(const std::vector<Sample>& imu, bool shuffled) {
  std::vector<Sample> picked;
  for (size_t i = 0; i < imu.size(); i += 5) picked.push_back(imu[i]);
  std::mt19937_64 rng(27);
  if (shuffled) {
    std::vector<Sample> values = picked;
    std::shuffle(values.begin(), values.end(), rng);
    for (size_t i = 0; i < picked.size(); ++i) {
      picked[i] = {picked[i].utime, values[i].x, values[i].y, values[i].z};
    }
  }
  std::normal_distribution<double> noise(0.0, 0.005);
  json msgs = json::array();
  int64_t seq = 0;
  for (const Sample& s : picked) {
    const int64_t us = kBootOnWallClockUs + s.utime;
    const json stamp = {{"sec", us / 1'000'000}, {"nanosec", (us % 1'000'000) * 1000}};
    const json zero9 = std::vector<double>(9, 0.0);
    msgs.push_back(
        {{"topic", "/mavros/imu/data"},
         {"type", "sensor_msgs/msg/Imu"},
         {"time_ns", (us + 3000) * 1000},
         {"sequence", seq++},
         {"msg",
          {{"header", {{"stamp", stamp}, {"frame_id", "base_link"}}},
           {"orientation", {{"x", 0}, {"y", 0}, {"z", 0}, {"w", 1}}},
           {"orientation_covariance", zero9},
           {"angular_velocity", {{"x", s.x + noise(rng)}, {"y", -s.y + noise(rng)}, {"z", -s.z + noise(rng)}}},
           {"angular_velocity_covariance", zero9},
           {"linear_acceleration", {{"x", 0}, {"y", 0}, {"z", 9.81}}},
           {"linear_acceleration_covariance", zero9}}}});
  }
  return {{"profile", "ros2"}, {"compression", "zstd"}, {"messages", msgs}};
}

TEST(FlightLogBesideBag, TheFlightLogGoesOnTheBagsClock) {
  const std::string ulog = test::shared_data(kFlight);
  if (ulog.empty()) return;
  test::TempDir dir;
  const std::vector<Sample> imu = flight_imu(ulog, dir);
  ASSERT_GT(imu.size(), 2000u);
  const std::string bag = dir.file("flight.mcap"), both = dir.file("both.lcm");
  if (!test::oracle_write_mcap(mavros_bag(imu, false), bag)) return;

  const auto r = test::run_capture(kDriftlab + " import '" + bag + "' '" + ulog + "' -o '" + both + "'");
  ASSERT_EQ(r.code, 0) << r.err;
  // Said once: the method and the offset.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.out, m,
                                std::regex("IMUs' angular rates \\(sensor_combined against "
                                           "/mavros/imu/data, correlation ([0-9.]+) over ([0-9.]+) s\\): "
                                           "offset \\+([0-9.]+) s, drift not measured")))
      << r.out;
  EXPECT_GT(std::stod(m[1]), 0.95);
  EXPECT_NEAR(std::stod(m[2]), 9.6, 0.6);
  // The offset within 10 ms: half the bag's 20 ms IMU period, so that every flight-log sample lands nearest the bag
  // sample of the same instant. The mean |rate| over 0.5 s windows of a 50 Hz copy with noise against the 250 Hz
  // original, its peak found on a 10 ms grid and refined by a parabola: on this flight the injected offset came
  // back 2 to 7 ms early with noise from 0 to 0.02 rad/s (the 50 Hz copy's windows see other vibration peaks than
  // the original's).
  const double offset_s = std::stod(m[3]);
  EXPECT_NEAR(offset_s, static_cast<double>(kBootOnWallClockUs) * 1e-6, 10e-3);

  // In the log: the bag's IMU as recorded, the flight log's on the bag's clock (its stamps and its event times).
  int64_t bag_imu = 0, px4_imu = 0;
  for (const auto& e : test::read_all(both)) {
    if (e.channel == "/mavros/imu/data") ++bag_imu;
    if (e.channel != "sensor_combined") continue;
    const auto msg = test::decode<imu_t>(e);
    ASSERT_LT(static_cast<size_t>(px4_imu), imu.size());
    const int64_t want = kBootOnWallClockUs + imu[static_cast<size_t>(px4_imu++)].utime;
    EXPECT_NEAR(static_cast<double>(msg.header.utime), static_cast<double>(want), 10e3);
    EXPECT_EQ(e.utime, msg.header.utime);  // sensor_combined's timestamp is its sample's
  }
  EXPECT_EQ(bag_imu, (static_cast<int64_t>(imu.size()) + 4) / 5);
  EXPECT_EQ(px4_imu, static_cast<int64_t>(imu.size()));

  // diagnose of the pair: one recording on one clock, the flight log's latencies those of PX4 (sample to
  // publication, well under a millisecond for sensor_combined), none of 10^12 ms; its own account still found.
  const auto d = test::run_capture(kDriftlab + " diagnose '" + bag + "' '" + ulog + "' --json");
  ASSERT_EQ(d.code, 0) << d.err;
  const json j = json::parse(d.out);
  std::set<std::string> names;
  for (const auto& c : j.at("channels")) {
    names.insert(c.at("name").get<std::string>());
    if (c.at("latency_s").is_object()) {
      EXPECT_LT(c.at("latency_s").at("max").get<double>(), 0.01) << c.at("name");
      EXPECT_GE(c.at("latency_s").at("p50").get<double>(), 0.0) << c.at("name");
    }
  }
  EXPECT_TRUE(names.count("/mavros/imu/data") && names.count("sensor_combined") && names.count("vehicle_attitude"));
  ASSERT_EQ(j.at("clock_domains").size(), 1u) << j.at("clock_domains").dump();
  EXPECT_EQ(j.at("clock_domains")[0].at("kind"), "recorder");
  EXPECT_TRUE(j.at("flight_log").is_object());
  EXPECT_GT(j.at("start_utime").get<int64_t>(), 1'700'000'000'000'000);
  // The alignment is said on stderr on the run that converts, and again on a later run reading the conversion.
  EXPECT_NE(d.err.find("offset +1700000012.3"), std::string::npos) << d.err;
  const auto again = test::run_capture(kDriftlab + " diagnose '" + bag + "' '" + ulog + "' --json");
  EXPECT_NE(again.err.find("reading its conversion"), std::string::npos) << again.err;
  EXPECT_NE(again.err.find("offset +1700000012.3"), std::string::npos) << again.err;

  // report of the pair: one recording (not a recording and its replay), its streams those of both, and the flight's
  // timeline drawn from the flight log's own account.
  const std::string out = dir.file("report");
  const auto rep = test::run_capture(kDriftlab + " report '" + bag + "' '" + ulog + "' -o '" + out + "'");
  ASSERT_EQ(rep.code, 0) << rep.err;
  EXPECT_TRUE(std::filesystem::exists(out + "/flight_timeline.png"));
  std::ifstream data(out + "/report.json");
  const json page = json::parse(data);
  ASSERT_EQ(page.at("logs").size(), 1u);
  EXPECT_EQ(page.at("logs")[0].at("path"), bag + " + " + ulog);
  std::set<std::string> drawn;
  for (const auto& st : page.at("streams")) drawn.insert(st.at("channel").get<std::string>());
  EXPECT_TRUE(drawn.count("/mavros/imu/data") && drawn.count("sensor_combined")) << page.at("streams").dump();
}

TEST(FlightLogBesideBag, ABagOfAnotherMotionIsRefusedInOneLine) {
  const std::string ulog = test::shared_data(kFlight);
  if (ulog.empty()) return;
  test::TempDir dir;
  const std::vector<Sample> imu = flight_imu(ulog, dir);
  const std::string bag = dir.file("other.mcap");
  if (!test::oracle_write_mcap(mavros_bag(imu, true), bag)) return;
  for (const std::string& cmd : {"import '" + bag + "' '" + ulog + "' -o '" + dir.file("both.lcm") + "'",
                                 "diagnose '" + bag + "' '" + ulog + "'"}) {
    const auto r = test::run_capture(kDriftlab + " " + cmd);
    EXPECT_EQ(r.code, 2) << cmd;
    EXPECT_EQ(r.out, "");
    // One line naming both recordings and why (the lines before it say what is being converted).
    const size_t at = r.err.find("cannot put " + ulog + " on " + bag + "'s clock: ");
    ASSERT_NE(at, std::string::npos) << r.err;
    // Each way tried, and why it failed: the IMUs' motions differ, and the bag has no time sync, the flight no GNSS.
    EXPECT_NE(
        r.err.find("by the IMUs: sensor_combined against /mavros/imu/data: the IMUs' angular rates do not match", at),
        std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("by a time sync: the bag has no time sync", at), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("by GNSS time: no GNSS time in the flight log", at), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find('\n', at), r.err.size() - 1) << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("both.lcm")));
}

/// /mavros/state at 10 Hz over [from, to) on the bag's clock [us], and /mavros/timesync_status at 10 Hz as MAVROS
/// writes it when its companion clock is `offset_us` ahead of the flight controller's boot clock: remote_timestamp
/// the controller's time of the exchange, the stamp the companion's a one-way trip (2 ms) later, the estimated
/// offset local - remote (MAVROS's sign), the observed one with 0.2 ms of jitter.
json status_bag(int64_t from, int64_t to, std::optional<int64_t> offset_us) {
  json msgs = json::array();
  auto stamp = [](int64_t us) { return json{{"sec", us / 1'000'000}, {"nanosec", (us % 1'000'000) * 1000}}; };
  int64_t seq = 0;
  for (int64_t us = from; us < to; us += 100'000) {
    msgs.push_back({{"topic", "/mavros/state"},
                    {"type", "mavros_msgs/msg/State"},
                    {"time_ns", (us + 1000) * 1000},
                    {"sequence", seq++},
                    {"msg",
                     {{"header", {{"stamp", stamp(us)}, {"frame_id", ""}}},
                      {"connected", true},
                      {"armed", false},
                      {"guided", false},
                      {"manual_input", true},
                      {"mode", "MANUAL"},
                      {"system_status", 3}}}});
    if (!offset_us) continue;
    const int64_t remote = us - *offset_us, local = us + 2000;
    const int64_t jitter_ns = (seq % 3 - 1) * 200'000;
    msgs.push_back({{"topic", "/mavros/timesync_status"},
                    {"type", "mavros_msgs/msg/TimesyncStatus"},
                    {"time_ns", (local + 300) * 1000},
                    {"sequence", seq++},
                    {"msg",
                     {{"header", {{"stamp", stamp(local)}, {"frame_id", ""}}},
                      {"remote_timestamp_ns", std::to_string(remote * 1000) + "n"},
                      {"observed_offset_ns", std::to_string(*offset_us * 1000 + jitter_ns) + "n"},
                      {"estimated_offset_ns", std::to_string(*offset_us * 1000) + "n"},
                      {"round_trip_time_ms", 4.0}}}});
  }
  return {{"profile", "ros2"}, {"compression", "none"}, {"messages", msgs}};
}

TEST(FlightLogBesideBag, ABagWithoutAnImuIsRefused) {
  const std::string ulog = test::shared_data(kFlight);
  if (ulog.empty()) return;
  test::TempDir dir;
  const std::string bag = dir.file("status.mcap");
  if (!test::oracle_write_mcap(
          status_bag(kBootOnWallClockUs + 12'000'000, kBootOnWallClockUs + 14'000'000, std::nullopt), bag)) {
    return;
  }
  const auto r = test::run_capture(kDriftlab + " diagnose '" + bag + "' '" + ulog + "'");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("cannot put " + ulog + " on " + bag + "'s clock: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("by the IMUs: the bag has no IMU"), std::string::npos) << r.err;
}

/// The first sensor_combined stamp of the flight log alone and of the log of both [us].
std::pair<int64_t, int64_t> first_imu_stamps(const std::string& ulog, const std::string& both,
                                             const test::TempDir& dir) {
  const std::vector<Sample> imu = flight_imu(ulog, dir);
  for (const auto& e : test::read_all(both)) {
    if (e.channel == "sensor_combined" && !imu.empty()) return {imu[0].utime, test::decode<imu_t>(e).header.utime};
  }
  ADD_FAILURE() << both << ": no sensor_combined";
  return {0, 0};
}

/// Writes bag (Foxglove's writer), imports it with ulog and checks the alignment line says `said` and the flight
/// log moved by offset_us. False when the writer is not there (the test is skipped).
bool expect_on_bags_clock(const std::string& ulog, const json& bag, const std::string& said, int64_t offset_us,
                          const test::TempDir& dir) {
  const std::string mcap = dir.file("bag.mcap"), both = dir.file("both.lcm");
  if (!test::oracle_write_mcap(bag, mcap)) return false;
  const auto r = test::run_capture(kDriftlab + " import '" + mcap + "' '" + ulog + "' -o '" + both + "'");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find(said), std::string::npos) << r.out;
  const auto [alone, together] = first_imu_stamps(ulog, both, dir);
  EXPECT_EQ(together - alone, offset_us);
  return true;
}

// A bag whose only tie to the flight controller is MAVROS's time sync (no IMU): the flight log goes on the bag's
// clock by the offset MAVROS estimated, to the microsecond (every exchange says the same estimate; the observed
// offsets' jitter is not used), and the line says so.
TEST(FlightLogBesideBag, ATimeSyncPutsTheFlightLogOnTheBagsClock) {
  const std::string ulog = test::shared_data(kFlight);
  if (ulog.empty()) return;
  test::TempDir dir;
  expect_on_bags_clock(ulog, status_bag(kBootOnWallClockUs, kBootOnWallClockUs + 12'000'000, kBootOnWallClockUs),
                       "by the bag's time sync (/mavros/timesync_status, 120 exchanges, estimated offsets within 0.0 "
                       "ms): offset +1700000012.345678 s",
                       kBootOnWallClockUs, dir);
}

// A flight log with GNSS time beside a bag on UTC with neither an IMU nor a time sync: GNSS time puts the flight on
// the bag's clock (the CubeOrange flight's 32 fixes; the bag's status stamped in UTC while it flew). A bag on
// another clock (its stamps days away from the flight's UTC) is refused, saying why each way failed.
TEST(FlightLogBesideBag, GnssTimePutsTheFlightOnABagInUtc) {
  const std::string ulog = test::shared_data("ulog/sample_logging_tagged_and_default_params.ulg");
  if (ulog.empty()) return;
  // UTC = boot time + 1651221926.946000 s (`driftlab info` of the flight; pyulog's GPS fixes say the same).
  constexpr int64_t kBootToUtcUs = 1'651'221'926'946'000;
  test::TempDir dir;
  if (!expect_on_bags_clock(ulog, status_bag(kBootToUtcUs + 1'000'000, kBootToUtcUs + 8'000'000, std::nullopt),
                            "by GNSS time (vehicle_gps_position, 32 fixes agreeing within 0.0 ms), the bag's clock "
                            "taken as UTC: offset +1651221926.946000 s",
                            kBootToUtcUs, dir)) {
    return;
  }

  const std::string elsewhere = dir.file("elsewhere.mcap");
  if (!test::oracle_write_mcap(
          status_bag(kBootToUtcUs + 5 * 86'400'000'000, kBootToUtcUs + 5 * 86'400'000'000 + 7'000'000, std::nullopt),
          elsewhere)) {
    return;
  }
  const auto refused =
      test::run_capture(kDriftlab + " import '" + elsewhere + "' '" + ulog + "' -o '" + dir.file("no.lcm") + "'");
  EXPECT_EQ(refused.code, 2);
  EXPECT_NE(refused.err.find("by GNSS time: the flight was at 2022-04-29 08:45:"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("and the bag's events are at 2022-05-04 08:45:"), std::string::npos) << refused.err;
  EXPECT_FALSE(std::filesystem::exists(dir.file("no.lcm")));
}

}  // namespace
}  // namespace driftlab
