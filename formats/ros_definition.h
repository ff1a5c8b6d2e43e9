// ROS message definitions as bags store them (rosbag's connection `message_definition`, rosbag2's and MCAP's
// `ros1msg`/`ros2msg` schemas): the type's .msg text, then each type it uses after a line of '=' and a line
// "MSG: pkg/Type". Parsed into types, so that any message can be walked field by field by its definition, in ROS 1
// serialization or CDR: `driftlab import` checks the messages it carries unmapped against their schema, and the
// tests compare the walk with Foxglove's readers. Thread-safety: a parsed definition is immutable.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/result.h"
#include "formats/ros_messages.h"

namespace driftlab::formats {

struct RosField {
  enum class Array { kNone, kFixed, kSequence };
  std::string name;
  std::string type;      ///< a primitive ("float64", "string", "time") or, when complex, the index's type name
  int complex = -1;      ///< index into RosDefinition::types() for a message type; -1 for a primitive
  Array array = Array::kNone;
  uint32_t length = 0;   ///< kFixed: the element count; kSequence: its bound (0: unbounded)
};

struct RosType {
  std::string name;  ///< "sensor_msgs/LaserScan" (ROS 2's "/msg/" left out, as in MSG: lines)
  std::vector<RosField> fields;
};

class RosDefinition {
 public:
  /// Parses `text`, the definition of `type_name` ("sensor_msgs/msg/LaserScan" or "sensor_msgs/LaserScan") with its
  /// dependencies. ROS 1 and ROS 2 differ in their primitives (ROS 1: time, duration, Header, byte = int8; ROS 2:
  /// byte = uint8, bounded strings and sequences). Errors say which line and why ("line 3: type Foo is not
  /// defined").
  static Result<RosDefinition> parse(std::string_view type_name, std::string_view text, Serialization serialization);

  /// types()[0] is the message's own type.
  const std::vector<RosType>& types() const { return types_; }
  Serialization serialization() const { return serialization_; }

  /// Empty when payload holds a message of this type, else why not ("ends inside the message (12 bytes)").
  /// Bytes after the message are allowed, as CDR readers allow them (Foxglove's among them): a publisher with a
  /// newer definition may have added fields at the end.
  std::string check(std::span<const uint8_t> payload) const;
  /// The message as JSON (integers exact, floats as the double they hold, NaN and infinities as null, time as
  /// {"sec","nsec"} in ROS 1), or why it cannot be read.
  Result<std::string> to_json(std::span<const uint8_t> payload) const;

 private:
  std::vector<RosType> types_;
  Serialization serialization_ = Serialization::kCdr;
};

}  // namespace driftlab::formats
