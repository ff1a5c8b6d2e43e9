// driftlab import of the standard messages on files driftlab did not write: an MCAP file made here by the writers
// Foxglove runs (tests/oracle/write_mcap.mjs: @mcap/core with @foxglove/rosmsg2-serialization for ROS 2's CDR, or
// @foxglove/rosmsg-serialization for ROS 1's serialization), from values chosen here; every converted message must
// hold those values (tests/formats/oracle.h: expect_same_message), and what the mapping decides (a fix's type, a
// compressed image's size, a missing quantity) is checked against the values too.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "driftlab/barometer_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/image_t.hpp"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/velocity_command_t.hpp"
#include "lcmtypes/validate.h"
#include "tests/formats/import_in_process.h"
#include "tests/formats/oracle.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using nlohmann::json;
using test::OwnedEvent;

/// A JPEG's first markers: APP0, then a baseline start-of-frame saying 320 x 240, then the end.
const std::vector<int> kJpeg = {0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 'J',  'F',  'I',  'F',  0x00, 0x01, 0x01, 0x00,
                                0x00, 0x01, 0x00, 0x01, 0x00, 0x00, 0xFF, 0xC0, 0x00, 0x11, 0x08, 0x00, 0xF0, 0x01,
                                0x40, 0x03, 0x01, 0x22, 0x00, 0x02, 0x11, 0x01, 0x03, 0x11, 0x01, 0xFF, 0xD9};
/// A PNG's signature and IHDR chunk: 7 x 5 pixels.
const std::vector<int> kPng = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A, 0, 0, 0, 0x0D, 'I', 'H',  'D',  'R',
                               0,    0,   0,   7,   0,    0,    0,    5,    8, 2, 0, 0,    0,   0x12, 0x34, 0x56};

struct Case {
  const char* name;
  bool ros2;
  const char* compression;
};

