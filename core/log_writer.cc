#include "core/log_writer.h"

#include <fcntl.h>
#include <sys/uio.h>
#include <unistd.h>

#include <cerrno>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <mutex>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include "core/log_format.h"

namespace driftlab {
namespace {
constexpr size_t kPage = 4096;
/// Buffers a background writer may hold filled beside the one being filled.
constexpr size_t kBuffersInFlight = 3;

/// write(2) until done; returns 0 or errno. written counts what went through.
int write_all(int fd, const uint8_t* data, size_t size, uint64_t& written) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    data += n;
    size -= static_cast<size_t>(n);
    written += static_cast<uint64_t>(n);
  }
  return 0;
}

/// Where the complete events end after the first done bytes of a buffer written from file offset start reached the
/// file: its events from first_event on are walked by their headers (bytes before first_event end an event begun
/// earlier); committed when not even those bytes went through.
uint64_t complete_events(const uint8_t* buffer, size_t first_event, size_t done, uint64_t start, uint64_t committed) {
  if (done < first_event) return committed;
  size_t p = first_event;
  while (p + logfmt::kEventHeaderSize <= done) {
    const uint8_t* h = buffer + p;
    const size_t size = logfmt::kEventHeaderSize + logfmt::load_be32(h + 20) + logfmt::load_be32(h + 24);
    if (p + size > done) break;
    p += size;
  }
  return start + p;
}
}  // namespace

/// The thread of a background writer and the buffers it shares with the writer; on the heap, so the writer can move.
struct LogWriter::Background {
  struct Chunk {
    std::unique_ptr<uint8_t[]> data;
    size_t size = 0;
    size_t first_event = 0;  // as first_event_in_buffer_
    uint64_t start = 0;      // its file offset
    uint64_t committed = 0;  // where the complete events before it end
  };
  std::mutex mutex;
  std::condition_variable changed;
  std::deque<Chunk> filled;  // oldest first
  std::vector<std::unique_ptr<uint8_t[]>> free;
  bool busy = false;  // a chunk is being written
  bool stop = false;
  // The first failure: errno, the bytes in the file and where its complete events end. Nothing is written after it.
  int error = 0;
  uint64_t failed_at = 0, complete = 0;
  std::thread thread;

  void run(int fd) {
    std::unique_lock lock(mutex);
    for (;;) {
      changed.wait(lock, [&] { return stop || !filled.empty(); });
      if (filled.empty()) return;
      Chunk c = std::move(filled.front());
      filled.pop_front();
      busy = true;
      const bool skip = error != 0;
      lock.unlock();
      uint64_t written = c.start;
      const int err = skip ? 0 : write_all(fd, c.data.get(), c.size, written);
      lock.lock();
      if (err != 0) {
        error = err;
        failed_at = written;
        complete = complete_events(c.data.get(), c.first_event, written - c.start, c.start, c.committed);
      }
      free.push_back(std::move(c.data));
      busy = false;
      changed.notify_all();
    }
  }
};

