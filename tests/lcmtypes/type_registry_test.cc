// Tests for the fingerprint registry generated from lcmtypes/*.lcm.
#include "lcmtypes/type_registry.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"

namespace driftlab::lcmtypes {
namespace {

TEST(TypeRegistry, NamesEncodedMessagesByTheirFingerprint) {
  driftlab::imu_t imu{};
  imu.header.frame_id = "imu";
  std::vector<uint8_t> buf(imu.getEncodedSize());
  ASSERT_EQ(imu.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  int64_t fp = 0;
  for (int i = 0; i < 8; ++i) fp = (fp << 8) | buf[i];
  ASSERT_NE(type_name(fp), nullptr);
  EXPECT_STREQ(type_name(fp), "driftlab.imu_t");
  EXPECT_STREQ(type_name(driftlab::laser_scan_t::getHash()), "driftlab.laser_scan_t");
  EXPECT_EQ(type_name(0x1234), nullptr);
}

TEST(TypeRegistry, ListsEveryTypeWithADistinctFingerprint) {
  std::set<int64_t> fingerprints;
  std::set<std::string> names;
  for (const TypeInfo& t : all_types()) {
    fingerprints.insert(t.fingerprint);
    names.insert(t.name);
  }
  EXPECT_EQ(fingerprints.size(), all_types().size());
  EXPECT_TRUE(find_type(driftlab::imu_t::getHash())->has_header);
  EXPECT_FALSE(find_type(driftlab::laser_scan_t::getHash()) == nullptr);
  for (const TypeInfo& t : all_types()) {
    const std::string name = t.name;
    const bool stream = name != "driftlab.header_t" && name != "driftlab.vector3_t" &&
                        name != "driftlab.quaternion_t" && name != "driftlab.fault_t" &&
                        name != "driftlab.channel_stats_t" && name != "driftlab.sender_stats_t" &&
                        // a point of a joint_trajectory_t, stamped by its trajectory
                        name != "driftlab.joint_trajectory_point_t" &&
                        // an imported message of a type driftlab does not map, and its definition: the source's bytes
                        name != "driftlab.foreign_message_t" && name != "driftlab.foreign_schema_t" &&
                        // what an import says of a channel
                        name != "driftlab.channel_source_t";
    EXPECT_EQ(t.has_header, stream) << name;
  }
  for (const char* required : {"driftlab.header_t", "driftlab.imu_t", "driftlab.laser_scan_t",
                               "driftlab.point_cloud_t", "driftlab.odometry_t", "driftlab.pose_t", "driftlab.tf_t",
                               "driftlab.velocity_command_t", "driftlab.image_t", "driftlab.joint_state_t",
                               "driftlab.fault_manifest_t", "driftlab.recorder_stats_t", "driftlab.module_stats_t"}) {
    EXPECT_TRUE(names.count(required)) << required;
  }
}

}  // namespace
}  // namespace driftlab::lcmtypes
