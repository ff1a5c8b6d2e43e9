// Other tools' recordings wherever a command takes a log: `driftlab diagnose run.mcap`, `driftlab eval --gt
// bag/:/ground_truth ...`. A ROS 1 or ROS 2 bag, a bag folder, an MCAP file or a CARMEN log (or the files of one
// split recording) is converted once (formats/import.h) into a cache beside it, as the log index is cached, and
// the conversion is reused while the files stay as they were (size, modification and change times, inode, and a
// digest of their head, tail and blocks between); each use says so on stderr. The key beside the conversion
// (CACHE.key) also records the conversion as written: a conversion or key that is a symbolic link, someone else's
// file, or not the file recorded (an output written over it) is made again. An LCM log, or anything that is not
// recognised as another format, is passed through unchanged.
// Thread-safety: plain functions; two processes converting the same file at once each write their own partial
// file (a name of its own, created exclusively) and the last rename wins (both hold the same log).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab::recordings {

/// In the errors of log_for() and the functions below when the conversion could not be written (a full disk, a
/// read-only folder): "INPUT: cannot write its conversion CACHE: why".
inline constexpr char kCannotWriteConversion[] = ": cannot write its conversion ";

/// Where the conversion of inputs is kept: beside the (first) file as FILE.dlimport.lcm (FOLDER.dlimport.lcm for a
/// bag folder, FIRST+N.dlimport.lcm for the N more files of a split recording); a name over 160 bytes is cut to
/// 100 and the hash of the whole appended (NAME~HASH.dlimport.lcm), so that the cache's files fit in 255.
std::string import_cache_path(const std::vector<std::string>& inputs);

/// The LCM log to read for inputs: inputs[0] itself for an LCM log (only one then), else the cached conversion,
/// made first when missing or stale. When the folder cannot be written, the cache goes under
/// $XDG_CACHE_HOME/driftlab (~/.cache/driftlab). Errors: one line naming the file (unknown format, nothing
/// readable, no place to write).
Result<std::string> log_for(const std::vector<std::string>& inputs);
inline Result<std::string> log_for(const std::string& input) { return log_for(std::vector<std::string>{input}); }

/// log_for(), then check_event_log() on the log it gives: for the commands that have nothing to do without an event
/// (every one but info, which describes an empty log). A file that is neither another tool's recording nor an LCM
/// log is "not an LCM event log".
Result<std::string> event_log_for(const std::vector<std::string>& inputs);
inline Result<std::string> event_log_for(const std::string& input) {
  return event_log_for(std::vector<std::string>{input});
}

/// A LOG:CHANNEL source (eval, export tum) whose LOG is another tool's recording: the same source with LOG
/// replaced by its conversion. Other sources (LCM logs, TUM files) come back unchanged.
Result<std::string> log_channel_for(const std::string& source);

/// A conversion's problems on stderr as they come: the first 20 a line each ("driftlab: LINE"), the rest counted and
/// said once by finish() ("driftlab: NAMED: N more problems").
class ProblemLines {
 public:
  explicit ProblemLines(std::string named) : named_(std::move(named)) {}
  void operator()(const std::string& line);
  void finish() const;
  int64_t count() const { return count_; }

 private:
  std::string named_;
  int64_t count_ = 0;
};

}  // namespace driftlab::recordings
