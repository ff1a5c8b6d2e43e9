#include "core/log_writer.h"

#include <fcntl.h>
#include <sys/uio.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>

#include "core/log_format.h"

namespace driftlab {
namespace {
constexpr size_t kPage = 4096;
}  // namespace

Result<LogWriter> LogWriter::create(const std::string& path, WriteOptions options) {
  LogWriter w;
  w.path_ = path;
  w.atomic_ = options.atomic;
  w.file_path_ = options.atomic ? path + ".partial" : path;
  w.fd_ = ::open(w.file_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (w.fd_ < 0) return Error{w.file_path_ + ": cannot create log: " + std::strerror(errno), ErrorCode::kCannotWrite};
  w.buffer_capacity_ = std::max<size_t>(options.buffer_bytes, 4 * kPage);
  w.buffer_ = std::make_unique<uint8_t[]>(w.buffer_capacity_);
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

int LogWriter::write_raw(const uint8_t* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd_, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    data += n;
    size -= static_cast<size_t>(n);
    written_ += static_cast<uint64_t>(n);
  }
  return 0;
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
    if (auto st = flush(); !st) return st;
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
  if (fd_ < 0 || buffered_ == 0) return {};
  const uint64_t start = written_;
  if (const int err = write_raw(buffer_.get(), buffered_); err != 0) {
    // Keep every event the kernel took whole: walk the event headers through the part that was written.
    const size_t done = written_ - start;
    uint64_t complete = committed_;
    size_t p = first_event_in_buffer_;
    if (done >= p) {
      complete = start + p;
      while (p + logfmt::kEventHeaderSize <= done) {
        const uint8_t* h = buffer_.get() + p;
        const size_t size = logfmt::kEventHeaderSize + logfmt::load_be32(h + 20) + logfmt::load_be32(h + 24);
        if (p + size > done) break;
        p += size;
        complete = start + p;
      }
    }
    return fail("write failed", err, complete);
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
  ::close(fd_);
  fd_ = -1;
  buffered_ = 0;
  if (atomic_) std::remove(file_path_.c_str());
}

}  // namespace driftlab