Result<LogWriter> LogWriter::create(const std::string& path, WriteOptions options) {
  LogWriter w;
  w.path_ = path;
  w.atomic_ = options.atomic;
  w.file_path_ = options.atomic ? path + ".partial" : path;
  w.fd_ = ::open(w.file_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (w.fd_ < 0) return Error{w.file_path_ + ": cannot create log: " + std::strerror(errno), ErrorCode::kCannotWrite};
  w.buffer_capacity_ = std::max<size_t>(options.buffer_bytes, 4 * kPage);
  w.buffer_ = std::make_unique<uint8_t[]>(w.buffer_capacity_);
  if (options.background) {
    w.background_ = std::make_unique<Background>();
    for (size_t i = 0; i < kBuffersInFlight; ++i)
      w.background_->free.push_back(std::make_unique<uint8_t[]>(w.buffer_capacity_));
    try {
      w.background_->thread = std::thread([bg = w.background_.get(), fd = w.fd_] { bg->run(fd); });
    } catch (const std::system_error&) {  // no thread to be had: the writer makes its write(2) calls itself
      w.background_.reset();
    }
  }
  return w;
}

LogWriter::LogWriter(LogWriter&& other) noexcept { *this = std::move(other); }

LogWriter& LogWriter::operator=(LogWriter&& other) noexcept {
  if (this != &other) {
    (void)close();
    path_ = std::move(other.path_);
    file_path_ = std::move(other.file_path_);
    fd_ = std::exchange(other.fd_, -1);
    buffer_ = std::move(other.buffer_);
    buffered_ = std::exchange(other.buffered_, 0);
    first_event_in_buffer_ = other.first_event_in_buffer_;
    buffer_capacity_ = other.buffer_capacity_;
    committed_ = other.committed_;
    written_ = other.written_;
    events_ = other.events_;
    atomic_ = other.atomic_;
    error_ = std::move(other.error_);
    background_ = std::move(other.background_);
  }
  return *this;
}

LogWriter::~LogWriter() { (void)close(); }

Status LogWriter::fail(const std::string& what, int err, uint64_t complete) {
  committed_ = complete;
  error_ = file_path_ + ": " + what + " at byte " + std::to_string(written_) + ": " + std::strerror(err);
  // Cut a partially written event off, so the file ends with a complete event.
  if (fd_ >= 0 && ftruncate(fd_, static_cast<off_t>(committed_)) != 0) {
    error_ += " (and could not cut the file back to the last complete event)";
  }
  written_ = committed_;
  buffered_ = 0;
  return Error{error_, ErrorCode::kCannotWrite};
}

int LogWriter::write_raw(const uint8_t* data, size_t size) { return write_all(fd_, data, size, written_); }

Status LogWriter::hand_off() {
  if (buffered_ == 0) return {};
  Background& bg = *background_;
  std::unique_lock lock(bg.mutex);
  bg.changed.wait(lock, [&] { return !bg.free.empty() || bg.error != 0; });
  if (bg.error != 0) {
    lock.unlock();
    return drain();
  }
  bg.filled.push_back({std::move(buffer_), buffered_, first_event_in_buffer_, written_, committed_});
  buffer_ = std::move(bg.free.back());
  bg.free.pop_back();
  bg.changed.notify_all();
  written_ += buffered_;
  buffered_ = 0;
  first_event_in_buffer_ = 0;
  return {};
}

Status LogWriter::drain() {
  Background& bg = *background_;
  std::unique_lock lock(bg.mutex);
  if (buffered_ > 0 && bg.error == 0) {
    lock.unlock();
    if (auto st = hand_off(); !st) return st;
    lock.lock();
  }
  bg.changed.wait(lock, [&] { return (bg.filled.empty() && !bg.busy) || bg.error != 0; });
  if (bg.error != 0) {
    // What the thread still holds is never written: the file ends where the failed write left it.
    bg.changed.wait(lock, [&] { return !bg.busy; });
    written_ = bg.failed_at;
    return fail("write failed", bg.error, bg.complete);
  }
  committed_ = written_;
  return {};
}

void LogWriter::stop_background() {
  if (!background_) return;
  {
    std::lock_guard lock(background_->mutex);
    background_->stop = true;
  }
  background_->changed.notify_all();
  background_->thread.join();
  background_.reset();
}

Status LogWriter::write(int64_t utime, std::string_view channel, std::span<const uint8_t> data) {
  if (!error_.empty()) return Error{error_, ErrorCode::kCannotWrite};
  if (fd_ < 0) return Error{path_ + ": write after close"};
  if (channel.empty() || channel.size() > static_cast<size_t>(logfmt::kMaxWriteChannelLength)) {
    return Error{path_ + ": channel name must be 1.." + std::to_string(logfmt::kMaxWriteChannelLength) +
                 " bytes, got " + std::to_string(channel.size())};
  }
  if (data.size() > static_cast<size_t>(INT32_MAX)) {
    return Error{path_ + ": message of " + std::to_string(data.size()) + " bytes is too large for an LCM log"};
  }
  const size_t total = logfmt::kEventHeaderSize + channel.size() + data.size();
  uint8_t header[logfmt::kEventHeaderSize];
  logfmt::encode_event_header(header, events_, utime, static_cast<int32_t>(channel.size()),
                              static_cast<int32_t>(data.size()));
  const bool direct = total > buffer_capacity_ / 2;
  if (direct || buffered_ + total > buffer_capacity_) {
    // In background mode a large event waits for the thread: it goes to the file from the caller's memory.
    if (auto st = background_ && !direct ? hand_off() : flush(); !st) return st;
  }
  if (!direct) {
    uint8_t* out = buffer_.get() + buffered_;
    std::memcpy(out, header, sizeof(header));
    std::memcpy(out + sizeof(header), channel.data(), channel.size());
    if (!data.empty()) std::memcpy(out + sizeof(header) + channel.size(), data.data(), data.size());
    buffered_ += total;
  } else {
    // Large event: the payload goes from the caller's memory to the file, uncopied, in whole pages.
    // Header, channel and the first bytes of the payload up to a page boundary of the file go through the
    // buffer, as does the tail (so the kernel copies whole, aligned pages, as stdio does).
    const uint64_t at = written_ + sizeof(header) + channel.size();
    const size_t head = std::min<size_t>(data.size(), (kPage - at % kPage) % kPage);
    uint8_t* out = buffer_.get();
    std::memcpy(out, header, sizeof(header));
    std::memcpy(out + sizeof(header), channel.data(), channel.size());
    std::memcpy(out + sizeof(header) + channel.size(), data.data(), head);
    const size_t middle = (data.size() - head) / kPage * kPage;
    const size_t tail = data.size() - head - middle;
    if (const int err = write_raw(out, sizeof(header) + channel.size() + head); err != 0) {
      return fail("write failed", err, committed_);
    }
    if (const int err = write_raw(data.data() + head, middle); err != 0) return fail("write failed", err, committed_);
    std::memcpy(out, data.data() + head + middle, tail);
    buffered_ = tail;
    first_event_in_buffer_ = tail;  // the buffer starts with the end of this event
    if (tail == 0) committed_ = written_;  // it ended on a page boundary: already whole in the file
  }
  ++events_;
  return {};
}

Status LogWriter::flush() {
  if (!error_.empty()) return Error{error_, ErrorCode::kCannotWrite};
  if (fd_ < 0) return {};
  if (background_) return drain();
  if (buffered_ == 0) return {};
  const uint64_t start = written_;
  if (const int err = write_raw(buffer_.get(), buffered_); err != 0) {
    // Keep every event the kernel took whole: walk the event headers through the part that was written.
    return fail("write failed", err,
                complete_events(buffer_.get(), first_event_in_buffer_, written_ - start, start, committed_));
  }
  // The buffer only ever ends with a complete event.
  committed_ = written_;
  buffered_ = 0;
  first_event_in_buffer_ = 0;
  return {};
}

Status LogWriter::sync() {
  if (auto st = flush(); !st) return st;
  if (fd_ >= 0 && fdatasync(fd_) != 0) return fail("fdatasync failed", errno, committed_);
  return {};
}

Status LogWriter::close() {
  if (fd_ < 0) return error_.empty() ? Status{} : Status{Error{error_, ErrorCode::kCannotWrite}};
  Status st = flush();
  stop_background();
  if (::close(fd_) != 0 && st.ok())
    st = Error{file_path_ + ": close failed: " + std::strerror(errno), ErrorCode::kCannotWrite};
  fd_ = -1;
  if (!atomic_) return st;
  if (!st.ok() || !error_.empty()) {
    // A log cut short (a full disk) never replaces what PATH held: the partial file goes, PATH stays untouched.
    std::remove(file_path_.c_str());
    return st.ok() ? Status{Error{error_, ErrorCode::kCannotWrite}} : st;
  }
  if (std::rename(file_path_.c_str(), path_.c_str()) != 0) {
    st = Error{path_ + ": cannot rename " + file_path_ + " into place: " + std::strerror(errno),
               ErrorCode::kCannotWrite};
    std::remove(file_path_.c_str());
  }
  return st;
}

void LogWriter::discard() {
  if (fd_ < 0) return;
  stop_background();
  ::close(fd_);
  fd_ = -1;
  buffered_ = 0;
  if (atomic_) std::remove(file_path_.c_str());
}

}  // namespace driftlab
