// ROS messages onto driftlab's messages: the standard sensor, navigation and geometry types a robot records,
// decoded from ROS 1 serialization (little endian, packed) or CDR (ROS 2: aligned, either byte order) and encoded
// as the driftlab LCM type that carries the same data. header.stamp becomes header.utime (the source clock);
// ROS 1's header.seq becomes header.seq. Thread-safety: plain functions.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "driftlab/header_t.hpp"

namespace driftlab::formats {

enum class Serialization { kRos1, kCdr };

/// "sensor_msgs/msg/LaserScan" -> "sensor_msgs/LaserScan" (ROS 2 names as ROS 1 writes them).
std::string ros1_type_name(std::string_view type);

/// The driftlab type a ROS type maps onto ("driftlab.laser_scan_t"), or nullptr when it has no mapping.
const char* driftlab_type_for(std::string_view ros_type);

struct Converted {
  std::vector<uint8_t> lcm;  ///< the driftlab message, LCM-encoded
  int64_t stamp_us = 0;      ///< its header.utime (0 for a type without a stamp)
  bool has_seq = false;      ///< header.seq is the source's (ROS 1 header.seq), not fallback_seq
};

/// rosgraph_msgs/Clock (ROS 1 or 2): the simulation's clock, as a simulator publishes it on /clock.
bool is_ros_clock_type(std::string_view ros_type);
/// A rosgraph_msgs/Clock as a header: its time the stamp, `fallback_seq` the seq, no frame; false when the payload
/// is too short for one. Carried so, /clock is a stream on simulation time like the others, and their reference
/// (analyzers/clock_domain.cc).
bool read_clock(Serialization serialization, std::span<const uint8_t> payload, int64_t fallback_seq, header_t* out);

/// The std_msgs/Header a message of another type starts with, as header_t (ROS 1's seq, else `fallback_seq`), or
/// false when the payload is too short for one. `has_seq` says whether the seq was the source's.
bool read_leading_header(Serialization serialization, std::span<const uint8_t> payload, int64_t fallback_seq,
                         header_t* out, bool* has_seq);

/// Converts one ROS message of a mapped type. `error` says why not when the payload does not hold a message of
/// its type ("12 bytes, shorter than sensor_msgs/LaserScan"); nullopt with an empty error means "no mapping".
/// `unstamped_us` is used as header.utime for types without a header (geometry_msgs/Twist): the arrival time;
/// `fallback_seq` as header.seq where the message carries none (ROS 2, tf2_msgs/TFMessage): the caller's count.
/// `reuse`, when given, is a buffer the result may take the memory of (a large message's: a point cloud's), so a
/// caller converting many gives back each result's `lcm` and the next is neither allocated nor zero-filled.
std::optional<Converted> convert_ros_message(std::string_view ros_type, Serialization serialization,
                                             std::span<const uint8_t> payload, int64_t unstamped_us,
                                             int64_t fallback_seq, std::string* error,
                                             std::vector<uint8_t>* reuse = nullptr);

}  // namespace driftlab::formats