class StandardMessages : public ::testing::TestWithParam<Case> {
 protected:
  bool ros2() const { return GetParam().ros2; }
  json stamp(int64_t sec, int64_t nsec) const {
    return ros2() ? json{{"sec", sec}, {"nanosec", nsec}} : json{{"sec", sec}, {"nsec", nsec}};
  }
  /// A header: ROS 1's carries a seq (here 40 + i, so it differs from the count on the topic).
  json header(int i, const char* frame) const {
    json h = {{"stamp", stamp(1'700'000'000 + i, 123'456'789 + i)}, {"frame_id", frame}};
    if (!ros2()) h["seq"] = 40 + i;
    return h;
  }
  /// The spec's messages: each type three times (i = 0, 1, 2) on its own topic, received 2 ms after the stamp.
  json messages() const {
    json out = json::array();
    const std::string pkg = ros2() ? "/msg/" : "/";
    auto add = [&](const std::string& topic, const std::string& type, int i, json msg) {
      const int64_t t = (1'700'000'000 + i) * int64_t{1'000'000'000} + 123'456'789 + i + 2'000'777;
      const std::string full = type.substr(0, type.find('/')) + pkg + type.substr(type.find('/') + 1);
      // ROS 2: an MCAP sequence of its own per message (10 + i); ROS 1's MCAP: none (0), so the count applies.
      out.push_back({{"topic", topic},
                     {"type", full},
                     {"encoding", ros2() ? "cdr" : "ros1"},
                     {"time_ns", t},
                     {"sequence", ros2() ? 10 + i : 0},
                     {"msg", std::move(msg)}});
    };
    for (int i = 0; i < 3; ++i) {
      const double d = i;
      add("/imu", "sensor_msgs/Imu", i,
          {{"header", header(i, "imu_link")},
           {"orientation", {{"x", 0.1 * d}, {"y", -0.2}, {"z", 0.3}, {"w", 0.9}}},
           {"orientation_covariance", {-1, 0, 0, 0, 0, 0, 0, 0, 0}},  // "no orientation", as ROS says it
           {"angular_velocity", {{"x", 0.01}, {"y", -0.02 * d}, {"z", 1.5}}},
           {"angular_velocity_covariance", {1e-4, 0, 0, 0, 1e-4, 0, 0, 0, 2e-4}},
           {"linear_acceleration", {{"x", 0.25}, {"y", 0.5}, {"z", 9.80665 + d}}},
           {"linear_acceleration_covariance", {0.01, 0.001, 0, 0.001, 0.01, 0, 0, 0, 0.02}}});
      // mono8 rows of 3 pixels padded to a step of 4 (the padding byte 0xEE must not reach the log), and an rgb8
      // image without padding.
      const json image = i == 1 ? json{{"header", header(i, "camera")},
                                       {"height", 1},
                                       {"width", 2},
                                       {"encoding", "rgb8"},
                                       {"is_bigendian", 0},
                                       {"step", 6},
                                       {"data", {1, 2, 3, 4, 5, 6}}}
                                : json{{"header", header(i, "camera")},
                                       {"height", 2},
                                       {"width", 3},
                                       {"encoding", "mono8"},
                                       {"is_bigendian", 0},
                                       {"step", 4},
                                       {"data", {10 + i, 20, 30, 0xEE, 40, 50, 60, 0xEE}}};
      add("/camera/image_raw", "sensor_msgs/Image", i, image);
      add("/camera/image_raw/compressed", "sensor_msgs/CompressedImage", i,
          {{"header", header(i, "camera")}, {"format", i == 2 ? "png" : "jpeg"}, {"data", i == 2 ? kPng : kJpeg}});
      add("/joint_states", "sensor_msgs/JointState", i,
          {{"header", header(i, "")},
           {"name", {"shoulder", "elbow", "wrist"}},
           {"position", {0.5 * d, -1.25, 3.0}},
           {"velocity", {0.0, 0.125, -0.5 * d}},
           {"effort", json::array()}});  // not measured
      add("/goal_pose", "geometry_msgs/PoseStamped", i,
          {{"header", header(i, "map")},
           {"pose",
            {{"position", {{"x", 12.5 + d}, {"y", -3.25}, {"z", 0.0}}},
             {"orientation", {{"x", 0.0}, {"y", 0.0}, {"z", 0.38268343236508978}, {"w", 0.92387953251128674}}}}}});
      add("/mocap/base", "geometry_msgs/TransformStamped", i,
          {{"header", header(i, "world")},
           {"child_frame_id", "base_link"},
           {"transform",
            {{"translation", {{"x", 1.0}, {"y", 2.0 + d}, {"z", 0.1}}},
             {"rotation", {{"x", 0.0}, {"y", 0.0}, {"z", 0.0}, {"w", 1.0}}}}}});
      add("/cmd_vel", "geometry_msgs/Twist", i,
          {{"linear", {{"x", 0.3 * d}, {"y", 0.0}, {"z", 0.0}}}, {"angular", {{"x", 0.0}, {"y", 0.0}, {"z", -0.4}}}});
      // A 3D fix with known variances, a 2D fix (no altitude) with an approximated covariance, no fix.
      const json fixes[3] = {{{"header", header(i, "gps")},
                              {"status", {{"status", 0}, {"service", 1}}},
                              {"latitude", 48.1351253},
                              {"longitude", 11.5819806},
                              {"altitude", 519.25},
                              {"position_covariance", {2.25, 0, 0, 0, 4.0, 0, 0, 0, 9.0}},
                              {"position_covariance_type", 2}},
                             {{"header", header(i, "gps")},
                              {"status", {{"status", 1}, {"service", 3}}},
                              {"latitude", -33.8688197},
                              {"longitude", 151.2092955},
                              {"altitude", "NaN"},
                              {"position_covariance", {1.0, 0.5, 0, 0.5, 1.0, 0, 0, 0, 16.0}},
                              {"position_covariance_type", 1}},
                             {{"header", header(i, "gps")},
                              {"status", {{"status", -1}, {"service", 1}}},
                              {"latitude", 0.0},
                              {"longitude", 0.0},
                              {"altitude", 0.0},
                              {"position_covariance", {0, 0, 0, 0, 0, 0, 0, 0, 0}},
                              {"position_covariance_type", 0}}};
      add("/fix", "sensor_msgs/NavSatFix", i, fixes[i]);
      add("/imu/mag", "sensor_msgs/MagneticField", i,
          {{"header", header(i, "imu_link")},
           {"magnetic_field", {{"x", 2.1e-5}, {"y", -4.5e-6 * d}, {"z", -4.3e-5}}},
           {"magnetic_field_covariance", {1e-12, 0, 0, 0, 1e-12, 0, 0, 0, 4e-12}}});
      add("/pressure", "sensor_msgs/FluidPressure", i,
          {{"header", header(i, "baro")}, {"fluid_pressure", 95461.5 - 10 * d}, {"variance", i == 0 ? 0.0 : 2.25}});
    }
    return out;
  }
};

/// The spec's values as the oracle's dump prints them (NaN as null).
json as_dumped(json j) {
  if (j.is_string() && j.get<std::string>() == "NaN") return nullptr;
  if (j.is_structured()) {
    for (auto& v : j) v = as_dumped(v);
  }
  return j;
}

TEST_P(StandardMessages, ImportHoldsTheValuesFoxglovesWritersWrote) {
  test::TempDir dir;
  const json msgs = messages();
  const std::string file = dir.file("written.mcap");
  if (!test::oracle_write_mcap(
          {{"profile", ros2() ? "ros2" : "ros1"}, {"compression", GetParam().compression}, {"messages", msgs}}, file)) {
    return;
  }
  // The writers wrote what was asked: Foxglove's readers read the same values back.
  auto dumped = test::oracle_messages(file);
  ASSERT_TRUE(dumped.has_value());
  ASSERT_EQ(dumped->size(), msgs.size());
  for (size_t i = 0; i < msgs.size(); ++i) EXPECT_EQ((*dumped)[i].at("msg"), as_dumped(msgs[i].at("msg"))) << i;

  const auto r = test::import_in_process({file}, dir.file("out.lcm"));
  ASSERT_EQ(r.said(), "");
  for (const char* line : {"NavSatFix", "driftlab.gnss_t", "driftlab.magnetometer_t", "driftlab.barometer_t",
                           "driftlab.image_t", "driftlab.joint_state_t"}) {
    EXPECT_NE(r.text.find(line), std::string::npos) << line << "\n" << r.text;
  }
  EXPECT_EQ(r.text.find("foreign_message_t"), std::string::npos) << r.text;  // every type mapped

  std::map<std::string, std::vector<OwnedEvent>> log;
  for (auto& e : test::read_all(dir.file("out.lcm"))) log[e.channel].push_back(std::move(e));
  EXPECT_EQ(log["CHANNEL_SOURCES"].size(), 10u);  // what the import says of each topic
  log.erase("CHANNEL_SOURCES");
  ASSERT_EQ(log.size(), 10u);
  std::map<std::string, int64_t> count;
  for (const auto& m : msgs) {
    const std::string topic = m.at("topic");
    ASSERT_TRUE(log.count(topic)) << topic;
    const int64_t k = count[topic]++;
    ASSERT_LT(k, static_cast<int64_t>(log.at(topic).size())) << topic;
    // header.seq where the message carries none: MCAP's sequence (ROS 2 here), else the count on the topic.
    const int64_t seq = m.at("sequence").get<int64_t>() != 0 ? m.at("sequence").get<int64_t>() : k;
    test::expect_same_message(as_dumped(m), log.at(topic)[static_cast<size_t>(k)], seq);
  }
  for (const auto& [topic, n] : count) EXPECT_EQ(static_cast<int64_t>(log.at(topic).size()), n) << topic;

  // What the mappings decide, against the values written.
  const auto& images = log.at("/camera/image_raw");
  EXPECT_EQ(test::decode<image_t>(images[0]).data, (std::vector<uint8_t>{10, 20, 30, 40, 50, 60}));  // padding gone
  EXPECT_EQ(test::decode<image_t>(images[1]).data, (std::vector<uint8_t>{1, 2, 3, 4, 5, 6}));
  const auto& compressed = log.at("/camera/image_raw/compressed");
  const auto jpeg = test::decode<image_t>(compressed[0]), png = test::decode<image_t>(compressed[2]);
  EXPECT_EQ(jpeg.encoding, "jpeg");
  EXPECT_EQ(jpeg.width, 320);  // from the JPEG's start-of-frame
  EXPECT_EQ(jpeg.height, 240);
  EXPECT_EQ(jpeg.size, static_cast<int32_t>(kJpeg.size()));
  EXPECT_EQ(png.encoding, "png");
  EXPECT_EQ(png.width, 7);  // from the PNG's IHDR
  EXPECT_EQ(png.height, 5);
  const auto joints = test::decode<joint_state_t>(log.at("/joint_states")[2]);
  ASSERT_EQ(joints.njoints, 3);
  EXPECT_EQ(joints.position[0], 1.0);
  EXPECT_EQ(joints.velocity[2], -1.0);
  for (double v : joints.effort) EXPECT_TRUE(std::isnan(v));  // not measured
  for (int i = 0; i < 3; ++i) {
    const auto& e = log.at("/cmd_vel")[static_cast<size_t>(i)];
    const auto twist = test::decode<velocity_command_t>(e);
    EXPECT_EQ(twist.header.utime, e.utime);  // no stamp of its own: its arrival, so no latency
    EXPECT_EQ(e.utime, (1'700'000'000 + i) * int64_t{1'000'000} + 125'457);
  }
  const auto& fixes = log.at("/fix");
  const auto fix3 = test::decode<gnss_t>(fixes[0]), fix2 = test::decode<gnss_t>(fixes[1]),
             none = test::decode<gnss_t>(fixes[2]);
  EXPECT_EQ(fix3.header.utime, 1'700'000'000'123'456);
  EXPECT_EQ(fixes[0].utime, 1'700'000'000'125'457);  // the arrival: both clocks kept
  EXPECT_EQ(fix3.fix_type, 3);
  EXPECT_EQ(fix3.altitude_m, 519.25);
  EXPECT_DOUBLE_EQ(fix3.eph_m, std::sqrt((2.25 + 4.0) / 2));
  EXPECT_EQ(fix3.epv_m, 3.0);
  EXPECT_EQ(fix3.satellites, 0);  // not given
  EXPECT_TRUE(std::isnan(fix3.velocity.x) && std::isnan(fix3.velocity.y) && std::isnan(fix3.velocity.z));
  EXPECT_TRUE(std::isnan(fix3.speed_accuracy_m_s));
  EXPECT_EQ(fix2.fix_type, 2);  // a fix without altitude
  EXPECT_TRUE(std::isnan(fix2.altitude_m));
  EXPECT_EQ(fix2.eph_m, 1.0);
  EXPECT_EQ(fix2.epv_m, 4.0);
  EXPECT_EQ(none.fix_type, 0);
  EXPECT_EQ(none.eph_m, 0);  // covariance unknown
  EXPECT_EQ(none.epv_m, 0);
  const auto mag = test::decode<magnetometer_t>(log.at("/imu/mag")[1]);
  EXPECT_EQ(mag.magnetic_field.y, -4.5e-6);
  EXPECT_EQ(mag.magnetic_field_covariance[8], 4e-12);
  const auto baro0 = test::decode<barometer_t>(log.at("/pressure")[0]),
             baro2 = test::decode<barometer_t>(log.at("/pressure")[2]);
  EXPECT_EQ(baro0.pressure_pa, 95461.5);
  EXPECT_EQ(baro0.pressure_variance, 0);
  EXPECT_EQ(baro2.pressure_pa, 95441.5);
  EXPECT_EQ(baro2.pressure_variance, 2.25);
  EXPECT_TRUE(std::isnan(baro0.temperature_c));  // FluidPressure carries none
  if (!ros2()) {
    EXPECT_EQ(fix3.header.seq, 40);                                               // ROS 1's header.seq
    EXPECT_EQ(test::decode<velocity_command_t>(log.at("/cmd_vel")[2]).header.seq, 2);  // the count: Twist has none
  } else {
    EXPECT_EQ(fix3.header.seq, 10);  // MCAP's sequence
  }
}

INSTANTIATE_TEST_SUITE_P(Import, StandardMessages,
                         ::testing::Values(Case{"Ros2CdrZstdChunks", true, "zstd"},
                                           Case{"Ros1SerializationUncompressedChunks", false, "none"}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace driftlab
