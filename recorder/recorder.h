// Recorder: captures live LCM traffic (udpm) into LCM event logs without loss, and records where anything was
// lost. A receive thread drains the socket in batches (recvmmsg) into a bounded queue and never touches the disk;
// a writer thread writes, flushes and syncs. Loss of every kind is counted and written into the log itself, on
// the statistics channel, as driftlab.recorder_stats_t.
// Thread-safety: run() blocks; request_stop() may be called from any thread or a signal handler.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/result.h"
#include "core/wall_clock.h"

namespace driftlab::recorder {

struct RecordOptions {
  std::string url = "udpm://239.255.76.67:7667?ttl=0";
  std::string out;                   ///< log path; with splitting, parts are OUT_0000.lcm, OUT_0001.lcm, ...
  std::string channels = ".*";       ///< record channels fully matching this regex
  std::string exclude;               ///< ... except those fully matching this one (empty: none)
  double split_mb = 0;               ///< start a new file past this size [MB]; 0: never
  double split_s = 0;                ///< start a new file after this long [s]; 0: never
  double duration_s = 0;             ///< stop after this long [s]; 0: until stopped
  double flush_interval_s = 0.1;     ///< hand data to the disk (fdatasync) this often [s]
  double stats_interval_s = 1.0;     ///< write the statistics channel this often [s]
  std::string stats_channel = "DRIFTLAB_RECORDER_STATS";
  int64_t queue_max_bytes = int64_t{1} << 30;  ///< memory for messages waiting for the disk [bytes]
  int64_t socket_buffer_bytes = 64 << 20;      ///< kernel receive buffer [bytes]
  /// Called about once a second with a one-line status (for a TTY).
  std::function<void(const std::string&)> on_status;
  /// Called once the socket listens and the first file is open, before the first message is taken.
  std::function<void()> on_listening;
};

/// Checks what the user gave, before anything is opened: the URL and the channel regexes. Errors are one line
/// naming the option ("LCM URL 'bogus://': only udpm:// is supported", "invalid channel regex '[bad': ...").
Status check_options(const RecordOptions& options);

/// What a recording did, for the summary at the end.
struct RecordSummary {
  std::vector<std::string> files;
  int64_t received = 0, written = 0, filtered = 0, bytes_written = 0;
  int64_t lost = 0, gaps = 0, queue_dropped = 0, kernel_dropped = 0, fragments_incomplete = 0, garbage = 0;
  int64_t senders = 0;
  double seconds = 0;
};

/// What the recorder says once it listens: what, on which URL, into which file, until when.
std::string listening_line(const RecordOptions& options);
/// What `driftlab record` prints at the end: what was written where, what was received, what was lost and how.
std::string record_text(const RecordSummary& s);

class Recorder {
 public:
  /// `clock` (borrowed: it must outlive the recorder) stamps what the kernel did not (a message without a receive
  /// timestamp) and the statistics; it is read from the receive and the writer threads.
  Recorder(RecordOptions options, const WallClock& clock);
  /// Records until request_stop(), the duration, or an error. An error (socket, disk) is one line naming the
  /// file or address; everything written before it stays readable.
  Result<RecordSummary> run();
  void request_stop() { stop_.store(true); }

 private:
  RecordOptions options_;
  const WallClock& clock_;
  std::atomic<bool> stop_{false};
};

/// Where part `index` of a split recording goes: "run.lcm" -> "run_0003.lcm".
std::string split_path(const std::string& out, int index);

}  // namespace driftlab::recorder
