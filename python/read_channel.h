// A channel of an LCM log as columns, one per field of its messages (lcmtypes/schema.h's walk), for the Python
// module's Log.read: numbers kept as numbers in native byte order, ready to become NumPy arrays without a copy.
// Thread-safety: plain functions on their own data; run without the GIL.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/result.h"

namespace driftlab::python {

/// One field of a channel's messages: every message's elements, in message order.
struct Column {
  std::string name;                  ///< dotted path without indices: "header.utime", "ranges", "pose.position.x"
  char kind = 'f';                   ///< NumPy's kind: 'f' float, 'i' signed integer, 'u' byte, 'b' boolean, 'O' string
  size_t item_bytes = 8;             ///< bytes of one element (0 for strings)
  std::vector<size_t> dims;          ///< the field's fixed dimensions (empty: a scalar, or a variable-length array)
  std::vector<uint8_t> data;         ///< the elements, native byte order
  std::vector<std::string> strings;  ///< kind 'O'
  std::vector<int64_t> counts;       ///< elements of each message
};

struct Channel {
  std::string type;              ///< "driftlab.odometry_t"
  std::vector<int64_t> arrival;  ///< the log's receive time of each message [us]
  std::vector<Column> columns;   ///< in the order of the message's fields
  int64_t skipped = 0;           ///< messages of another type, or cut short, left out [count]
};

/// Reads every message of `channel` in the LCM log at `path`. `expected` (the index's count) sizes the columns.
/// Errors: the log cannot be read; a channel whose messages are of no driftlab type.
Result<Channel> read_channel(const std::string& path, const std::string& channel, int64_t expected);

/// Reads every message of each of `channels` (name, the index's count) in one pass over the log, in that order.
/// Errors: the log cannot be read; a channel whose messages are of no driftlab type.
Result<std::vector<Channel>> read_channels(const std::string& path,
                                           const std::vector<std::pair<std::string, int64_t>>& channels);

}  // namespace driftlab::python
