// MCAP files (mcap.dev/spec, major version 0), read and written by driftlab's own code: no C++ MCAP library is
// packaged for Debian. The reader goes front to back through the data section without the summary, so a file
// cut short or never finished (no summary, no footer) reads like a whole one; chunks are uncompressed, zstd or lz4
// and are checked against their CRC, on threads of the reader's own (two chunks decompressed at once) a few chunks
// ahead of the callbacks; memory is bounded by a few chunks. Corruption goes to the problem callback with the file
// offset, and reading goes on at the next record that parses. The writer makes indexed files: chunks
// with message indexes, schemas and channels repeated in the summary, chunk indexes, statistics, metadata
// indexes, summary offsets, and the data-section and summary CRCs; it compresses and writes each closed chunk on
// threads of its own (two chunks compressed at once) while the next one fills (at most four chunks in memory).
// Thread-safety: one reader or writer per thread (each runs threads of its own inside, invisible to callers).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/mapped_file.h"
#include "core/result.h"

namespace driftlab::formats {

struct McapSchema {
  uint16_t id = 0;
  std::string name;      ///< "sensor_msgs/msg/LaserScan"
  std::string encoding;  ///< "ros2msg", "ros1msg", "jsonschema", ... ("" : no schema)
  std::string data;      ///< the definition
};

struct McapChannel {
  uint16_t id = 0;
  uint16_t schema_id = 0;  ///< 0: no schema
  std::string topic;
  std::string message_encoding;  ///< "cdr", "ros1", "json", ...
  std::vector<std::pair<std::string, std::string>> metadata;
  const McapSchema* schema = nullptr;  ///< nullptr for schema_id 0 (or a schema the file never defined)
};

struct McapMessage {
  const McapChannel* channel = nullptr;
  uint32_t sequence = 0;
  uint64_t log_time = 0;      ///< [ns] when the recorder received it
  uint64_t publish_time = 0;  ///< [ns]
  std::span<const uint8_t> data;
  uint64_t offset = 0;           ///< file offset of its record, or of the chunk holding it
  int64_t offset_in_chunk = -1;  ///< its record's offset in the chunk's uncompressed records; -1 outside chunks
};

/// A Metadata record: name and key/value pairs.
struct McapMetadata {
  std::string name;
  std::vector<std::pair<std::string, std::string>> entries;
};

/// Something unreadable: where (file offset) and what, in words.
struct McapProblem {
  uint64_t offset = 0;
  std::string what;
};

/// What the summary's Statistics record says (when the file has one).
struct McapStatistics {
  uint64_t message_count = 0;
  std::map<uint16_t, uint64_t> channel_message_counts;
};

class McapReader {
 public:
  static Result<McapReader> open(const std::string& path);
  /// A file in memory (bytes must outlive the reader): for fuzzing and tests.
  static Result<McapReader> from_memory(std::span<const uint8_t> bytes);
  /// Whether the bytes start with MCAP's magic.
  static bool looks_like(std::span<const uint8_t> head);

  McapReader(McapReader&&) noexcept;
  McapReader& operator=(McapReader&&) noexcept;
  ~McapReader();

  /// Calls on_message for every message of the data section in file order (its channel and schema are known
  /// before it), on_metadata for every Metadata record, and on_problem for every unreadable part; returns the
  /// number of messages delivered. Message data stays valid until on_message returns. The callbacks run on the
  /// calling thread, one at a time; pipelined (the default), chunks are read, decompressed and checked on threads
  /// of the reader's own meanwhile (two at once), at most four chunks ahead. What the callbacks see does not depend
  /// on it.
  int64_t read(const std::function<void(const McapMessage&)>& on_message,
               const std::function<void(const McapProblem&)>& on_problem,
               const std::function<void(const McapMetadata&)>& on_metadata = {});

  /// Whether read() decompresses and checks chunks on threads of its own (default true); false: all on the caller's.
  void set_pipelined(bool on);

  const std::string& profile() const { return profile_; }
  const std::string& library() const { return library_; }
  /// Statistics from the summary, when read() found one (a file cut short has none).
  const McapStatistics* statistics() const { return has_statistics_ ? &statistics_ : nullptr; }
  uint64_t size() const { return bytes_.size(); }

 private:
  McapReader();
  static Result<McapReader> check(const std::string& name, std::span<const uint8_t> bytes);
  struct Impl;
  std::unique_ptr<Impl> impl_;
  MappedFile file_;
  std::span<const uint8_t> bytes_;
  std::string profile_, library_;
  McapStatistics statistics_;
  bool has_statistics_ = false;
  bool pipelined_ = true;
};

enum class McapCompression { kNone, kZstd, kLz4 };

struct McapWriteOptions {
  std::string profile = "ros2";
  std::string library = "driftlab";
  McapCompression compression = McapCompression::kZstd;
  int level = 1;  ///< zstd level (1: fast, what live recorders use) or lz4's (0: fast)
  /// A chunk is closed once its uncompressed records reach this size [bytes] (rosbag2 and the mcap CLI use 768 KiB
  /// to 4 MiB); a larger message gets a chunk of its own.
  size_t chunk_bytes = 4 << 20;
  /// Write to PATH.partial and rename to PATH on close(), so no half-written file is ever seen under PATH.
  bool atomic = true;
};

class McapWriter {
 public:
  static Result<McapWriter> create(const std::string& path, McapWriteOptions options = {});
  McapWriter(McapWriter&&) noexcept;
  McapWriter& operator=(McapWriter&&) noexcept;
  ~McapWriter();

  /// Registers a schema; returns its id (1, 2, ...). Its record is written before the first message that uses it.
  uint16_t add_schema(std::string_view name, std::string_view encoding, std::string_view data);
  /// Registers a channel on schema_id (0: none); returns its id (0, 1, ...).
  uint16_t add_channel(uint16_t schema_id, std::string_view topic, std::string_view message_encoding,
                       const std::vector<std::pair<std::string, std::string>>& metadata = {});
  /// Appends a message. Times in ns. A failure to write an earlier chunk (on the writing thread) is returned
  /// here or by close(), naming the file.
  Status write(uint16_t channel_id, uint32_t sequence, uint64_t log_time, uint64_t publish_time,
               std::span<const uint8_t> data);
  /// As write(), the message's `size` bytes written in place by `fill` (given where they go; it must write all
  /// of them): a large message built straight into the chunk, without a copy.
  Status write(uint16_t channel_id, uint32_t sequence, uint64_t log_time, uint64_t publish_time, size_t size,
               const std::function<void(uint8_t*)>& fill);
  /// Adds a Metadata record (written between chunks; indexed in the summary).
  Status add_metadata(std::string_view name, const std::vector<std::pair<std::string, std::string>>& entries);
  /// Closes the last chunk, writes the summary and footer, and (atomic) renames into place. Idempotent.
  Status close();
  /// Closes and removes the partial file (atomic mode).
  void discard();

  uint64_t messages() const;
  /// Bytes written to the file so far (waits for the chunks handed to the writing thread to be written).
  uint64_t bytes() const;

 private:
  McapWriter();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace driftlab::formats
