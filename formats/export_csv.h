// `driftlab export csv`: every channel of a log as a table, one CSV file per channel, for PlotJuggler and
// spreadsheets. Each message of a driftlab type is one row: its log time, then its fields flattened by
// lcmtypes/schema.h ("linear_velocity.x", "ranges[3]"). Thread-safety: one call per output folder.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/result.h"

namespace driftlab::formats {

struct CsvExportOptions {
  std::string log;          ///< an LCM log
  std::string out;          ///< the folder the files go into (made when absent)
  std::string channels;     ///< LogReader's channel filter: comma-separated names or patterns; empty: all
  size_t max_array = 1024;  ///< elements of an array written, at most, per message
  bool bytes = false;       ///< also write byte arrays (images), one column per byte
};

struct CsvExport {
  struct File {
    std::string channel, path;
    int64_t rows = 0;
  };
  std::vector<File> files;                                           ///< by channel name
  std::map<std::string, std::pair<int64_t, std::string>> malformed;  ///< channel -> skipped, the first's problem
  std::map<std::string, int64_t> unknown;  ///< channel -> messages of a type that is not driftlab's, skipped
  uint64_t problems = 0;                   ///< damaged spots of the log skipped
};

/// Writes OUT/CHANNEL.csv for every channel of a driftlab type, each first as CHANNEL.csv.partial and renamed when
/// the log has been read; on an error no .partial is left. Its columns are the union of its messages' fields, in
/// the order they first appear. Errors: the log (kBadInput), a file that cannot be written (kCannotWrite).
Result<CsvExport> export_csv(const CsvExportOptions& a);
/// What `driftlab export csv` prints of it: a line per file (channel, rows, path), per channel skipped (malformed
/// messages, with the first's problem; a type that is not driftlab's) and the log's damaged spots skipped.
std::string export_text(const CsvExport& e, const std::string& log);

/// A file name a person can read for a channel: leading '/'s dropped, bytes other than [A-Za-z0-9_.-] (and a
/// leading '.') made '_' ("/tf" -> "tf", "/camera/image_raw" -> "camera_image_raw", "" -> "channel"); names longer
/// than 200 bytes cut and given a hash of the whole name, within the file system's 255-byte limit. Two channels
/// that map to one name ("/a/b" and "a_b") are told apart by export_csv: the second is "NAME~HASH", HASH 16 hex
/// digits of the whole channel name (FNV-1a), deterministic in the order the channels come; names are compared
/// without case, as macOS and Windows do.
std::string channel_file_name(std::string_view channel);

}  // namespace driftlab::formats
