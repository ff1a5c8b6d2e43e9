// LogWriter: writes LCM event logs, readable by every LCM tool.
// Events are batched in a buffer and written with few system calls; large payloads go straight from the
// caller's memory to the file. On a write error (full disk) the file is cut back to the last complete
// event, so everything written before stays readable. Thread-safety: one writer per thread.
// With WriteOptions::background a thread of the writer's own makes the write(2) calls: a full buffer is handed to
// it and filling goes on in another, so the kernel's copy into the file overlaps the caller's work. A write error is
// then returned by a later write(), flush() or close(), with the same cut back to the last complete event.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "core/result.h"

namespace driftlab {

struct WriteOptions {
  /// Size of the write buffer [bytes].
  size_t buffer_bytes = 1 << 20;
  /// Write to PATH.partial and rename to PATH on close(), so no half-written log is ever seen under PATH. After a
  /// write error close() removes the partial file and leaves PATH as it was.
  bool atomic = false;
  /// Write on a thread of the writer's own (see above): for a converter that makes events as fast as the kernel
  /// takes them.
  bool background = false;
};

class LogWriter {
 public:
  /// Creates (or truncates) path. Errors name the file.
  static Result<LogWriter> create(const std::string& path, WriteOptions options = {});

  LogWriter(LogWriter&& other) noexcept;
  LogWriter& operator=(LogWriter&& other) noexcept;
  LogWriter(const LogWriter&) = delete;
  LogWriter& operator=(const LogWriter&) = delete;
  /// Closes (and, when atomic, commits) the log; use close() to see errors.
  ~LogWriter();

  /// Appends one event with the next event number (from 0). utime is the log timestamp [us].
  /// channel must be 1..255 bytes.
  Status write(int64_t utime, std::string_view channel, std::span<const uint8_t> data);
  Status write(int64_t utime, std::string_view channel, std::string_view data) {
    return write(utime, channel, {reinterpret_cast<const uint8_t*>(data.data()), data.size()});
  }
  /// Hands buffered events to the kernel.
  Status flush();
  /// flush() and fdatasync(): the events survive a power cut.
  Status sync();
  /// Flushes, closes and (atomic) renames into place. Idempotent.
  Status close();
  /// Atomic mode: closes and removes the partial file; otherwise like close().
  void discard();

  const std::string& path() const { return path_; }
  int64_t events() const { return events_; }
  /// Bytes of log written so far, buffered ones included.
  uint64_t bytes() const { return written_ + buffered_; }

 private:
  LogWriter() = default;
  /// Records a write error; cuts the file back to complete (the end of the last complete event).
  Status fail(const std::string& what, int err, uint64_t complete);
  /// write(2) until done; returns 0 or errno (written_ counts what went through).
  int write_raw(const uint8_t* data, size_t size);
  /// Background mode: hands the buffer to the thread and takes a free one.
  Status hand_off();
  /// Background mode: hands the buffer off and waits until the thread has written everything.
  Status drain();
  /// Background mode: stops the thread (after it has written what it holds).
  void stop_background();

  struct Background;

  std::string path_;
  std::string file_path_;  // path_, or path_ + ".partial"
  int fd_ = -1;
  std::unique_ptr<uint8_t[]> buffer_;
  size_t buffered_ = 0;
  size_t first_event_in_buffer_ = 0;  // bytes before it end an event written around the buffer
  size_t buffer_capacity_ = 0;
  uint64_t written_ = 0;    // bytes in the file
  uint64_t committed_ = 0;  // bytes of complete events in the file
  int64_t events_ = 0;
  bool atomic_ = false;
  std::string error_;  // sticky after a failure
  std::unique_ptr<Background> background_;  // background mode; written_ then counts bytes handed to the thread
};

}  // namespace driftlab
