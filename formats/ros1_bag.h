// ROS 1 bags (format 2.0): connections and messages, read front to back without the index, so a bag that was
// never closed (`.bag.active`, no index, as `rosbag reindex` would need) reads like a finished one. Chunks are
// uncompressed, bz2 or lz4 (roslz4 writes LZ4 frames); compressed ones are decompressed a few ahead on threads of
// the reader's own (two at once). Memory is bounded by a few chunks, not by the file.
// Corruption goes to the problem callback with the file offset, and reading goes on at the next record that
// parses. Thread-safety: one reader per thread.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>

#include "core/mapped_file.h"
#include "core/result.h"

namespace driftlab::formats {

/// A topic's connection: what rosbag stores in its connection records (the publisher's connection header).
struct RosConnection {
  uint32_t id = 0;
  std::string topic;
  std::string type;        ///< "sensor_msgs/LaserScan"
  std::string md5sum;
  std::string definition;  ///< the full message definition (gendeps text)
  std::string callerid;
  bool latching = false;
};

struct BagMessage {
  const RosConnection* connection = nullptr;
  int64_t record_time_ns = 0;  ///< when rosbag received it [ns since the epoch, recorder clock]
  std::span<const uint8_t> data;
  uint64_t offset = 0;  ///< file offset of its record, or of its chunk for a message inside a chunk
};

/// Something unreadable: where (file offset) and what, in words.
struct BagProblem {
  uint64_t offset = 0;
  std::string what;
};

class Ros1BagReader {
 public:
  /// Opens path and checks the "#ROSBAG V2.0" magic (another version is an error naming it).
  static Result<Ros1BagReader> open(const std::string& path);
  /// A bag in memory (bytes must outlive the reader): for fuzzing and tests.
  static Result<Ros1BagReader> from_memory(std::span<const uint8_t> bytes);
  /// Whether the bytes start like a ROS 1 bag.
  static bool looks_like(std::span<const uint8_t> head);

  /// Calls on_message for every message in file order (a connection is known before its first message) and
  /// on_problem for every unreadable part; returns the number of messages delivered.
  int64_t read(const std::function<void(const BagMessage&)>& on_message,
               const std::function<void(const BagProblem&)>& on_problem);

  /// Whether read() decompresses the chunks ahead on threads of its own (default true); false: each on the
  /// caller's thread when it comes to it. What the callbacks see does not depend on it.
  void set_pipelined(bool on) { pipelined_ = on; }

  const std::map<uint32_t, RosConnection>& connections() const { return connections_; }
  uint64_t size() const { return bytes_.size(); }

 private:
  Ros1BagReader() = default;
  static Result<Ros1BagReader> check(const std::string& name, std::span<const uint8_t> bytes);
  MappedFile file_;  // unmapped for a bag in memory
  std::span<const uint8_t> bytes_;
  std::map<uint32_t, RosConnection> connections_;
  bool pipelined_ = true;
};

}  // namespace driftlab::formats
