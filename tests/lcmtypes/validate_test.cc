// Tests for lcmtypes/validate.h: hostile lengths and short payloads are refused before any generated decoder sees
// them; every well-formed message passes.
#include "lcmtypes/validate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "driftlab/image_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/stream_header.h"
#include "tests/test_util.h"

namespace driftlab::lcmtypes {
namespace {

using test::encode;

using test::put_be32;

driftlab::laser_scan_t scan_of(int n) {
  driftlab::laser_scan_t s{};
  s.header = {1, 2, "laser"};
  s.nranges = n;
  s.ranges.assign(static_cast<size_t>(n), 1.5f);
  s.nintensities = n;
  s.intensities.assign(static_cast<size_t>(n), 7.0f);
  return s;
}
/// Offset of laser_scan_t.nranges with frame "laser": the header, then seven floats.
constexpr size_t kNranges = kHeaderFrameOffset + 4 + 6 + 7 * 4;

TEST(Validate, WellFormedMessagesPass) {
  EXPECT_EQ(layout_problem(encode(scan_of(0))), std::nullopt);
  EXPECT_EQ(layout_problem(encode(scan_of(361))), std::nullopt);
  driftlab::tf_t tf{};
  tf.header = {0, 0, "tf"};
  tf.ntransforms = 3;
  tf.transforms.resize(3);
  for (auto& t : tf.transforms) t.header.frame_id = "odom", t.child_frame_id = "base_link";
  EXPECT_EQ(layout_problem(encode(tf)), std::nullopt);
  driftlab::image_t img{};
  img.header.frame_id = "cam";
  img.encoding = "mono8";
  img.size = 4;
  img.data = {1, 2, 3, 4};
  EXPECT_EQ(layout_problem(encode(img)), std::nullopt);
  driftlab::laser_scan_t out;
  EXPECT_TRUE(decode(encode(scan_of(5)), out));
  EXPECT_EQ(out.ranges.size(), 5u);
}

TEST(Validate, NegativeLengthsAreRefusedNotThrown) {
  auto b = encode(scan_of(4));
  put_be32(b, kNranges, -5);
  ASSERT_TRUE(layout_problem(b).has_value());
  EXPECT_NE(layout_problem(b)->find("ranges: length -5"), std::string::npos) << *layout_problem(b);
  driftlab::laser_scan_t out;
  EXPECT_FALSE(decode(b, out));  // lcm-gen's decoder would throw std::length_error here
  // A frame_id length of -3.
  auto p = encode(scan_of(1));
  put_be32(p, kHeaderFrameOffset, -3);
  EXPECT_NE(layout_problem(p)->find("header.frame_id: string length -3"), std::string::npos) << *layout_problem(p);
  EXPECT_FALSE(decode(p, out));
}

TEST(Validate, HugeCountsInSmallMessagesAreRefusedWithoutAllocating) {
  driftlab::tf_t tf{};
  tf.header = {0, 0, ""};
  auto b = encode(tf);
  put_be32(b, kHeaderFrameOffset + 4 + 1, 0x7fffffff);  // ntransforms after the empty frame_id
  b.resize(2000, 0);
  ASSERT_TRUE(layout_problem(b).has_value());
  driftlab::tf_t out;
  EXPECT_FALSE(decode(b, out));
  auto s = encode(scan_of(2));
  put_be32(s, kNranges, 0x7fffffff);
  EXPECT_NE(layout_problem(s)->find("does not fit"), std::string::npos) << *layout_problem(s);
}

TEST(Validate, ShortAndLongPayloadsAreRefused) {
  driftlab::pose_t pose{};
  pose.header.frame_id = "world";
  pose.child_frame_id = "robot";
  auto b = encode(pose);
  const auto cut = std::vector<uint8_t>(b.begin(), b.begin() + 40);
  EXPECT_TRUE(layout_problem(cut).has_value());
  driftlab::pose_t out;
  EXPECT_FALSE(decode(cut, out));
  auto longer = b;
  longer.push_back(0);
  EXPECT_NE(layout_problem(longer)->find("1 bytes after the end"), std::string::npos);
  EXPECT_TRUE(layout_problem(std::vector<uint8_t>{1, 2, 3}).has_value());
  // Another type's bytes are not a pose.
  EXPECT_FALSE(decode(encode(scan_of(1)), out));
}

TEST(Validate, UnknownTypesHaveNoLayoutToCheck) {
  auto b = encode(scan_of(1));
  b[0] ^= 0xff;  // a fingerprint driftlab does not know
  EXPECT_EQ(layout_problem(b), std::nullopt);
}

TEST(Validate, EveryTruncationOfEveryMessageIsRefused) {
  driftlab::point_cloud_t pc{};
  pc.header.frame_id = "lidar";
  driftlab::imu_t imu{};
  imu.header.frame_id = "imu";
  for (const auto& b : {encode(scan_of(3)), encode(pc), encode(imu)}) {
    for (size_t n = 0; n < b.size(); ++n) {
      EXPECT_TRUE(layout_problem(std::span(b).first(n)).has_value()) << n;
    }
  }
}

TEST(NonFinite, NamesTheFirstNanOrInfinityWhereANumberMustBeOne) {
  driftlab::odometry_t o{};
  o.header = {0, 1, "odom"};
  EXPECT_EQ(non_finite(encode(o)), std::nullopt);
  o.twist_covariance[35] = INFINITY;
  EXPECT_EQ(non_finite(encode(o)), "twist_covariance[35] = inf");
  o.linear_velocity.x = NAN;  // earlier in the message: named first
  EXPECT_EQ(non_finite(encode(o)), "linear_velocity.x = nan");
  driftlab::tf_t tf{};
  tf.ntransforms = 3;
  tf.transforms.resize(3);
  tf.transforms[2].rotation.w = -INFINITY;
  EXPECT_EQ(non_finite(encode(tf)), "transforms[2].rotation.w = -inf");
}

TEST(NonFinite, LeavesSamplesAloneWhereNanMeansNoReturn) {
  auto scan = scan_of(4);
  scan.ranges = {1, NAN, INFINITY, 2};  // no return (REP 117)
  EXPECT_EQ(non_finite(encode(scan)), std::nullopt);
  scan.angle_increment = NAN;
  EXPECT_EQ(non_finite(encode(scan)), "angle_increment = nan");
  driftlab::point_cloud_t pc{};
  pc.npoints = 2;
  pc.x = {NAN, 1};
  pc.y = {NAN, 1};
  pc.z = {NAN, 1};
  EXPECT_EQ(non_finite(encode(pc)), std::nullopt);
  // Nothing to say about what is malformed or of an unknown type.
  auto bad = encode(scan);
  bad.resize(bad.size() - 1);
  EXPECT_EQ(non_finite(bad), std::nullopt);
  EXPECT_EQ(non_finite(std::vector<uint8_t>(16, 0)), std::nullopt);
}

}  // namespace
}  // namespace driftlab::lcmtypes
