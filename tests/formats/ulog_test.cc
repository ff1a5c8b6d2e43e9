// PX4 flight logs (formats/ulog.h, and their import in formats/import.h): the shared real logs against what PX4's
// own reader, pyulog, finds in them (../shared/data/ulog/expected.json), and hostile files written here: cut short,
// damaged in the middle, an unknown incompatible flag, formats that do not resolve (an unknown nested type, a type
// containing itself, arrays too large for a ULog message).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>

#include "analyzers/flight_log.h"
#include "driftlab/barometer_t.hpp"
#include "driftlab/channel_source_t.hpp"
#include "driftlab/dropout_t.hpp"
#include "driftlab/foreign_message_t.hpp"
#include "driftlab/foreign_schema_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/log_text_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/motor_command_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/parameter_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/timesync_status_t.hpp"
#include "driftlab/trajectory_setpoint_t.hpp"
#include "driftlab/vehicle_status_t.hpp"
#include "formats/import.h"
#include "formats/ulog.h"
#include "lcmtypes/seq_origin.h"
#include "tests/formats/ulog_writer.h"
#include "tests/test_util.h"

namespace driftlab::formats {
namespace {

using test::OwnedEvent;

const std::set<std::string> kRecordChannels = {"ULOG_LOG",      "ULOG_PARAMS",     "ULOG_INFO",      "ULOG_UTC",
                                               "ULOG_DROPOUTS", "FOREIGN_SCHEMAS", "CHANNEL_SOURCES"};

using test::f32;
using test::put;
using test::Ulog;

/// A small flight: two topics (one in two instances), a logged string and a dropout.
Ulog small_flight() {
  Ulog u;
  u.flags(0);
  u.format("t:uint64_t timestamp;float x;");
  u.info("char[3] sys_name", {'P', 'X', '4'});
  u.subscribe(0, 1, "t");
  u.subscribe(1, 2, "t");
  for (int i = 0; i < 10; ++i) {
    u.data(1, 2000 + 100 * i, static_cast<float>(i));
    u.data(2, 2050 + 100 * i, static_cast<float>(-i));
  }
  u.logged('6', 2500, "takeoff");
  u.dropout(20);
  return u;
}

struct Read {
  std::vector<std::pair<uint64_t, std::string>> problems;
  std::vector<std::pair<uint64_t, std::vector<uint8_t>>> data;  // offset, payload
  mutable std::map<std::string, int64_t> per_topic;
  int64_t logged = 0, dropouts = 0;
  std::map<char, int64_t> unknown;  // records of unknown types skipped
  Status status;
};

/// What reader r reads: a log in memory, or a file (open).
Read read(Result<UlogReader> r) {
  Read out;
  if (!r) {
    out.status = r.error();
    return out;
  }
  UlogReader::Callbacks cb;
  cb.data = [&](const UlogData& d) {
    out.data.emplace_back(d.offset, std::vector<uint8_t>(d.payload.begin(), d.payload.end()));
    ++out.per_topic[d.subscription->name + "/" + std::to_string(d.subscription->multi_id)];
  };
  cb.logged = [&](const UlogLogged&) { ++out.logged; };
  cb.dropout = [&](const UlogDropout&) { ++out.dropouts; };
  cb.problem = [&](uint64_t offset, const std::string& what) { out.problems.emplace_back(offset, what); };
  out.status = r->read(cb);
  out.unknown = r->unknown_types();
  return out;
}

Read read(std::vector<uint8_t> bytes) { return read(UlogReader::from_memory(std::move(bytes))); }

std::vector<uint8_t> file_bytes(const std::string& path) { return test::read_file(path); }

// ---- the shared real logs ----

nlohmann::json expected() {
  const std::string path = test::shared_data("ulog/expected.json");
  if (path.empty()) return {};
  std::ifstream f(path);
  return nlohmann::json::parse(f);
}

/// Every topic's count, the total, the first (the header's start) and last timestamp, the dropouts, the count of
/// logged strings and the information fields of the ULog at path equal what pyulog found in it (want: one entry of
/// expected.json); the import reports no problem on a whole file.
void expect_agrees_with_pyulog(const std::string& path, const nlohmann::json& want) {
  EXPECT_EQ(detect_format(path).format, Format::kUlog);
  EXPECT_EQ(detect_format(path).name, "PX4 ULog");
  test::TempDir dir;
  std::vector<std::string> problems;
  auto summary = import_log(path, dir.file("out.lcm"), [&](const std::string& p) { problems.push_back(p); });
  ASSERT_TRUE(summary) << summary.error().message;
  EXPECT_EQ(problems, std::vector<std::string>{});
  EXPECT_EQ(summary->format, "PX4 ULog");

  std::map<std::string, int64_t> counts;
  int64_t total = 0, last = 0, logged = 0;
  size_t sources = 0;
  std::vector<std::pair<int64_t, int64_t>> dropouts;
  std::map<std::string, std::string> info;
  for (const OwnedEvent& e : test::read_all(dir.file("out.lcm"))) {
    if (e.channel == "ULOG_DROPOUTS") {
      const auto d = test::decode<dropout_t>(e);
      dropouts.emplace_back(d.header.utime, d.duration_us);
      EXPECT_EQ(e.utime, d.header.utime);
    } else if (e.channel == "ULOG_LOG") {
      // expected.json counts pyulog's logged_messages: the untagged strings ('L'); the tagged ones ('C') are
      // its logged_messages_tagged (three in the SITL log, all kept here too).
      if (test::decode<log_text_t>(e).tag < 0) ++logged;
    } else if (e.channel == "ULOG_INFO") {
      const auto p = test::decode<parameter_t>(e);
      info[p.name] = p.text;
    } else if (e.channel == "CHANNEL_SOURCES") {
      // Each topic said once: its ULog name, and a seq the import counted (ULog has no sequence numbers).
      const auto src = test::decode<channel_source_t>(e);
      EXPECT_EQ(src.channel.substr(0, src.channel.find('/')), src.source_type);
      EXPECT_EQ(src.seq_origin, static_cast<int8_t>(lcmtypes::SeqOrigin::kCounted));
      ++sources;
    } else if (!kRecordChannels.count(e.channel)) {
      ++counts[e.channel];
      ++total;
      last = std::max(last, e.utime);
    }
  }
  std::map<std::string, int64_t> want_counts;
  for (const auto& [topic, n] : want["topics"].items()) want_counts[topic] = n.get<int64_t>();
  EXPECT_EQ(counts, want_counts);
  EXPECT_EQ(sources, want_counts.size());
  EXPECT_EQ(total, want["messages"].get<int64_t>());
  EXPECT_EQ(last, want["last_us"].get<int64_t>());
  EXPECT_EQ(logged, want["logged_strings"].get<int64_t>());
  std::vector<std::pair<int64_t, int64_t>> want_dropouts;
  for (const auto& d : want["dropouts"]) {
    want_dropouts.emplace_back(d["timestamp_us"].get<int64_t>(), d["duration_ms"].get<int64_t>() * 1000);
  }
  EXPECT_EQ(dropouts, want_dropouts);
  for (const auto& [key, value] : want["info"].items()) {
    EXPECT_EQ(info[key], value.is_string() ? value.get<std::string>() : value.dump()) << key;
  }

  auto r = UlogReader::open(path);
  ASSERT_TRUE(r);
  ASSERT_TRUE(r->read({}));
  EXPECT_EQ(static_cast<int64_t>(r->start_us()), want["start_us"].get<int64_t>());
  EXPECT_EQ(static_cast<int64_t>(r->last_us()), want["last_us"].get<int64_t>());
}

TEST(Ulog, ImportOfTheSharedLogsAgreesWithPyulog) {
  const nlohmann::json want_all = expected();
  if (want_all.empty()) return;
  ASSERT_EQ(want_all.size(), 3u);
  for (const auto& [file, want] : want_all.items()) {
    SCOPED_TRACE(file);
    const std::string path = test::shared_data("ulog/" + file);
    ASSERT_FALSE(path.empty());
    expect_agrees_with_pyulog(path, want);
  }
}

// Two more of pyulog's own test logs, of kinds the shared three are not: an AUAV-X2.1 flight on an older PX4
// (sample.ulg: control_state and ekf2_innovations, 64,542 messages, four dropouts, one of them 0 ms long) and a PX4
// 1.15 SITL flight (sample_px4_events.ulg: 69 topics, PX4's `event` topic, a boot clock that reads as Unix time,
// 1.7e15 us), held to what pyulog finds in them (tests/data/ulog/pyulog_more.json, written by pyulog_expected.py
// beside it). Run when they are in $DRIFTLAB_ULOG_DATA or ../shared/data/ulog; skipped otherwise, also under CI,
// until they are added there.
TEST(Ulog, MoreOfPyulogsLogsAgreeWithPyulog) {
  std::ifstream f(std::string(DRIFTLAB_SOURCE_DIR) + "/tests/data/ulog/pyulog_more.json");
  ASSERT_TRUE(f.good());
  const nlohmann::json want_all = nlohmann::json::parse(f);
  int ran = 0;
  for (const auto& [file, want] : want_all.items()) {
    SCOPED_TRACE(file);
    std::string path;
    for (const char* dir :
         {static_cast<const char*>(std::getenv("DRIFTLAB_ULOG_DATA")), DRIFTLAB_SHARED_DATA "/ulog"}) {
      if (dir != nullptr && std::filesystem::exists(std::string(dir) + "/" + file)) {
        path = std::string(dir) + "/" + file;
        break;
      }
    }
    if (path.empty()) continue;
    expect_agrees_with_pyulog(path, want);
    ++ran;
  }
  if (ran == 0)
    GTEST_SKIP() << "none of tests/data/ulog/pyulog_more.json's logs in $DRIFTLAB_ULOG_DATA or ../shared/data/ulog";
}

// A carried topic keeps its payload and its format (with the formats it nests) on FOREIGN_SCHEMAS; sensor_combined
// becomes imu_t stamped with its timestamp, seq counting its messages; every event's time is its message's
// timestamp field.
TEST(Ulog, MessagesKeepTheirFormatAndTime) {
  for (const char* name : {"sample_log_small.ulg", "sample_logging_tagged_and_default_params.ulg"}) {
    SCOPED_TRACE(name);
    const std::string path = test::shared_data(std::string("ulog/") + name);
    if (path.empty()) return;
    // The SITL log's vehicle_local_position has timestamp_sample (PX4 1.13); the CubeOrange's (1.11) has not.
    const bool has_sample_time = std::string(name) != "sample_log_small.ulg";
    test::TempDir dir;
    auto summary = import_log(path, dir.file("out.lcm"), [](const std::string& p) { ADD_FAILURE() << p; });
    ASSERT_TRUE(summary);
    std::map<std::string, foreign_schema_t> schemas;
    std::map<std::string, int64_t> seen;
    int64_t imus = 0;
    std::vector<std::pair<int64_t, bool>> armed_times;        // vehicle_status: (time, armed)
    std::vector<std::pair<int64_t, double>> vertical_speeds;  // vehicle_local_position: (time, vz) [m/s]
    for (const OwnedEvent& e : test::read_all(dir.file("out.lcm"))) {
      if (e.channel == "FOREIGN_SCHEMAS") {
        const auto s = test::decode<foreign_schema_t>(e);
        EXPECT_EQ(s.encoding, "ulog");
        EXPECT_TRUE(s.definition.starts_with(s.type + ":")) << s.definition;
        EXPECT_FALSE(schemas.count(s.channel)) << "one schema per channel: " << s.channel;
        schemas[s.channel] = s;
        continue;
      }
      if (e.channel == "sensor_combined") {
        const auto m = test::decode<imu_t>(e);
        EXPECT_EQ(m.header.seq, imus++);
        EXPECT_EQ(m.header.utime, e.utime);  // sensor_combined has no timestamp_sample
        // A vehicle at rest or flying: gravity's 9.8 m/s^2 is there within what a flight's manoeuvres add.
        const double g = std::hypot(m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z);
        EXPECT_GT(g, 2.0);
        EXPECT_LT(g, 40.0);
        continue;
      }
      if (e.channel == "vehicle_gps_position" || e.channel == "sensor_gps") {
        const auto m = test::decode<gnss_t>(e);
        EXPECT_EQ(m.header.utime, e.utime);  // no timestamp_sample in either version
        EXPECT_TRUE(m.fix_type == 0 || m.fix_type == 2 || m.fix_type == 3);
        if (m.fix_type == 3) {
          EXPECT_LE(std::abs(m.latitude_deg), 90.0);
          EXPECT_LE(std::abs(m.longitude_deg), 180.0);
          EXPECT_GT(m.satellites, 3);  // a 3D fix needs four
        }
        ++seen[e.channel];
        continue;
      }
      if (e.channel == "vehicle_local_position") {
        const auto m = test::decode<odometry_t>(e);
        if (has_sample_time) {
          EXPECT_LE(m.header.utime, e.utime);  // sampled, then published
        } else {
          EXPECT_EQ(m.header.utime, e.utime);
        }
        EXPECT_EQ(m.header.seq, seen[e.channel]);
        EXPECT_NEAR(std::hypot(m.orientation.w, m.orientation.z), 1.0, 1e-9);
        if (std::isfinite(m.linear_velocity.z)) vertical_speeds.emplace_back(e.utime, m.linear_velocity.z);
        ++seen[e.channel];
        continue;
      }
      if (e.channel == "vehicle_attitude") {
        const auto m = test::decode<pose_t>(e);
        if (has_sample_time) {
          EXPECT_LE(m.header.utime, e.utime);
        } else {
          EXPECT_EQ(m.header.utime, e.utime);
        }
        // PX4 publishes a unit quaternion (in float32: to about 1e-6); the position is not in the message.
        const auto& q = m.orientation;
        EXPECT_NEAR(std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z), 1.0, 1e-5);
        EXPECT_TRUE(std::isnan(m.position.x));
        ++seen[e.channel];
        continue;
      }
      if (e.channel == "vehicle_status") {
        const auto m = test::decode<vehicle_status_t>(e);
        EXPECT_EQ(m.header.utime, e.utime);  // no timestamp_sample
        EXPECT_NE(m.mode, "unknown") << "a nav_state PX4 defines";
        EXPECT_NE(m.landed, m.armed);
        armed_times.push_back({e.utime, m.armed});
        ++seen[e.channel];
        continue;
      }
      // vehicle_imu, sensor_baro, sensor_mag, vehicle_magnetometer: one channel per instance ("vehicle_imu/1").
      const std::string topic = e.channel.substr(0, e.channel.find('/'));
      if (topic == "vehicle_imu") {
        const auto m = test::decode<imu_t>(e);
        EXPECT_LE(m.header.utime, e.utime);  // sampled, then published
        // The changes over their intervals: gravity's 9.8 m/s^2 within what manoeuvres add, rates a vehicle turns at.
        const double g = std::hypot(m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z);
        EXPECT_GT(g, 2.0);
        EXPECT_LT(g, 40.0);
        EXPECT_LT(std::hypot(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z), 20.0);
        ++seen[topic];
        continue;
      }
      if (topic == "sensor_baro") {
        const auto m = test::decode<barometer_t>(e);
        EXPECT_LE(m.header.utime, e.utime);
        // Both flights are near the ground (the 1.11 log's millibar and the later log's Pascal alike): the air's
        // pressure below 5 km and above a deep depression's; the sensor's temperature a circuit board's.
        EXPECT_GT(m.pressure_pa, 50000.0);
        EXPECT_LT(m.pressure_pa, 110000.0);
        EXPECT_GT(m.temperature_c, -40.0);
        EXPECT_LT(m.temperature_c, 100.0);
        ++seen[topic];
        continue;
      }
      if (topic == "sensor_mag" || topic == "vehicle_magnetometer") {
        const auto m = test::decode<magnetometer_t>(e);
        EXPECT_LE(m.header.utime, e.utime);
        // The Earth's field is 25-65 uT; an uncalibrated sensor near motors reads within a few times that.
        const double b = std::hypot(m.magnetic_field.x, m.magnetic_field.y, m.magnetic_field.z);
        EXPECT_GT(b, 5e-6) << e.channel;
        EXPECT_LT(b, 300e-6) << e.channel;
        ++seen[topic];
        continue;
      }
      if (kRecordChannels.count(e.channel)) continue;
      const auto f = test::decode<foreign_message_t>(e);
      ASSERT_TRUE(schemas.count(e.channel)) << "its schema before its first message: " << e.channel;
      EXPECT_EQ(f.encoding, "ulog");
      // The event time is the message's timestamp: its first field in every PX4 topic.
      ASSERT_GE(f.data.size(), 8u);
      uint64_t t = 0;
      for (int i = 7; i >= 0; --i) t = (t << 8) | f.data[static_cast<size_t>(i)];
      EXPECT_EQ(static_cast<int64_t>(t), e.utime) << e.channel;
      ++seen[e.channel];
    }
    EXPECT_GT(imus, 0);
    // The definition carried holds every format the type nests (one a line, its own first): it resolves alone.
    for (const auto& [channel, schema] : schemas) {
      std::map<std::string, std::string, std::less<>> formats;
      const std::string& text = schema.definition;
      size_t at = 0;
      while (at < text.size()) {
        const size_t nl = text.find('\n', at);
        const std::string line = text.substr(at, nl == std::string::npos ? std::string::npos : nl - at);
        formats[line.substr(0, line.find(':'))] = line;
        at = nl == std::string::npos ? text.size() : nl + 1;
      }
      EXPECT_TRUE(resolve_ulog_format(formats, schema.type)) << channel << ": the definition carried resolves alone";
    }
    // position_setpoint_triplet nests position_setpoint (three of them): its definition has both.
    ASSERT_TRUE(schemas.count("position_setpoint_triplet"));
    EXPECT_NE(schemas["position_setpoint_triplet"].definition.find("\nposition_setpoint:"), std::string::npos)
        << schemas["position_setpoint_triplet"].definition;
    EXPECT_GT(seen["vehicle_gps_position"], 0);
    EXPECT_GT(seen["vehicle_local_position"], 0);
    EXPECT_GT(seen["vehicle_status"], 0);
    // Physics against the status: while vehicle_status says disarmed, the vehicle stands still (its motors are
    // stopped): the estimated vertical speed stays under 0.5 m/s, well above an estimator's noise at rest (the SITL
    // log's, disarmed throughout, stays within centimetres per second) and well below a landing's descent.
    int64_t disarmed_samples = 0;
    for (const auto& [t, vz] : vertical_speeds) {
      auto at = std::upper_bound(armed_times.begin(), armed_times.end(), std::make_pair(t, true));
      if (at == armed_times.begin() || std::prev(at)->second) continue;
      ++disarmed_samples;
      EXPECT_LT(std::abs(vz), 0.5) << "moving at " << t << " us while disarmed";
    }
    EXPECT_GT(disarmed_samples, 0);
    // The CubeOrange log is a landing: armed, then disarmed once on the ground; the SITL vehicle never arms.
    const bool lands = std::string(name) == "sample_log_small.ulg";
    ASSERT_FALSE(armed_times.empty());
    EXPECT_EQ(armed_times.front().second, lands);
    EXPECT_FALSE(armed_times.back().second);
    EXPECT_GT(seen["vehicle_attitude"], 0);
    for (const char* topic : {"vehicle_imu", "sensor_baro", "sensor_mag"}) EXPECT_GT(seen[topic], 0) << topic;
  }
}

/// The import of path as channel -> {count, smallest and largest event time}, and the logged strings (untagged,
/// tagged) and dropout durations [ms].
struct Imported {
  std::map<std::string, std::array<int64_t, 3>> topics;
  int64_t logs = 0, tagged_logs = 0;
  std::vector<int64_t> dropouts_ms;
  std::vector<std::array<int64_t, 2>> gnss_utc;  // ULOG_UTC: (boot, UTC) [us]
  analyzers::FlightUtc utc;                      // what info and diagnose say of them
};
Imported imported(const std::string& path) {
  Imported out;
  test::TempDir dir;
  auto s = import_log(path, dir.file("out.lcm"), [](const std::string& p) { ADD_FAILURE() << p; });
  EXPECT_TRUE(s);
  if (!s) return out;
  for (const OwnedEvent& e : test::read_all(dir.file("out.lcm"))) {
    if (e.channel == "ULOG_LOG") {
      ++(test::decode<log_text_t>(e).tag < 0 ? out.logs : out.tagged_logs);
    } else if (e.channel == "ULOG_DROPOUTS") {
      out.dropouts_ms.push_back(test::decode<dropout_t>(e).duration_us / 1000);
    } else if (e.channel == "ULOG_UTC") {
      const auto m = test::decode<timesync_status_t>(e);
      out.gnss_utc.push_back({m.header.utime, m.remote_utime});
    } else if (!kRecordChannels.count(e.channel)) {
      auto [it, fresh] = out.topics.try_emplace(e.channel, std::array<int64_t, 3>{0, e.utime, e.utime});
      auto& t = it->second;
      ++t[0];
      t[1] = std::min(t[1], e.utime);
      t[2] = std::max(t[2], e.utime);
    }
  }
  out.utc = analyzers::flight_utc(dir.file("out.lcm"), 0);
  return out;
}

// Foxglove's own ULog reader (@foxglove/ulog, pinned in tests/oracle; tests/oracle/dump_ulog.mjs) finds in each
// shared log the same topic instances, each with the same count and the same smallest and largest timestamp, the
// same logged strings (tagged and not) and the same dropouts as driftlab's import. Skipped without node and the
// oracle's modules, a failure under CI.
TEST(Ulog, ImportAgreesWithFoxglovesReader) {
  const std::string oracle = std::string(DRIFTLAB_SOURCE_DIR) + "/tests/oracle";
  if (test::run("node --version >/dev/null 2>&1") != 0 ||
      !std::filesystem::exists(oracle + "/node_modules/@foxglove/ulog/package.json")) {
    const char* ci = std::getenv("CI");
    if (ci && std::string(ci) == "true") {
      ADD_FAILURE() << "node or @foxglove/ulog missing under CI (scripts/bootstrap installs them)";
    } else {
      GTEST_SKIP() << "node or tests/oracle/node_modules/@foxglove/ulog missing (scripts/bootstrap installs them)";
    }
    return;
  }
  for (const char* name :
       {"sample_log_small.ulg", "sample_appended_multiple.ulg", "sample_logging_tagged_and_default_params.ulg"}) {
    SCOPED_TRACE(name);
    const std::string path = test::shared_data(std::string("ulog/") + name);
    if (path.empty()) return;
    std::string text;
    ASSERT_EQ(test::run("node '" + oracle + "/dump_ulog.mjs' '" + path + "'", &text), 0);
    const auto fox = nlohmann::json::parse(text);
    const Imported got = imported(path);
    std::map<std::string, std::array<int64_t, 3>> want;
    for (const auto& [channel, t] : fox["topics"].items()) {
      want[channel] = {t["count"].get<int64_t>(), t["first_us"].get<int64_t>(), t["last_us"].get<int64_t>()};
    }
    EXPECT_EQ(got.topics, want);
    EXPECT_EQ(got.logs, fox["logs"].get<int64_t>());
    EXPECT_EQ(got.tagged_logs, fox["tagged_logs"].get<int64_t>());
    EXPECT_EQ(got.dropouts_ms, fox["dropouts_ms"].get<std::vector<int64_t>>());
    // The GNSS receiver's UTC against the boot clock: each fix's pair as Foxglove reads it, and the log's start in
    // UTC from their median offset (numpy's: the middle two's mean for an even count) and the header's start.
    const auto want_utc = fox["gnss_utc"].get<std::vector<std::array<int64_t, 2>>>();
    EXPECT_EQ(got.gnss_utc, want_utc);
    EXPECT_EQ(got.utc.known, !want_utc.empty());
    if (want_utc.empty()) continue;
    std::vector<int64_t> offsets;
    for (const auto& [boot, utc] : want_utc) offsets.push_back(utc - boot);
    std::sort(offsets.begin(), offsets.end());
    const size_t n = offsets.size();
    const int64_t median =
        n % 2 ? offsets[n / 2]
              : std::llround((static_cast<double>(offsets[n / 2 - 1]) + static_cast<double>(offsets[n / 2])) / 2);
    EXPECT_EQ(got.utc.boot_to_utc_us, median);
    EXPECT_EQ(got.utc.start_utime, fox["start_us"].get<int64_t>());
    EXPECT_EQ(got.utc.start_utc_us, fox["start_us"].get<int64_t>() + median);
    EXPECT_EQ(got.utc.fixes, static_cast<int64_t>(n));
    EXPECT_NEAR(got.utc.spread_s, static_cast<double>(offsets.back() - offsets.front()) * 1e-6, 1e-9);
    // A GNSS time is UTC of this century: after 2015 (the oldest of these PX4 versions) and before 2030.
    EXPECT_GT(got.utc.start_utc_us, int64_t{1420070400} * 1000000);
    EXPECT_LT(got.utc.start_utc_us, int64_t{1893456000} * 1000000);
  }
}

// ---- hostile files ----

// A file cut anywhere keeps every message that ends before the cut and reports the cut once, with its offset.
TEST(Ulog, TruncatedFileKeepsEveryMessageBeforeTheCut) {
  const std::string path = test::shared_data("ulog/sample_log_small.ulg");
  if (path.empty()) return;
  const std::vector<uint8_t> whole = file_bytes(path);
  const Read all = read(whole);
  ASSERT_TRUE(all.status);
  ASSERT_TRUE(all.problems.empty());
  // Cuts inside the definitions, inside a record's header, inside a record's data, and on a record's boundary.
  for (const size_t cut : {size_t{2000}, whole.size() / 3, whole.size() / 2 + 1, whole.size() - 5,
                           static_cast<size_t>(all.data[all.data.size() / 2].first)}) {
    SCOPED_TRACE(cut);
    std::vector<uint8_t> part(whole.begin(), whole.begin() + static_cast<ptrdiff_t>(cut));
    const Read r = read(part);
    ASSERT_TRUE(r.status);
    size_t kept = 0;
    for (const auto& [offset, payload] : all.data) {
      if (offset + 3 + 2 + payload.size() <= cut) ++kept;
    }
    ASSERT_EQ(r.data.size(), kept);
    for (size_t i = 0; i < kept; ++i) ASSERT_EQ(r.data[i], all.data[i]);
    const bool on_boundary = cut == all.data[all.data.size() / 2].first;
    if (on_boundary) {
      EXPECT_TRUE(r.problems.empty());
    } else {
      ASSERT_EQ(r.problems.size(), 1u);
      EXPECT_NE(r.problems[0].second.find("cut short"), std::string::npos) << r.problems[0].second;
      EXPECT_LT(r.problems[0].first, cut);
    }
  }
}

// Through the importer, the problem line names the file and the byte offset.
TEST(Ulog, TruncatedFileProblemNamesFileAndOffset) {
  Ulog u = small_flight();
  const size_t full = u.b.size();
  u.b.resize(full - 4);  // into the dropout record (3 + 2 bytes)
  test::TempDir dir;
  test::write_file(dir.file("cut.ulg"), u.b);
  std::vector<std::string> problems;
  auto s = import_log(dir.file("cut.ulg"), dir.file("out.lcm"), [&](const std::string& p) { problems.push_back(p); });
  ASSERT_TRUE(s) << s.error().message;
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_EQ(problems[0].rfind(dir.file("cut.ulg") + ": at byte " + std::to_string(full - 5) + ": ", 0), 0u)
      << problems[0];
  EXPECT_EQ(s->problems, 1);
  std::map<std::string, int64_t> counts;
  for (const auto& e : test::read_all(dir.file("out.lcm"))) ++counts[e.channel];
  EXPECT_EQ(counts["t/0"], 10);
  EXPECT_EQ(counts["t/1"], 10);
  EXPECT_EQ(counts["ULOG_LOG"], 1);
  EXPECT_EQ(counts["ULOG_DROPOUTS"], 0);
}

// A damaged record header in the middle of a real log: reported once at its offset; reading goes on at the next
// record, and every other message is kept as it was.
TEST(Ulog, CorruptedByteInTheMiddleResyncsAndKeepsTheRest) {
  const std::string path = test::shared_data("ulog/sample_log_small.ulg");
  if (path.empty()) return;
  const std::vector<uint8_t> whole = file_bytes(path);
  const Read all = read(whole);
  ASSERT_TRUE(all.status);
  const size_t victim = all.data.size() / 2;
  const uint64_t at = all.data[victim].first;
  for (const uint8_t type : {uint8_t{0}, uint8_t{0xff}}) {
    SCOPED_TRACE(type);
    std::vector<uint8_t> bad = whole;
    bad[at + 2] = type;  // the record's type byte
    const Read r = read(bad);
    ASSERT_TRUE(r.status);
    ASSERT_EQ(r.problems.size(), 1u);
    EXPECT_EQ(r.problems[0].first, at);
    EXPECT_NE(r.problems[0].second.find("reading again at byte"), std::string::npos) << r.problems[0].second;
    ASSERT_EQ(r.data.size(), all.data.size() - 1);
    for (size_t i = 0, j = 0; i < all.data.size(); ++i) {
      if (i == victim) continue;
      ASSERT_EQ(r.data[j++], all.data[i]) << i;
    }
  }
  // Its type byte made a letter no record uses: what a newer writer's record looks like, which the specification
  // has readers skip whole; its framing holds (a known record follows), so it is skipped and counted, not reported.
  {
    std::vector<uint8_t> bad = whole;
    bad[at + 2] = 'x';
    const Read r = read(bad);
    EXPECT_TRUE(r.problems.empty());
    EXPECT_EQ(r.data.size(), all.data.size() - 1);
    EXPECT_EQ(r.unknown, (std::map<char, int64_t>{{'x', 1}}));
  }
  // Its size made huge: the record claims bytes far past its own; reading goes on at the next one all the same.
  std::vector<uint8_t> bad = whole;
  bad[at] = 0xff;
  bad[at + 1] = 0xff;
  const Read r = read(bad);
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_EQ(r.problems[0].first, at);
  EXPECT_EQ(r.data.size(), all.data.size() - 1);
}

// A file is read forward through a window of it (formats/ulog.cc, Bytes): read from its file, a log damaged in many
// places (records' types and sizes broken, garbage, around the window's edges too), cut short, or with appended
// data reads as the same bytes in memory do, message for message and problem for problem.
TEST(Ulog, AFileReadsAsTheSameBytesInMemory) {
  const std::string path = test::shared_data("ulog/sample_logging_tagged_and_default_params.ulg");
  const std::string appended = test::shared_data("ulog/sample_appended_multiple.ulg");
  if (path.empty() || appended.empty()) return;
  const std::vector<uint8_t> whole = file_bytes(path);
  const Read all = read(whole);
  ASSERT_TRUE(all.status);
  ASSERT_GT(all.data.size(), 1000u);
  std::vector<uint8_t> bad = whole;
  for (size_t i = 7; i < all.data.size(); i += all.data.size() / 23) {
    const uint64_t at = all.data[i].first;
    if (i % 3 == 0) {
      bad[at + 2] = 0xff;
    } else if (i % 3 == 1) {
      bad[at] = bad[at + 1] = 0xff;
    } else {
      bad[at + 2] = 'x';
    }
  }
  for (const uint64_t edge : {uint64_t{1} << 20, (uint64_t{1} << 20) + (uint64_t{1} << 19)}) {
    for (uint64_t k = edge - 40; k < edge + 40; ++k) bad[k] = static_cast<uint8_t>(0x90 + k % 50);
  }
  std::vector<uint8_t> cut(bad.begin(), bad.begin() + static_cast<ptrdiff_t>(bad.size() - 1000));
  test::TempDir dir;
  for (const auto& [name, bytes] : std::vector<std::pair<std::string, std::vector<uint8_t>>>{
           {"whole.ulg", whole}, {"bad.ulg", bad}, {"cut.ulg", cut}, {"appended.ulg", file_bytes(appended)}}) {
    SCOPED_TRACE(name);
    test::write_file(dir.file(name), bytes);
    const Read memory = read(bytes), file = read(UlogReader::open(dir.file(name)));
    ASSERT_TRUE(memory.status);
    ASSERT_TRUE(file.status) << file.status.message();
    if (name == "bad.ulg") {
      EXPECT_GT(memory.problems.size(), 10u);
    }
    EXPECT_EQ(file.problems, memory.problems);
    EXPECT_EQ(file.data, memory.data);
    EXPECT_EQ(file.unknown, memory.unknown);
    EXPECT_EQ(file.logged, memory.logged);
    EXPECT_EQ(file.dropouts, memory.dropouts);
  }
}

// Garbage between two records of a written log: the messages on both sides are kept.
TEST(Ulog, GarbageBetweenRecordsIsSkippedOnce) {
  Ulog u;
  u.flags(0);
  u.format("t:uint64_t timestamp;float x;");
  u.subscribe(0, 1, "t");
  u.data(1, 2000, 1);
  const size_t garbage_at = u.b.size();
  for (int i = 0; i < 50; ++i) u.b.push_back(static_cast<uint8_t>(0x90 + i));
  u.data(1, 2100, 2);
  const Read r = read(u.b);
  ASSERT_TRUE(r.status);
  EXPECT_EQ(r.data.size(), 2u);
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_EQ(r.problems[0].first, garbage_at);
}

// A record of a type no writer uses that is not followed by a record is damage: reported, not skipped silently.
TEST(Ulog, UnknownTypeBeforeGarbageIsReported) {
  Ulog u;
  u.flags(0);
  u.format("t:uint64_t timestamp;float x;");
  u.subscribe(0, 1, "t");
  u.data(1, 2000, 1);
  const size_t unknown_at = u.b.size();
  u.record('x', {1, 2, 3});
  for (int i = 0; i < 20; ++i) u.b.push_back(static_cast<uint8_t>(0x90 + i));
  u.data(1, 2100, 2);
  const Read r = read(u.b);
  ASSERT_TRUE(r.status);
  EXPECT_EQ(r.data.size(), 2u);
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_EQ(r.problems[0].first, unknown_at);
  EXPECT_TRUE(r.unknown.empty());
}

// An incompatible flag this reader does not know: the log cannot be read, and nothing is written.
TEST(Ulog, UnknownIncompatFlagIsAnError) {
  for (const auto& [incompat0, other] : {std::pair<uint8_t, uint8_t>{0x02, 0}, {0x01, 0x10}}) {
    Ulog u;
    u.flags(incompat0, 0, other);
    u.format("t:uint64_t timestamp;float x;");
    u.subscribe(0, 1, "t");
    u.data(1, 2000, 1);
    const Read r = read(u.b);
    ASSERT_FALSE(r.status);
    EXPECT_NE(r.status.message().find("incompatible flag bit " + std::to_string(incompat0 == 2 ? 1 : 12)),
              std::string::npos)
        << r.status.message();
    EXPECT_TRUE(r.data.empty());
    test::TempDir dir;
    test::write_file(dir.file("f.ulg"), u.b);
    auto s = import_log(dir.file("f.ulg"), dir.file("out.lcm"), [](const std::string&) {});
    ASSERT_FALSE(s);
    EXPECT_EQ(s.error().message.rfind(dir.file("f.ulg") + ": at byte ", 0), 0u) << s.error().message;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.lcm")));
  }
}

// Appended data (incompatible flag bit 0): the section after the offset is read too.
TEST(Ulog, AppendedDataIsRead) {
  Ulog u;
  const size_t flags_at = u.b.size();
  u.flags(0x01, 0);
  u.format("t:uint64_t timestamp;float x;");
  u.subscribe(0, 1, "t");
  u.data(1, 2000, 1);
  const size_t appended = u.b.size();
  u.data(1, 2100, 2);
  u.data(1, 2200, 3);
  for (int i = 0; i < 8; ++i) u.b[flags_at + 3 + 16 + i] = static_cast<uint8_t>(appended >> (8 * i));
  const Read r = read(u.b);
  ASSERT_TRUE(r.status);
  EXPECT_TRUE(r.problems.empty());
  EXPECT_EQ(r.data.size(), 3u);
}

// Nested types, arrays of them and padding: the layout is flattened with the offsets C would give, and the
// trailing padding PX4 does not write may be missing from a message.
TEST(Ulog, NestedTypesArraysAndPadding) {
  const std::map<std::string, std::string, std::less<>> formats = {
      {"inner", "inner:float a;uint8_t[3] _padding0;"},
      {"outer", "outer:uint64_t timestamp;inner[2] v;char[4] name;uint8_t[4] _padding0;"}};
  auto l = resolve_ulog_format(formats, "outer");
  ASSERT_TRUE(l) << l.error().message;
  EXPECT_EQ(l->size, 8u + 2 * 7 + 4 + 4);
  EXPECT_EQ(l->size_written, 8u + 2 * 7 + 4);
  EXPECT_EQ(l->timestamp_offset, 0);
  ASSERT_EQ(l->fields.size(), 4u);
  EXPECT_EQ(l->fields[1].name, "v[0].a");
  EXPECT_EQ(l->fields[1].offset, 8u);
  EXPECT_EQ(l->fields[2].name, "v[1].a");
  EXPECT_EQ(l->fields[2].offset, 15u);
  EXPECT_EQ(l->fields[3].name, "name");
  EXPECT_EQ(l->fields[3].count, 4u);
  EXPECT_EQ(l->definition,
            "outer:uint64_t timestamp;inner[2] v;char[4] name;uint8_t[4] _padding0;\n"
            "inner:float a;uint8_t[3] _padding0;");
  std::vector<uint8_t> msg(l->size_written, 0);
  const auto v = f32(2.5f);
  std::copy(v.begin(), v.end(), msg.begin() + 15);
  EXPECT_EQ(l->number(msg, "v[1].a"), 2.5);
  EXPECT_TRUE(std::isnan(l->number(msg, "missing")));
  EXPECT_TRUE(std::isnan(l->number(msg, "name")));
}

// A definition naming a nested type the file never defines: the subscription is reported once with its offset,
// its messages are left out (counted), and the other topics are read.
TEST(Ulog, UnknownNestedTypeLeavesOnlyItsTopicOut) {
  Ulog u;
  u.flags(0);
  u.format("t:uint64_t timestamp;float x;");
  u.format("broken:uint64_t timestamp;missing_t[2] m;");
  u.subscribe(0, 1, "t");
  const size_t sub_at = u.b.size();
  u.subscribe(0, 2, "broken");
  for (int i = 0; i < 3; ++i) {
    u.data(1, 2000 + i, 1);
    std::vector<uint8_t> r;
    put(r, 2, 2);
    put(r, 2000 + i, 8);
    put(r, 0, 4);
    u.record('D', r);
  }
  const Read r = read(u.b);
  ASSERT_TRUE(r.status);
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_EQ(r.problems[0].first, sub_at);
  EXPECT_NE(r.problems[0].second.find("type missing_t is not defined"), std::string::npos) << r.problems[0].second;
  EXPECT_EQ(r.per_topic["t/0"], 3);

  test::TempDir dir;
  test::write_file(dir.file("f.ulg"), u.b);
  std::vector<std::string> problems;
  auto s = import_log(dir.file("f.ulg"), dir.file("out.lcm"), [&](const std::string& p) { problems.push_back(p); });
  ASSERT_TRUE(s);
  ASSERT_EQ(problems.size(), 1u);
  for (const auto& t : s->topics) {
    if (t.channel == "broken") {
      EXPECT_EQ(t.malformed, 3);
    }
    if (t.channel == "t") {
      EXPECT_EQ(t.messages, 3);
    }
  }
  std::map<std::string, int64_t> counts;
  for (const auto& e : test::read_all(dir.file("out.lcm"))) ++counts[e.channel];
  EXPECT_EQ(counts["t"], 3);
  EXPECT_EQ(counts.count("broken"), 0u);
}

// A type that contains itself, directly or through another: refused, never walked forever.
TEST(Ulog, RecursiveDefinitionIsRefused) {
  const std::map<std::string, std::string, std::less<>> direct = {{"a", "a:uint64_t timestamp;a inner;"}};
  auto l = resolve_ulog_format(direct, "a");
  ASSERT_FALSE(l);
  EXPECT_NE(l.error().message.find("contains itself"), std::string::npos) << l.error().message;
  const std::map<std::string, std::string, std::less<>> mutual = {{"a", "a:uint64_t timestamp;b[3] x;"},
                                                                  {"b", "b:float y;a z;"}};
  l = resolve_ulog_format(mutual, "a");
  ASSERT_FALSE(l);
  EXPECT_NE(l.error().message.find("contains itself"), std::string::npos) << l.error().message;

  // In a file: reported with the subscription, and the file's other messages read.
  Ulog u;
  u.flags(0);
  u.format("t:uint64_t timestamp;float x;");
  u.format("a:uint64_t timestamp;a inner;");
  u.subscribe(0, 1, "t");
  u.subscribe(0, 2, "a");
  u.data(1, 2000, 1);
  const Read r = read(u.b);
  ASSERT_TRUE(r.status);
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_EQ(r.data.size(), 1u);
}

// Array sizes no ULog message can hold (its size is a uint16_t): refused from the definition, without allocating
// or walking them; a nesting of empty types in large arrays is bounded too.
TEST(Ulog, HugeArraySizesAreRefused) {
  for (const char* text :
       {"a:uint64_t timestamp;float[4294967295] x;", "a:uint64_t timestamp;float[99999999999999999999] x;",
        "a:uint64_t timestamp;float[16000] x;float[16000] y;", "a:uint64_t timestamp;b[65535] x;"}) {
    SCOPED_TRACE(text);
    const std::map<std::string, std::string, std::less<>> formats = {{"a", text}, {"b", "b:double[4] v;"}};
    auto l = resolve_ulog_format(formats, "a");
    ASSERT_FALSE(l);
    EXPECT_NE(l.error().message.find("larger than a ULog message can hold"), std::string::npos) << l.error().message;
  }
  // A field with a 60,000-byte name, in an array of 65535: 65535 bytes, a size a message can have, but 3.9 GB of
  // flattened names; refused before they are made.
  const std::map<std::string, std::string, std::less<>> long_names = {
      {"a", "a:b[65535] x;"}, {"b", "b:uint8_t " + std::string(60000, 'n') + ";"}};
  auto named = resolve_ulog_format(long_names, "a");
  ASSERT_FALSE(named);
  EXPECT_NE(named.error().message.find("longer names"), std::string::npos) << named.error().message;
  // Empty types nested in the largest arrays: sizes 0, resolved in bounded time (each type is laid out once).
  const std::map<std::string, std::string, std::less<>> empty = {
      {"a", "a:uint64_t timestamp;b[65535] x;"}, {"b", "b:c[65535] y;"}, {"c", "c:"}};
  auto l = resolve_ulog_format(empty, "a");
  ASSERT_TRUE(l) << l.error().message;
  EXPECT_EQ(l->size, 8u);
}

// Logged strings, information fields and dropouts as records on their own channels.
TEST(Ulog, RecordsOnTheirOwnChannels) {
  Ulog u = small_flight();
  test::TempDir dir;
  test::write_file(dir.file("f.ulg"), u.b);
  auto s = import_log(dir.file("f.ulg"), dir.file("out.lcm"), [](const std::string& p) { ADD_FAILURE() << p; });
  ASSERT_TRUE(s);
  int logs = 0, drops = 0, infos = 0;
  for (const auto& e : test::read_all(dir.file("out.lcm"))) {
    if (e.channel == "ULOG_LOG") {
      const auto m = test::decode<log_text_t>(e);
      EXPECT_EQ(m.level, 6);
      EXPECT_EQ(m.tag, -1);
      EXPECT_EQ(m.text, "takeoff");
      EXPECT_EQ(m.header.utime, 2500);
      EXPECT_EQ(e.utime, 2500);
      ++logs;
    } else if (e.channel == "ULOG_DROPOUTS") {
      const auto m = test::decode<dropout_t>(e);
      EXPECT_EQ(m.duration_us, 20000);
      EXPECT_EQ(m.header.utime, 2950);  // the latest timestamp read before it
      ++drops;
    } else if (e.channel == "ULOG_INFO") {
      const auto m = test::decode<parameter_t>(e);
      EXPECT_EQ(m.name, "sys_name");
      EXPECT_EQ(m.type, "char[3]");
      EXPECT_EQ(m.text, "PX4");
      EXPECT_TRUE(std::isnan(m.value));
      EXPECT_EQ(m.header.utime, 1000);  // the header's start: it was in the definitions
      ++infos;
    }
  }
  EXPECT_EQ(logs, 1);
  EXPECT_EQ(drops, 1);
  EXPECT_EQ(infos, 1);
}

/// A data message's bytes as its format lays them out, field by field.
struct Fields {
  std::vector<uint8_t> b;
  Fields& u64(uint64_t v) {
    put(b, v, 8);
    return *this;
  }
  Fields& u8(uint8_t v) {
    b.push_back(v);
    return *this;
  }
  Fields& u16(uint16_t v) {
    put(b, v, 2);
    return *this;
  }
  Fields& f(std::initializer_list<float> values) {
    for (const float v : values) {
      const auto x = f32(v);
      b.insert(b.end(), x.begin(), x.end());
    }
    return *this;
  }
};

/// The import of u: every channel's events, in order.
std::map<std::string, std::vector<OwnedEvent>> import_written(const Ulog& u) {
  test::TempDir dir;
  test::write_file(dir.file("f.ulg"), u.b);
  auto s = import_log(dir.file("f.ulg"), dir.file("out.lcm"), [](const std::string& p) { ADD_FAILURE() << p; });
  EXPECT_TRUE(s);
  std::map<std::string, std::vector<OwnedEvent>> out;
  for (auto& e : test::read_all(dir.file("out.lcm"))) out[e.channel].push_back(std::move(e));
  return out;
}

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
const float kHalfSqrt2 = static_cast<float>(std::sqrt(0.5));

// vehicle_odometry, the setpoints and actuator_motors as PX4 1.14 lays them out (arrays: position[3], velocity[3];
// pose_frame and velocity_frame 1 NED, 2 FRD, 3 body; variances), each value read by its name.
TEST(Ulog, OdometrySetpointsAndMotorsOfPx4_1_14) {
  Ulog u;
  u.flags(0);
  u.format(
      "vehicle_odometry:uint64_t timestamp;uint64_t timestamp_sample;float[3] position;float[4] q;float[3] velocity;"
      "float[3] angular_velocity;float[3] position_variance;float[3] orientation_variance;float[3] "
      "velocity_variance;uint8_t pose_frame;uint8_t velocity_frame;uint8_t reset_counter;int8_t quality;uint8_t[4] "
      "_padding0;");
  u.format(
      "trajectory_setpoint:uint64_t timestamp;float[3] position;float[3] velocity;float[3] acceleration;float[3] "
      "jerk;float yaw;float yawspeed;");
  u.format("actuator_motors:uint64_t timestamp;uint64_t timestamp_sample;uint16_t reversible_flags;float[12] control;");
  u.subscribe(0, 1, "vehicle_odometry");
  u.subscribe(0, 2, "trajectory_setpoint");
  u.subscribe(0, 3, "actuator_motors");
  // Heading east (90 degrees about down), flying north at 1 m/s: in the body that is 1 m/s to its left (-y).
  u.data_bytes(1, Fields{}
                      .u64(2000)
                      .u64(1900)
                      .f({1, 2, -3, kHalfSqrt2, 0, 0, kHalfSqrt2, 1, 0, 0, 0.1f, 0.2f, 0.3f})
                      .f({0.01f, 0.02f, 0.03f, 0.001f, 0.002f, 0.003f, 0.04f, 0.05f, 0.06f})
                      .u8(1)
                      .u8(1)
                      .u8(0)
                      .u8(100)
                      .b);
  // In an FRD local frame, its velocity already in the body's: kept as it is.
  u.data_bytes(1, Fields{}
                      .u64(3000)
                      .u64(2950)
                      .f({0, 0, 0, 1, 0, 0, 0, 0.5f, 0, 0, 0, 0, 0})
                      .f({0, 0, 0, 0, 0, 0, 0, 0, 0})
                      .u8(2)
                      .u8(3)
                      .u8(0)
                      .u8(100)
                      .b);
  u.data_bytes(2, Fields{}.u64(2100).f({1, 2, -5, kNaNf, kNaNf, kNaNf, 0, 0, 0.5f, 0, 0, 0, 1.5f, 0}).b);
  u.data_bytes(3, Fields{}
                      .u64(2200)
                      .u64(2190)
                      .u16(0)
                      .f({0.1f, 0.2f, 0.3f, 0.4f})
                      .f(std::initializer_list<float>({kNaNf, kNaNf, kNaNf, kNaNf, kNaNf, kNaNf, kNaNf, kNaNf}))
                      .b);
  Fields disarmed;
  disarmed.u64(2300).u64(2290).u16(0);
  for (int i = 0; i < 12; ++i) disarmed.f({kNaNf});
  u.data_bytes(3, disarmed.b);
  auto ch = import_written(u);

  ASSERT_EQ(ch["vehicle_odometry"].size(), 2u);
  const auto o = test::decode<odometry_t>(ch["vehicle_odometry"][0]);
  EXPECT_EQ(ch["vehicle_odometry"][0].utime, 2000);
  EXPECT_EQ(o.header.utime, 1900);  // timestamp_sample
  EXPECT_EQ(o.header.frame_id, "local_ned");
  EXPECT_EQ(o.child_frame_id, "body_frd");
  EXPECT_NEAR(o.position.x, 1, 1e-6);
  EXPECT_NEAR(o.position.z, -3, 1e-6);
  EXPECT_NEAR(o.orientation.w, std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(o.orientation.z, std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(o.linear_velocity.x, 0, 1e-6);
  EXPECT_NEAR(o.linear_velocity.y, -1, 1e-6);
  EXPECT_NEAR(o.linear_velocity.z, 0, 1e-6);
  EXPECT_NEAR(o.angular_velocity.z, 0.3, 1e-6);
  EXPECT_NEAR(o.pose_covariance[0], 0.01, 1e-8);
  EXPECT_NEAR(o.pose_covariance[14], 0.03, 1e-8);
  EXPECT_NEAR(o.pose_covariance[35], 0.003, 1e-9);
  EXPECT_NEAR(o.twist_covariance[7], 0.05, 1e-8);
  EXPECT_EQ(o.pose_covariance[1], 0);
  const auto frd = test::decode<odometry_t>(ch["vehicle_odometry"][1]);
  EXPECT_EQ(frd.header.frame_id, "local_frd");
  EXPECT_NEAR(frd.linear_velocity.x, 0.5, 1e-6);

  ASSERT_EQ(ch["trajectory_setpoint"].size(), 1u);
  const auto sp = test::decode<trajectory_setpoint_t>(ch["trajectory_setpoint"][0]);
  EXPECT_EQ(sp.header.utime, 2100);
  EXPECT_EQ(sp.header.frame_id, "local_ned");
  EXPECT_NEAR(sp.position.z, -5, 1e-6);
  EXPECT_TRUE(std::isnan(sp.velocity.x));  // unset by PX4: kept unset
  EXPECT_NEAR(sp.acceleration.z, 0.5, 1e-6);
  EXPECT_NEAR(sp.yaw, 1.5, 1e-6);

  ASSERT_EQ(ch["actuator_motors"].size(), 2u);
  const auto armed = test::decode<motor_command_t>(ch["actuator_motors"][0]);
  EXPECT_EQ(armed.header.utime, 2190);
  EXPECT_TRUE(armed.armed);
  ASSERT_EQ(armed.nmotors, 4);  // the motors after the fourth are not configured (NaN)
  EXPECT_NEAR(armed.control[3], 0.4, 1e-6);
  const auto stopped = test::decode<motor_command_t>(ch["actuator_motors"][1]);
  EXPECT_FALSE(stopped.armed);
  EXPECT_EQ(stopped.nmotors, 0);
}

// The same topics as earlier PX4 versions lay them out: x, y, z and vx, vy, vz (1.12: local_frame 0 NED,
// velocity_frame 0 NED, the covariances' upper triangles; 1.10: no velocity_frame, so the velocity's frame is not
// known), PX4 1.9's acc_x, acc_y, acc_z; and formats lacking a field a mapping needs, which stay carried as they are.
TEST(Ulog, OdometryAndSetpointsOfEarlierPx4AndIncompleteFormats) {
  Ulog u;
  u.flags(0);
  u.format(
      "vehicle_odometry:uint64_t timestamp;uint64_t timestamp_sample;float x;float y;float z;float[4] q;float[4] "
      "q_offset;float[21] pose_covariance;float vx;float vy;float vz;float rollspeed;float pitchspeed;float "
      "yawspeed;float[21] velocity_covariance;uint8_t local_frame;uint8_t velocity_frame;");
  u.format(
      "vehicle_local_position_setpoint:uint64_t timestamp;float x;float y;float z;float yaw;float vx;float vy;float "
      "vz;float acc_x;float acc_y;float acc_z;");
  u.format("trajectory_setpoint:uint64_t timestamp;float x;float y;float z;float vx;float vy;float vz;");  // no yaw
  u.format("actuator_motors:uint64_t timestamp;uint16_t[12] control;");                                    // not floats
  u.subscribe(0, 1, "vehicle_odometry");
  u.subscribe(0, 2, "vehicle_local_position_setpoint");
  u.subscribe(0, 3, "trajectory_setpoint");
  u.subscribe(0, 4, "actuator_motors");
  // Heading south (180 degrees about down), flying east at 2 m/s: 2 m/s to its left in the body.
  Fields odom;
  odom.u64(5000).u64(4900).f({4, 5, 6, 0, 0, 0, 1, 1, 0, 0, 0});
  for (int k = 0; k < 21; ++k) odom.f({0.01f * static_cast<float>(k + 1)});
  odom.f({0, 2, 0, 0, 0, -0.5f});
  for (int k = 0; k < 21; ++k) odom.f({0});
  odom.u8(0).u8(0);
  u.data_bytes(1, odom.b);
  u.data_bytes(2, Fields{}.u64(5100).f({1, 1, -2, 0.5f, 0, 0, -1, 0, 0, 0.2f}).b);
  u.data_bytes(3, Fields{}.u64(5200).f({1, 1, -2, 0, 0, 0}).b);
  Fields motors;
  motors.u64(5300);
  for (int i = 0; i < 12; ++i) motors.u16(1500);
  u.data_bytes(4, motors.b);
  auto ch = import_written(u);

  ASSERT_EQ(ch["vehicle_odometry"].size(), 1u);
  const auto o = test::decode<odometry_t>(ch["vehicle_odometry"][0]);
  EXPECT_EQ(o.header.utime, 4900);
  EXPECT_EQ(o.header.frame_id, "local_ned");
  EXPECT_NEAR(o.position.y, 5, 1e-6);
  EXPECT_NEAR(o.linear_velocity.x, 0, 1e-6);
  EXPECT_NEAR(o.linear_velocity.y, -2, 1e-6);
  EXPECT_NEAR(o.angular_velocity.z, -0.5, 1e-6);
  // The upper triangle, row by row, mirrored: (0,0) is its first value, (0,1) and (1,0) its second, (1,1) its
  // seventh (after row 0's six), (5,5) its last.
  EXPECT_NEAR(o.pose_covariance[0], 0.01, 1e-8);
  EXPECT_NEAR(o.pose_covariance[1], 0.02, 1e-8);
  EXPECT_NEAR(o.pose_covariance[6], 0.02, 1e-8);
  EXPECT_NEAR(o.pose_covariance[7], 0.07, 1e-8);
  EXPECT_NEAR(o.pose_covariance[35], 0.21, 1e-8);

  ASSERT_EQ(ch["vehicle_local_position_setpoint"].size(), 1u);
  const auto sp = test::decode<trajectory_setpoint_t>(ch["vehicle_local_position_setpoint"][0]);
  EXPECT_NEAR(sp.position.z, -2, 1e-6);
  EXPECT_NEAR(sp.velocity.z, -1, 1e-6);
  EXPECT_NEAR(sp.acceleration.z, 0.2, 1e-6);
  EXPECT_NEAR(sp.yaw, 0.5, 1e-6);

  // Without yaw, or with control in integers, the topics are carried as the file has them.
  for (const char* topic : {"trajectory_setpoint", "actuator_motors"}) {
    ASSERT_EQ(ch[topic].size(), 1u) << topic;
    const auto f = test::decode<foreign_message_t>(ch[topic][0]);
    EXPECT_EQ(f.type, topic);
  }

  // PX4 1.10's vehicle_odometry, without velocity_frame: the pose as given, the velocity not known.
  Ulog v10;
  v10.flags(0);
  v10.format(
      "vehicle_odometry:uint64_t timestamp;float x;float y;float z;float[4] q;float vx;float vy;float vz;float "
      "rollspeed;float pitchspeed;float yawspeed;uint8_t local_frame;");
  v10.subscribe(0, 1, "vehicle_odometry");
  v10.data_bytes(1, Fields{}.u64(7000).f({1, 2, 3, 1, 0, 0, 0, 1, 1, 1, 0, 0, 0}).u8(1).b);
  auto ch10 = import_written(v10);
  ASSERT_EQ(ch10["vehicle_odometry"].size(), 1u);
  const auto o10 = test::decode<odometry_t>(ch10["vehicle_odometry"][0]);
  EXPECT_EQ(o10.header.utime, 7000);
  EXPECT_EQ(o10.header.frame_id, "local_frd");  // local_frame 1 before PX4 1.14
  EXPECT_NEAR(o10.position.z, 3, 1e-6);
  EXPECT_TRUE(std::isnan(o10.linear_velocity.x));
}

// A GNSS time counts only with a 3D fix (before it, a receiver's clock is not solved) and when set (0: not known);
// it is the UTC of timestamp + timestamp_time_relative, as vehicle_gps_position.msg defines it.
TEST(Ulog, GnssUtcNeedsA3dFixAndATime) {
  Ulog u;
  u.flags(0);
  u.format(
      "vehicle_gps_position:uint64_t timestamp;uint64_t time_utc_usec;int32_t lat;int32_t lon;int32_t alt;float "
      "eph;float epv;int32_t timestamp_time_relative;uint8_t fix_type;uint8_t satellites_used;");
  u.subscribe(0, 1, "vehicle_gps_position");
  auto gps = [&](uint64_t t, uint64_t utc, int32_t relative, uint8_t fix) {
    Fields f;
    f.u64(t).u64(utc);
    put(f.b, 473977420, 4);
    put(f.b, 85455940, 4);
    put(f.b, 488000, 4);
    f.f({1, 2});
    put(f.b, static_cast<uint32_t>(relative), 4);
    f.u8(fix).u8(fix >= 3 ? 10 : 0);
    u.data_bytes(1, f.b);
  };
  const uint64_t utc0 = 1700000000000000;
  gps(2000000, utc0, 0, 2);                // a 2D fix: its time is not taken
  gps(3000000, 0, 0, 3);                   // a 3D fix without a time
  gps(4000000, utc0 + 2000000, -5000, 3);  // UTC at boot time 3.995 s
  gps(5000000, utc0 + 3000000, -5000, 3);
  gps(6000000, utc0 + 4000000, -5000, 6);  // RTK fixed: a 3D fix too
  test::TempDir dir;
  test::write_file(dir.file("f.ulg"), u.b);
  ASSERT_TRUE(import_log(dir.file("f.ulg"), dir.file("out.lcm"), [](const std::string& p) { ADD_FAILURE() << p; }));
  const auto utc = analyzers::flight_utc(dir.file("out.lcm"), 0);
  ASSERT_TRUE(utc.known);
  EXPECT_EQ(utc.fixes, 3);
  EXPECT_EQ(utc.boot_to_utc_us, static_cast<int64_t>(utc0) - 1995000);  // utc0 + 2 s at 3.995 s
  EXPECT_EQ(utc.spread_s, 0);
  EXPECT_EQ(utc.channel, "vehicle_gps_position");
  // No information fields: the log's start is the one given, here 0, the boot.
  EXPECT_EQ(utc.start_utc_us, static_cast<int64_t>(utc0) - 1995000);
}

}  // namespace
}  // namespace driftlab::formats
