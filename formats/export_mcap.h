// driftlab logs out as ROS 2 bags in MCAP storage, for Foxglove and `ros2 bag play`: driftlab's sensor, navigation
// and geometry types become the standard ROS 2 messages (CDR, ros2msg schemas with the exact standard definitions
// and their dependencies, as rosbag2 writes them); messages carried from another recording (foreign_message_t) go
// back out as they came, with their own schema; driftlab's other types (statistics, faults, comparisons) go out as
// CDR with a ros2msg schema made from their .lcm definition (package driftlab_msgs), which Foxglove decodes and
// plots like any ROS message. The event time is the MCAP log time, header.seq the MCAP sequence.
// Thread-safety: plain functions.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "core/result.h"
#include "formats/mcap.h"
#include "formats/ros2_schema.h"

namespace driftlab::formats {

struct McapExportOptions {
  McapCompression compression = McapCompression::kZstd;
  int level = 1;                  ///< zstd level: 1 is fast (rosbag2 records with its default, 1 too)
  size_t chunk_bytes = 4 << 20;   ///< uncompressed bytes per chunk
  /// Only channels fully matching this ECMAScript regex (as export csv's); empty: every channel.
  std::string channels;
  /// Extra Metadata records (name, key/value pairs), e.g. a diagnosis's findings.
  std::vector<McapMetadata> metadata;
};

struct ExportedTopic {
  std::string channel;        ///< the driftlab channel
  std::string topic;          ///< the ROS topic (the channel, or a valid ROS name made from it)
  std::string driftlab_type;  ///< "driftlab.laser_scan_t"
  std::string ros_type;       ///< "sensor_msgs/msg/LaserScan"
  std::string encoding;       ///< "cdr" (or the foreign message's own)
  int64_t messages = 0;
};

struct McapExportSummary {
  std::vector<ExportedTopic> topics;
  int64_t messages = 0;
  std::vector<std::pair<std::string, int64_t>> skipped;  ///< channels of types driftlab does not know, with counts
  int64_t start_ns = 0, end_ns = 0;                      ///< first and last log time written
  uint64_t bytes = 0;                                    ///< of the file
};

/// Writes log as the MCAP file out (atomically). Damaged spots of the log and messages that do not decode go to
/// on_problem (one line each); everything else is written. Errors name the file.
Result<McapExportSummary> export_mcap(const std::string& log, const std::string& out, const McapExportOptions& options,
                                      const std::function<void(const std::string&)>& on_problem);

/// What `driftlab export mcap|rosbag2` prints of an export: the messages and bytes written, a line per topic (its
/// driftlab and ROS types, its count, the channel it came from when renamed), the channels skipped.
std::string export_text(const McapExportSummary& s, const std::string& log, const std::string& out);

/// Writes log as a rosbag2 folder: folder/metadata.yaml and folder/NAME_0.mcap (NAME: the folder's name). The
/// folder must not exist yet or be empty; it is made beside as FOLDER.partial and renamed when whole.
Result<McapExportSummary> export_rosbag2(const std::string& log, const std::string& folder,
                                         const McapExportOptions& options,
                                         const std::function<void(const std::string&)>& on_problem);

}  // namespace driftlab::formats
