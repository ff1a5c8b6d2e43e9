// Tests for lcmtypes/stream_header.h: the header's byte layout read and rewritten in place, checked against
// lcm-gen's own encoders and decoders.
#include "lcmtypes/stream_header.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/validate.h"
#include "tests/lcmtypes/largest_allocation.h"
#include "tests/test_util.h"

namespace driftlab::lcmtypes {
namespace {

using test::encode;

/// A foreign type (not in the registry) that starts with our header: a different fingerprint, same bytes after it.
std::vector<uint8_t> as_foreign(std::vector<uint8_t> b) {
  b[0] ^= 0x5A;
  return b;
}

TEST(StreamHeader, ReadHeaderAgreesWithLcmGensEncoder) {
  driftlab::imu_t imu{};
  imu.header = {17, 1234567, "imu_link"};
  const auto b = encode(imu);
  const auto h = read_header(b, 0);
  ASSERT_TRUE(h.has_value());
  EXPECT_EQ(h->seq, 17);
  EXPECT_EQ(h->utime, 1234567);
  EXPECT_EQ(h->frame_id, "imu_link");
  EXPECT_EQ(header_stamp(b, 0), 1234567);
  // A known type is trusted whatever its stamp; an unknown one only when its stamp is near its arrival.
  EXPECT_TRUE(has_header(b, int64_t{1} << 60));
  const auto foreign = as_foreign(b);
  EXPECT_TRUE(has_header(foreign, 1234567 + 3'600'000'000LL));
  EXPECT_FALSE(has_header(foreign, 1234567 + 2 * 86'400'000'000LL));
}

TEST(StreamHeader, ShapeCheckIsSafeOnArbitraryStamps) {
  // Stamps and arrivals at the ends of int64 used to overflow stamp - arrival (UBSan: signed overflow).
  driftlab::imu_t imu{};
  imu.header = {1, std::numeric_limits<int64_t>::min(), "x"};
  const auto b = as_foreign(encode(imu));
  EXPECT_FALSE(looks_like_header(b, std::numeric_limits<int64_t>::max()));
  imu.header.utime = std::numeric_limits<int64_t>::max();
  EXPECT_FALSE(looks_like_header(as_foreign(encode(imu)), std::numeric_limits<int64_t>::min()));
  EXPECT_TRUE(looks_like_header(as_foreign(encode(imu)), std::numeric_limits<int64_t>::max() - 5));
}

TEST(StreamHeader, ShortOrBrokenHeadersAreRefused) {
  driftlab::imu_t imu{};
  imu.header = {1, 100, "frame"};
  auto b = encode(imu);
  EXPECT_FALSE(read_header(std::span(b).first(kHeaderFrameOffset + 2), 100).has_value());
  // A frame_id length running past the message.
  b[kHeaderFrameOffset] = 0x7f;
  EXPECT_FALSE(read_header(b, 100).has_value());
  EXPECT_FALSE(header_stamp(b, 100).has_value());
  EXPECT_FALSE(has_header(std::vector<uint8_t>{}, 0));
}

TEST(StreamHeader, MapStampsRewritesHeadersAndTransforms) {
  driftlab::pose_t pose{};
  pose.header = {2, 5000, "world"};
  auto b = encode(pose);
  ASSERT_TRUE(map_stamps(b, 0, [](int64_t s) { return s + 250; }));
  driftlab::pose_t back;
  ASSERT_GT(back.decode(b.data(), 0, static_cast<int>(b.size())), 0);
  EXPECT_EQ(back.header.utime, 5250);

  driftlab::tf_t tf{};
  tf.header = {3, 1000, ""};
  tf.ntransforms = 2;
  tf.transforms.resize(2);
  tf.transforms[0].header = {0, 1100, "odom"};
  tf.transforms[1].header = {0, 1200, "base_link"};
  auto t = encode(tf);
  ASSERT_TRUE(map_stamps(t, 0, [](int64_t s) { return s - 100; }));
  driftlab::tf_t tf_back;
  ASSERT_GT(tf_back.decode(t.data(), 0, static_cast<int>(t.size())), 0);
  EXPECT_EQ(tf_back.header.utime, 900);
  EXPECT_EQ(tf_back.transforms[0].header.utime, 1000);
  EXPECT_EQ(tf_back.transforms[1].header.utime, 1100);

  // A tf_t whose transform count is impossible is refused, not thrown through.
  t[kHeaderFrameOffset + 4 + 1] = 0xff;  // ntransforms follows the empty frame_id: make it negative
  t[kHeaderFrameOffset + 4 + 2] = 0xff;
  t[kHeaderFrameOffset + 4 + 3] = 0xff;
  t[kHeaderFrameOffset + 4 + 4] = 0xfb;
  const auto before = t;
  EXPECT_FALSE(map_stamps(t, 0, [](int64_t s) { return s; }));
  EXPECT_EQ(t, before);
}

TEST(StreamHeader, MapStampsRefusesAnImpossibleTransformCountBeforeAllocatingForIt) {
  // A 1.5 KB tf_t claiming 2,000,000 transforms: lcm-gen's decoder sized its vector for them (some 270 MB) before
  // finding the message short, on every TF message `replay --restamp` rewrote (peak memory 393 MB instead of 136).
  // The layout check refuses the count first: the message is left as it was and nothing near that size is allocated.
  driftlab::tf_t tf{};
  tf.header = {1, 1000, ""};
  tf.ntransforms = 1;
  tf.transforms.resize(1);
  tf.transforms[0].header = {0, 1000, "odom"};
  tf.transforms[0].child_frame_id = "base_link";
  auto t = encode(tf);
  test::put_be32(t, kHeaderFrameOffset + 4 + 1, 2'000'000);  // ntransforms follows the empty frame_id
  t.resize(1500, 0);
  ASSERT_TRUE(layout_problem(t).has_value());
  const auto before = t;
  test::start_counting_allocations();
  const bool mapped = map_stamps(t, 0, [](int64_t s) { return s + 1; });
  const std::size_t largest = test::largest_allocation();
  EXPECT_FALSE(mapped);
  EXPECT_EQ(t, before);
  EXPECT_LT(largest, std::size_t{64} << 10) << "an allocation of " << largest << " bytes";
  // The counter sees a decoder's allocations: a well-formed message of 2,000 transforms is decoded and rewritten.
  tf.transforms.resize(2000, tf.transforms[0]);
  tf.ntransforms = 2000;
  auto big = encode(tf);
  test::start_counting_allocations();
  const bool rewritten = map_stamps(big, 0, [](int64_t s) { return s + 1; });
  EXPECT_GE(test::largest_allocation(), 2000 * sizeof(driftlab::transform_t));
  EXPECT_TRUE(rewritten);
}

TEST(StreamHeader, ReadyAfterIsTheSweepToTheLastBeam) {
  driftlab::laser_scan_t scan{};
  scan.header = {0, 0, "laser"};
  scan.time_increment = 1e-4f;
  scan.nranges = 361;
  scan.ranges.assign(361, 1.0f);
  EXPECT_EQ(ready_after_us(encode(scan)), 36000);
  scan.time_increment = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(ready_after_us(encode(scan)), 0);
  driftlab::imu_t imu{};
  EXPECT_EQ(ready_after_us(encode(imu)), 0);
  // A negative beam count (hostile bytes) reads as no sweep, without decoding the ranges.
  scan.time_increment = 1e-4f;
  auto b = encode(scan);
  const size_t nranges_at = kHeaderFrameOffset + 4 + 6 + 7 * 4;  // frame "laser" + NUL, seven floats
  b[nranges_at] = 0xff;
  EXPECT_EQ(ready_after_us(b), 0);
}

TEST(StreamHeader, ReadMotionAgreesWithLcmGensDecoders) {
  driftlab::imu_t imu{};
  imu.header = {3, 1234567, "an_imu_frame"};
  imu.angular_velocity = {0.1, 0.2, 0.3};
  imu.orientation_covariance[8] = 9;
  driftlab::odometry_t odom{};
  odom.header = {4, 7654321, "odom"};
  odom.child_frame_id = "base_link_with_a_long_name";
  odom.angular_velocity = {1, 2, -0.7};
  odom.linear_velocity = {5, 6, 7};
  driftlab::pose_t pose{};
  pose.header = {5, 42, "world"};
  pose.child_frame_id = "robot";
  const double yaw = 2.5;
  pose.orientation = {std::cos(yaw / 2), 0, 0, std::sin(yaw / 2)};
  const auto b1 = encode(imu);
  auto m = read_motion(b1);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->stamp_s, 1.234567);
  EXPECT_EQ(m->value, 0.3);
  EXPECT_FALSE(m->is_pose);
  const auto b2 = encode(odom);
  m = read_motion(b2);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->value, -0.7);
  const auto b3 = encode(pose);
  m = read_motion(b3);
  ASSERT_TRUE(m.has_value());
  EXPECT_TRUE(m->is_pose);
  EXPECT_NEAR(m->value, yaw, 1e-12);
  // Truncated data is refused, not read past its end
  // (cut 2 bytes into angular_velocity.z, which the 36 doubles of twist_covariance follow).
  EXPECT_FALSE(read_motion(std::span(b2).first(b2.size() - 36 * 8 - 2)).has_value());
  driftlab::laser_scan_t scan{};
  EXPECT_FALSE(read_motion(encode(scan)).has_value());
}

}  // namespace
}  // namespace driftlab::lcmtypes
