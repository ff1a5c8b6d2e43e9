// What every reader of another tool's recording hands its messages to (formats/import.h): a message of a ROS bag
// or MCAP file converted onto its driftlab type, or carried as a foreign message checked against its schema;
// the channels' sources described once; problems counted and reported. The readers of each format (ROS 1 bags,
// MCAP, rosbag2's sqlite3, CARMEN in importer.cc; ULog in import_ulog.cc) fill one Importer.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/log_writer.h"
#include "formats/compression.h"
#include "formats/import.h"
#include "formats/ros_definition.h"
#include "lcmtypes/seq_origin.h"

namespace driftlab::formats::internal {

/// Where the schemas of foreign messages go, once per channel before its first message.
inline constexpr char kSchemaChannel[] = "FOREIGN_SCHEMAS";

/// A string as an LCM message holds it: up to its first NUL (LCM encodes strings so).
std::string lcm_text(std::string_view v);

/// Where a message was met, for problem lines.
struct Where {
  enum Kind { kByte, kChunk, kRow } kind = kByte;
  uint64_t offset = 0;   ///< file offset (kByte, kChunk), or the row id (kRow)
  int64_t in_chunk = 0;  ///< kChunk: the record's offset in the chunk's records
  std::string text() const {
    switch (kind) {
      case kByte: return "at byte " + std::to_string(offset);
      case kChunk:
        return "at byte " + std::to_string(offset) + " (in the chunk there, byte " + std::to_string(in_chunk) +
               " of its records)";
      case kRow: return "at row " + std::to_string(offset);
    }
    return {};
  }
};

/// A message of a ROS bag or MCAP file, as every reader hands it on.
struct Incoming {
  std::string_view topic;
  std::string_view type;                 ///< as the file names it ("sensor_msgs/msg/LaserScan")
  std::string_view encoding;             ///< "ros1", "cdr", or another MCAP message encoding
  std::string_view definition;           ///< its schema text ("" when the file has none)
  std::string_view definition_encoding;  ///< "ros1msg", "ros2msg", "ros2idl", "jsonschema", ...
  int64_t arrival_us = 0;
  bool has_sequence = false;  ///< MCAP: a sequence number travels with it
  uint32_t sequence = 0;
  /// What an earlier import said of the channel (driftlab export keeps it in an MCAP channel's metadata): its type
  /// in the first recording, and where its seq came from.
  std::string_view source_type;
  std::optional<lcmtypes::SeqOrigin> seq_origin;
  std::span<const uint8_t> payload;
  Where where;
};

class Importer {
 public:
  Importer(LogWriter writer, std::function<void(const std::string&)> on_problem)
      : writer_(std::move(writer)), on_problem_(std::move(on_problem)) {}

  ImportSummary summary;
  std::string file;  ///< the file being read, for problem lines

  LogWriter& writer() { return writer_; }
  const Status& status() const { return status_; }

  /// A temporary file read in place of the user's (a zstd-compressed bag decompressed) and what problems call it.
  std::string temporary, temporary_named;

  void problem(const std::string& line) {
    ++summary.problems;
    on_problem_(named(line));
  }

  /// line with the temporary file, at its start, named as the user knows it: the temporary is gone when it is read.
  std::string named(const std::string& line) const {
    if (temporary.empty() || !line.starts_with(temporary)) return line;
    return temporary_named + line.substr(temporary.size());
  }

  TopicCount& topic(std::string_view channel, std::string_view source_type, const char* driftlab_type) {
    auto it = topic_index_.find(channel);
    if (it == topic_index_.end()) {
      it = topic_index_.emplace(std::string(channel), summary.topics.size()).first;
      summary.topics.push_back({std::string(channel), std::string(source_type), driftlab_type, 0, 0});
    }
    return summary.topics[it->second];
  }
  bool write(int64_t utime, std::string_view channel, std::span<const uint8_t> bytes) {
    if (!status_) return false;
    status_ = writer_.write(utime, channel, bytes);
    if (!status_) return false;
    ++summary.messages;
    return true;
  }
  /// Says what the recording knew of a channel that its messages do not (channel_source_t), once, before the
  /// channel's first message: from that message (an MCAP channel whose first sequence is 0 is taken as counted, as
  /// rosbag2 writes 0 for every message; one whose sequence starts later at 0 and then counts is taken so too).
  bool describe(int64_t utime, std::string_view channel, std::string_view source_type, lcmtypes::SeqOrigin origin);

  /// Converts one ROS message: a mapped type onto its driftlab type, any other carried as foreign_message_t after
  /// a check against its schema.
  void message(const Incoming& m);

 private:
  struct State {
    int64_t count = 0;
    bool sequences = false;
    uint32_t last_sequence = 0;
    int64_t sequence_high = 0;
    bool definition_checked = false;
    bool stamped = false;  // its definition starts with a std_msgs/Header: carried as stamped_foreign_message_t
    bool clock = false;    // rosgraph_msgs/Clock: carried stamped with its time
    bool schema_written = false;
    std::unique_ptr<RosDefinition> definition;
  };
  LogWriter writer_;
  std::function<void(const std::string&)> on_problem_;
  std::map<std::string, size_t, std::less<>> topic_index_;
  std::map<std::string, State, std::less<>> state_;
  std::set<std::string, std::less<>> sources_;  // the channels described
  Status status_;
  std::string error_;
  int64_t bad_topics_ = 0;
  Decompressor decompressor_;
  std::vector<uint8_t> unpacked_;
  std::vector<uint8_t> reuse_;  // the last large converted message's memory, for the next (convert_ros_message)
};

/// Each format's reader: the file's messages into `out`, going past what it can (each problem reported to `out`);
/// an error when the file cannot be read at all or the output cannot be written.
Status import_ros1(const std::string& path, Importer& out);
Status import_mcap(const std::string& path, Importer& out);
Status import_sqlite(const std::string& path, Importer& out);
Status import_carmen(const std::string& path, Importer& out);
Status import_ulog(const std::string& path, Importer& out);

}  // namespace driftlab::formats::internal
