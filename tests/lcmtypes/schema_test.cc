// Tests for lcmtypes/schema.h: the compiled-in definitions and walking messages by them.
#include "lcmtypes/schema.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

#include "driftlab/image_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/recorder_stats_t.hpp"
#include "lcmtypes/type_registry.h"

namespace driftlab::lcmtypes {
namespace {

template <typename T>
std::vector<uint8_t> encode(const T& m) {
  std::vector<uint8_t> buf(static_cast<size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  return buf;
}

std::vector<std::pair<std::string, std::string>> walk(const char* type, const std::vector<uint8_t>& data,
                                                      const FlattenOptions& o = {}, bool* complete = nullptr) {
  std::vector<std::pair<std::string, std::string>> out;
  const StructDef* def = find_struct(type);
  EXPECT_NE(def, nullptr) << type;
  if (def == nullptr) return out;
  const bool ok = flatten(*def, data, [&](const std::string& c, const std::string& v) { out.emplace_back(c, v); }, o);
  if (complete != nullptr) *complete = ok;
  return out;
}

TEST(Schema, EveryRegisteredTypeHasADefinition) {
  for (const TypeInfo& t : all_types()) {
    const StructDef* def = find_struct(t.name);
    ASSERT_NE(def, nullptr) << t.name;
    EXPECT_FALSE(def->fields.empty()) << t.name;
    EXPECT_EQ(def->fields.front().name == "header", t.has_header) << t.name;
  }
  EXPECT_EQ(find_struct("driftlab.no_such_t"), nullptr);
}

TEST(Schema, FlattenVisitsEveryFieldOfAnImuInOrderWithItsValue) {
  driftlab::imu_t imu{};
  imu.header.seq = 41;
  imu.header.utime = -1234567890123;
  imu.header.frame_id = "imu_link";
  imu.orientation = {1, 0, 0, 0};
  imu.angular_velocity = {0.1, -0.2, 0.3};
  imu.linear_acceleration = {0, 0, 9.81};
  imu.angular_velocity_covariance[8] = 1e-6;
  const auto v = walk("driftlab.imu_t", encode(imu));
  ASSERT_EQ(v.size(), 3u + 4 + 9 + 3 + 9 + 3 + 9);
  EXPECT_EQ(v[0], std::make_pair(std::string("header.seq"), std::string("41")));
  EXPECT_EQ(v[1].second, "-1234567890123");
  EXPECT_EQ(v[2], std::make_pair(std::string("header.frame_id"), std::string("imu_link")));
  std::map<std::string, std::string> by_name(v.begin(), v.end());
  EXPECT_EQ(std::stod(by_name["angular_velocity.y"]), -0.2);
  EXPECT_EQ(std::stod(by_name["linear_acceleration.z"]), 9.81);
  EXPECT_EQ(std::stod(by_name["angular_velocity_covariance[8]"]), 1e-6);
  EXPECT_EQ(std::stod(by_name["orientation.w"]), 1.0);
}

TEST(Schema, VariableArraysFollowTheirLengthFieldAndLongOnesAreLeftOut) {
  driftlab::laser_scan_t scan{};
  scan.header.frame_id = "laser";
  scan.nranges = 3;
  scan.ranges = {1.5f, NAN, 2.25f};
  scan.nintensities = 0;
  auto v = walk("laser_scan_t", encode(scan));
  std::map<std::string, std::string> by_name(v.begin(), v.end());
  EXPECT_EQ(by_name["nranges"], "3");
  EXPECT_EQ(by_name["ranges[0]"], "1.5");
  EXPECT_EQ(by_name["ranges[1]"], "nan");
  EXPECT_EQ(by_name["ranges[2]"], "2.25");
  EXPECT_EQ(by_name.count("ranges[3]"), 0u);
  EXPECT_EQ(by_name["nintensities"], "0");

  FlattenOptions few;
  few.max_array = 2;
  v = walk("laser_scan_t", encode(scan), few);
  by_name = {v.begin(), v.end()};
  EXPECT_EQ(by_name.count("ranges[0]"), 0u);
  EXPECT_EQ(by_name["nranges"], "3");
  EXPECT_EQ(by_name["nintensities"], "0");  // what follows the left-out array is still read right
}

TEST(Schema, BytesOnlyWhenAskedAndNestedArraysOfStructs) {
  driftlab::image_t image{};
  image.encoding = "png";
  image.size = 2;
  image.data = {7, 255};
  auto v = walk("image_t", encode(image));
  std::map<std::string, std::string> by_name(v.begin(), v.end());
  EXPECT_EQ(by_name.count("data[0]"), 0u);
  EXPECT_EQ(by_name["encoding"], "png");
  FlattenOptions bytes;
  bytes.bytes = true;
  v = walk("image_t", encode(image), bytes);
  by_name = {v.begin(), v.end()};
  EXPECT_EQ(by_name["data[0]"], "7");
  EXPECT_EQ(by_name["data[1]"], "255");  // LCM's byte is unsigned

  driftlab::recorder_stats_t stats{};
  stats.nsenders = 2;
  stats.senders.resize(2);
  stats.senders[1].sender = "10.0.0.2:7667";
  stats.senders[1].lost = 5;
  stats.nchannels = 0;
  v = walk("recorder_stats_t", encode(stats));
  by_name = {v.begin(), v.end()};
  EXPECT_EQ(by_name["senders[1].sender"], "10.0.0.2:7667");
  EXPECT_EQ(by_name["senders[1].lost"], "5");
}

// walk() (the Python module's reads): columns without indices, a numeric array in one call, the same bytes the
// text walk formats, and lengths still followed.
TEST(Schema, WalkGivesEachArrayOfNumbersInOneCallAsItsBytes) {
  driftlab::laser_scan_t scan{};
  scan.header.seq = 7;
  scan.header.frame_id = "laser";
  scan.nranges = 3;
  scan.ranges = {1.5f, NAN, 2.25f};
  scan.nintensities = 0;
  std::vector<std::pair<std::string, size_t>> calls;
  std::vector<uint8_t> ranges;
  const bool ok = lcmtypes::walk(*find_struct("laser_scan_t"), encode(scan),
                                 [&](const std::string& column, const FieldDef& f, std::span<const uint8_t> bytes) {
                                   calls.emplace_back(column, bytes.size());
                                   if (column == "ranges") {
                                     EXPECT_EQ(f.type, "float");
                                     ranges.assign(bytes.begin(), bytes.end());
                                   }
                                 });
  EXPECT_TRUE(ok);
  ASSERT_EQ(calls.size(), 3u + 7 + 1 + 1 + 1 + 1);  // header, 7 floats, nranges, ranges, nintensities, intensities
  EXPECT_EQ(calls[0], std::make_pair(std::string("header.seq"), size_t{8}));
  EXPECT_EQ(calls[2], std::make_pair(std::string("header.frame_id"), size_t{5}));  // without its NUL
  EXPECT_EQ(calls[11], std::make_pair(std::string("ranges"), size_t{12}));
  EXPECT_EQ(calls[13], std::make_pair(std::string("intensities"), size_t{0}));  // empty, still named
  ASSERT_EQ(ranges.size(), 12u);
  EXPECT_EQ(ranges[0], 0x3f);  // 1.5f big-endian: 3f c0 00 00
  EXPECT_EQ(ranges[1], 0xc0);
}

TEST(Schema, TruncatedDataStopsWithoutReadingPastTheEnd) {
  driftlab::laser_scan_t scan{};
  scan.nranges = 100;
  scan.ranges.assign(100, 1.0f);
  auto bytes = encode(scan);
  bytes.resize(bytes.size() - 10);
  bool complete = true;
  const auto v = walk("laser_scan_t", bytes, {}, &complete);
  EXPECT_FALSE(complete);
  EXPECT_LT(v.size(), 100u + 12);
  bytes.resize(4);
  EXPECT_TRUE(walk("laser_scan_t", bytes, {}, &complete).empty());
  EXPECT_FALSE(complete);
}

}  // namespace
}  // namespace driftlab::lcmtypes
