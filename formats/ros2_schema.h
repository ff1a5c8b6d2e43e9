// ROS 2 message definitions as rosbag2 and MCAP store them (ros2msg): the standard types' exact upstream text, and
// driftlab's own types (package driftlab_msgs) made from their .lcm definitions; which ROS 2 type each driftlab
// type goes out as. For the MCAP and rosbag2 export (formats/export_mcap.h). Thread-safety: pure functions.
#pragma once

#include <string>
#include <string_view>

namespace driftlab::formats {

/// The ROS 2 type a driftlab type goes out as ("sensor_msgs/msg/LaserScan" for "driftlab.laser_scan_t";
/// "driftlab_msgs/msg/ChannelStats" for types without a standard equivalent).
std::string ros2_type_for(std::string_view driftlab_type);

/// The ros2msg schema of a type as rosbag2 stores it: its .msg text, then each type it uses (depth first, in
/// name order, each once) after a line of 80 '=' and "MSG: pkg/Type". Standard types (sensor_msgs,
/// geometry_msgs, nav_msgs, std_msgs, tf2_msgs, builtin_interfaces) have their exact upstream text; driftlab_msgs
/// types are made from lcmtypes/. Empty for a type neither knows.
std::string ros2_schema(std::string_view ros_type);

}  // namespace driftlab::formats
