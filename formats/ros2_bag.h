// ROS 2 bags (rosbag2): a folder with metadata.yaml and its storage files (sqlite3 `.db3` or `.mcap`, maybe
// split in several, maybe compressed whole with zstd as rosbag2's file compression writes them), and the sqlite3
// storage read with Debian's libsqlite3. MCAP storage is read by formats/mcap.h.
// Thread-safety: one reader per thread; the functions are plain.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab::formats {

struct Ros2TopicInfo {
  std::string name;
  std::string type;                  ///< "sensor_msgs/msg/LaserScan"
  std::string serialization_format;  ///< "cdr"
  std::string offered_qos_profiles;  ///< YAML text
  std::string type_description_hash;
  int64_t message_count = 0;
};

/// metadata.yaml (rosbag2_bagfile_information, versions 1 to 9).
struct Ros2BagMetadata {
  int version = 0;
  std::string storage_identifier;  ///< "sqlite3" or "mcap"
  std::vector<std::string> relative_file_paths;
  std::string compression_format;  ///< "" or "zstd"
  std::string compression_mode;    ///< "", "FILE" or "MESSAGE"
  int64_t message_count = 0;
  int64_t starting_time_ns = 0;
  int64_t duration_ns = 0;
  std::vector<Ros2TopicInfo> topics;
};

/// Reads folder/metadata.yaml. Errors name the file and the key.
Result<Ros2BagMetadata> read_ros2_metadata(const std::string& folder);

/// What a bag's storage file holds for one file of metadata.yaml's `files` list.
struct Ros2FileInfo {
  std::string path;  ///< relative to the bag folder
  int64_t starting_time_ns = 0;
  int64_t duration_ns = 0;
  int64_t message_count = 0;
};
/// metadata.yaml text for a bag, as rosbag2 writes it (version 8).
std::string ros2_metadata_yaml(const std::string& storage_identifier, const std::vector<Ros2TopicInfo>& topics,
                               const std::vector<Ros2FileInfo>& files);

/// One message of the sqlite3 storage.
struct Ros2DbMessage {
  const Ros2TopicInfo* topic = nullptr;
  int64_t timestamp_ns = 0;  ///< rosbag2's recv_timestamp: when the recorder received it [ns since the epoch]
  std::span<const uint8_t> data;
  int64_t row = 0;  ///< the messages table's id
};

struct Ros2DbProblem {
  int64_t row = 0;  ///< the messages table's id where it happened (0: not about one row)
  std::string what;
};

class SqliteBagReader {
 public:
  /// Opens a .db3 read-only. Errors name the file.
  static Result<SqliteBagReader> open(const std::string& path);
  /// A database image in memory (for fuzzing and tests).
  static Result<SqliteBagReader> from_memory(std::span<const uint8_t> bytes);
  /// Whether the bytes start like an SQLite 3 database.
  static bool looks_like(std::span<const uint8_t> head);

  SqliteBagReader(SqliteBagReader&&) noexcept;
  SqliteBagReader& operator=(SqliteBagReader&&) noexcept;
  ~SqliteBagReader();

  /// Calls on_message for every message in the order rosbag2 wrote them (by id, as they arrived), and on_problem
  /// for every row or part that cannot be read; returns the number delivered. Definitions come from the
  /// message_definitions table (rosbag2 Iron and later); older bags have none.
  int64_t read(const std::function<void(const Ros2DbMessage&)>& on_message,
               const std::function<void(const Ros2DbProblem&)>& on_problem);

  /// Topics by id, from the topics table.
  const std::map<int64_t, Ros2TopicInfo>& topics() const { return topics_; }
  /// Message definitions by type ("sensor_msgs/msg/LaserScan"): encoding ("ros2msg") and text.
  const std::map<std::string, std::pair<std::string, std::string>>& definitions() const { return definitions_; }

 private:
  SqliteBagReader();
  Status load_tables();
  struct Db;
  std::unique_ptr<Db> db_;
  std::string name_;
  std::string note_;  // a problem met when opening (a cut file), reported by read()
  std::map<int64_t, Ros2TopicInfo> topics_;
  std::map<std::string, std::pair<std::string, std::string>> definitions_;
};

/// Whether bytes start with a zstd frame (rosbag2's compressed files and messages).
bool looks_like_zstd(std::span<const uint8_t> head);

/// Decompresses the zstd file in into out (written beside, then renamed), streaming: memory stays bounded.
Status decompress_zstd_file(const std::string& in, const std::string& out);

}  // namespace driftlab::formats
