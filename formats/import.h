// Other people's logs into driftlab logs: the format is recognised from the content (never the extension) and
// every message becomes a log event, stamped the way driftlab's time model wants: the message's own stamp
// (header.stamp, ipc_timestamp, a ULog message's timestamp_sample) in header.utime, its arrival at the recorder
// (ROS 1 record time, rosbag2's recv_timestamp, MCAP's log_time, CARMEN's logger_timestamp, a ULog message's
// timestamp) as the event time. Topics keep their names as
// channels ("/scan"); messages of types without a mapping are carried as driftlab.foreign_message_t with their
// definition on FOREIGN_SCHEMAS (as driftlab.stamped_foreign_message_t, their header read out, when the definition
// starts with a std_msgs/Header, so that every stamped message gets the timing analysis). A recording split into
// several files is one recording: give its folder (ROS 2) or all of its files. Thread-safety: plain functions.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab::formats {

enum class Format {
  kUnknown,
  kLcmLog,
  kRos1Bag,
  kCarmen,
  kMrptRawlog,
  kMcap,        ///< an MCAP file (a ROS 2 bag's storage, or any MCAP of ROS 1 or ROS 2 messages)
  kRos2Sqlite,  ///< rosbag2's sqlite3 storage (.db3)
  kRos2Folder,  ///< a rosbag2 folder: metadata.yaml and its storage files
  kZstd,        ///< a file compressed whole with zstd (rosbag2's file compression): decompressed, then read
  kUlog,        ///< a PX4 flight log (ULog, .ulg)
};

/// What the file holds, from its first bytes; `description` says what an unknown file looks like in words
/// ("text starting \"hello\"", "gzip data that is not a CARMEN log", "an empty file").
struct Detected {
  Format format = Format::kUnknown;
  std::string name;         ///< "ROS 1 bag", "CARMEN log", ...
  std::string description;  ///< for kUnknown
};
Detected detect_format(const std::string& path);
/// Whether driftlab reads this format by converting it (everything but LCM logs, and MRPT rawlogs, which
/// `driftlab import rawlog` reads).
bool is_importable(Format f);

struct TopicCount {
  std::string channel;
  std::string source_type;    ///< the type in the source file ("sensor_msgs/LaserScan", "FLASER")
  std::string driftlab_type;  ///< "driftlab.laser_scan_t", or "driftlab.foreign_message_t" (or
                              ///< stamped_foreign_message_t) when not mapped
  int64_t messages = 0;       ///< written
  int64_t malformed = 0;      ///< not written: the payload does not hold a message of its type
};

struct ImportSummary {
  std::string format;  ///< Detected::name (with the number of files when there are several)
  std::vector<TopicCount> topics;
  std::vector<std::pair<std::string, int64_t>> skipped;  ///< CARMEN lines without a driftlab type, by name
  int64_t messages = 0;  ///< events written
  int64_t problems = 0;  ///< unreadable parts and malformed messages, each reported through on_problem
};

/// Converts in into the LCM log out (written atomically). Unreadable parts and malformed messages go, one line
/// each naming the file, the topic and the offset or line, to on_problem; everything intact is converted. An
/// Error only when nothing can be converted (unknown format, unreadable file, output not writable).
Result<ImportSummary> import_log(const std::string& in, const std::string& out,
                                 const std::function<void(const std::string&)>& on_problem);
/// The files of one recording (the parts of a split bag, given in any order: they are read in the natural
/// order of their names, "b_2" before "b_10"), or one bag folder, into one log.
Result<ImportSummary> import_log(const std::vector<std::string>& inputs, const std::string& out,
                                 const std::function<void(const std::string&)>& on_problem);

/// What `driftlab import` prints of a conversion: the messages written, a line per channel (its source type, its
/// driftlab type, its count, malformed messages left out, a type carried as recorded), the lines skipped.
std::string import_text(const ImportSummary& s, const std::string& from, const std::string& to);

/// The files of a recording given as inputs, in reading order: a ROS 2 bag folder gives its storage files (from
/// metadata.yaml, else the .mcap and .db3 files in it), files are sorted naturally. For cache keys.
std::vector<std::string> recording_files(const std::vector<std::string>& inputs);

}  // namespace driftlab::formats
