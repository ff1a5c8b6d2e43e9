#include "recorder/recorder.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <condition_variable>
#include <cstring>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <regex>
#include <thread>
#include <unordered_map>

#include "core/log_writer.h"
#include "core/number_text.h"
#include "core/string_hash.h"
#include "driftlab/recorder_stats_t.hpp"
#include "recorder/lcm_udpm.h"

namespace driftlab::recorder {
namespace {

/// Messages waiting for the writer, packed: channel and data bytes back to back, plus where each message is.
struct Chunk {
  static constexpr size_t kTargetBytes = 4 << 20;
  struct Record {
    int64_t utime;
    size_t channel_offset, channel_size, data_offset, data_size;
  };
  std::vector<uint8_t> bytes;
  std::vector<Record> records;

  void add(int64_t utime, std::string_view channel, std::span<const uint8_t> data) {
    const size_t at = bytes.size();
    bytes.insert(bytes.end(), channel.begin(), channel.end());
    bytes.insert(bytes.end(), data.begin(), data.end());
    records.push_back({utime, at, channel.size(), at + channel.size(), data.size()});
  }
  void clear() {
    bytes.clear();
    records.clear();
  }
};

/// A queue of chunks bounded by bytes, with a free list so buffers are reused, not reallocated.
class ChunkQueue {
 public:
  explicit ChunkQueue(int64_t max_bytes) : max_bytes_(max_bytes) {}

  /// Whether n more bytes fit (an estimate: only the receiver adds).
  bool has_room(int64_t n) const { return bytes_.load(std::memory_order_relaxed) + n <= max_bytes_; }
  int64_t bytes() const { return bytes_.load(std::memory_order_relaxed); }

  void push(std::unique_ptr<Chunk> c) {
    {
      std::lock_guard lock(mutex_);
      bytes_ += static_cast<int64_t>(c->bytes.size());
      full_.push_back(std::move(c));
    }
    cv_.notify_one();
  }
  /// The next chunk, or null after the timeout or when closed and drained.
  std::unique_ptr<Chunk> pop(double timeout_s) {
    std::unique_lock lock(mutex_);
    cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), [&] { return !full_.empty() || closed_; });
    if (full_.empty()) return nullptr;
    auto c = std::move(full_.front());
    full_.pop_front();
    bytes_ -= static_cast<int64_t>(c->bytes.size());
    return c;
  }
  std::unique_ptr<Chunk> take_free() {
    std::lock_guard lock(mutex_);
    if (free_.empty()) {
      auto c = std::make_unique<Chunk>();
      c->bytes.reserve(Chunk::kTargetBytes);
      return c;
    }
    auto c = std::move(free_.back());
    free_.pop_back();
    return c;
  }
  void recycle(std::unique_ptr<Chunk> c) {
    c->clear();
    std::lock_guard lock(mutex_);
    if (free_.size() < 64 && c->bytes.capacity() <= 4 * Chunk::kTargetBytes) free_.push_back(std::move(c));
  }
  void close() {
    {
      std::lock_guard lock(mutex_);
      closed_ = true;
    }
    cv_.notify_all();
  }
  bool drained() {
    std::lock_guard lock(mutex_);
    return closed_ && full_.empty();
  }

 private:
  const int64_t max_bytes_;
  std::atomic<int64_t> bytes_{0};
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::unique_ptr<Chunk>> full_;
  std::vector<std::unique_ptr<Chunk>> free_;
  bool closed_ = false;
};

struct ChannelCounters {
  int64_t messages = 0, bytes = 0, last_utime = 0;
};

/// The receiver's counters, copied out for the writer about ten times a second.
struct Counters {
  std::map<uint64_t, SenderCounters> senders;
  std::map<std::string, ChannelCounters, std::less<>> channels;
  int64_t received = 0, filtered = 0, queue_dropped = 0, kernel_dropped = 0, garbage = 0, queue_bytes_max = 0;
};

std::string sender_name(uint64_t key) {
  in_addr a{};
  a.s_addr = htonl(static_cast<uint32_t>(key >> 16));
  char ip[INET_ADDRSTRLEN];
  inet_ntop(AF_INET, &a, ip, sizeof(ip));
  return std::string(ip) + ":" + std::to_string(key & 0xffff);
}

/// A multicast socket joined to the URL's group, with a large receive buffer, kernel drop counts and
/// kernel receive timestamps.
Result<int> open_socket(const UdpmUrl& url, const std::string& url_text, int64_t buffer_bytes) {
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return Error{url_text + ": cannot create a UDP socket: " + std::strerror(errno)};
  auto fail = [&](const std::string& what) {
    const int err = errno;
    ::close(fd);
    return Error{url_text + ": " + what + ": " + std::strerror(err)};
  };
  const int one = 1;
  if (setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one)) != 0) return fail("SO_REUSEADDR");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_ANY);
  addr.sin_port = htons(url.port);
  if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
    return fail("cannot bind UDP port " + std::to_string(url.port));
  }
  ip_mreq mreq{};
  inet_pton(AF_INET, url.group.c_str(), &mreq.imr_multiaddr);
  mreq.imr_interface.s_addr = htonl(INADDR_ANY);
  if (setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &mreq, sizeof(mreq)) != 0) {
    return fail("cannot join multicast group " + url.group + " (is there a route for 224.0.0.0/4?)");
  }
  // SO_RCVBUFFORCE passes net.core.rmem_max when privileged; otherwise take what the kernel allows.
  const int size = static_cast<int>(std::min<int64_t>(buffer_bytes, INT32_MAX / 2));
  if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &size, sizeof(size)) != 0) {
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &size, sizeof(size));
  }
  setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof(one));
  setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof(one));
  return fd;
}

class Session {
 public:
  Session(const RecordOptions& o, const WallClock& clock, std::atomic<bool>& stop, int fd)
      : o_(o), clock_(clock), stop_(stop), fd_(fd), queue_(o.queue_max_bytes) {}

  Status compile_filters() {
    try {
      include_.emplace(o_.channels, std::regex::ECMAScript | std::regex::optimize);
      if (!o_.exclude.empty()) exclude_.emplace(o_.exclude, std::regex::ECMAScript | std::regex::optimize);
    } catch (const std::regex_error& e) {
      return Error{"invalid channel regex: " + std::string(e.what())};
    }
    return {};
  }

  Status open_part() {
    const std::string path = splitting() ? split_path(o_.out, static_cast<int>(summary_.files.size())) : o_.out;
    auto w = LogWriter::create(path, {.buffer_bytes = 4 << 20});
    if (!w) return w.error();
    writer_.emplace(std::move(*w));
    summary_.files.push_back(path);
    part_start_.restart();
    return {};
  }

  Result<RecordSummary> run() {
    start_.restart();
    std::thread receiver([this] { receive(); });
    const Status written = write();
    stop_.store(true);
    receiver.join();
    if (!written.ok()) return written.error();
    summary_.seconds = start_.seconds();
    return summary_;
  }

 private:
  bool splitting() const { return o_.split_mb > 0 || o_.split_s > 0; }

  bool accept(std::string_view channel) {
    auto it = decisions_.find(channel);
    if (it == decisions_.end()) {
      const bool ok = std::regex_match(channel.begin(), channel.end(), *include_) &&
                      !(exclude_ && std::regex_match(channel.begin(), channel.end(), *exclude_));
      it = decisions_.emplace(std::string(channel), ok).first;
    }
    return it->second;
  }

  void publish(const LcmReassembler& reassembler) {
    std::lock_guard lock(counters_mutex_);
    shared_ = local_;
    shared_.senders = reassembler.senders();
    shared_.garbage = reassembler.garbage();
  }

  /// The receive thread: socket -> reassembly -> filters -> queue. Never blocks on the disk.
  void receive() {
    constexpr int kBatch = 64;
    constexpr size_t kDatagram = 65536;
    std::vector<uint8_t> buffers(kBatch * kDatagram);
    mmsghdr msgs[kBatch];
    iovec iovs[kBatch];
    sockaddr_in from[kBatch];
    alignas(cmsghdr) char control[kBatch][256];
    LcmReassembler reassembler;
    auto chunk = queue_.take_free();
    Stopwatch since_push, since_publish;
    for (;;) {
      // On stop, one last pass takes what the kernel already holds, then the loop ends.
      const bool stopping = stop_.load(std::memory_order_relaxed);
      if (!stopping) {
        pollfd pfd{fd_, POLLIN, 0};
        poll(&pfd, 1, 20);
      }
      for (;;) {
        for (int i = 0; i < kBatch; ++i) {
          iovs[i] = {buffers.data() + i * kDatagram, kDatagram};
          msgs[i].msg_hdr = {&from[i], sizeof(from[i]), &iovs[i], 1, control[i], sizeof(control[i]), 0};
        }
        const int n = recvmmsg(fd_, msgs, kBatch, MSG_DONTWAIT, nullptr);
        if (n <= 0) break;
        for (int i = 0; i < n; ++i) {
          int64_t utime = 0;
          for (cmsghdr* c = CMSG_FIRSTHDR(&msgs[i].msg_hdr); c != nullptr; c = CMSG_NXTHDR(&msgs[i].msg_hdr, c)) {
            if (c->cmsg_level != SOL_SOCKET) continue;
            if (c->cmsg_type == SCM_TIMESTAMPNS) {
              timespec ts;
              std::memcpy(&ts, CMSG_DATA(c), sizeof(ts));
              utime = static_cast<int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
            } else if (c->cmsg_type == SO_RXQ_OVFL) {
              uint32_t dropped;
              std::memcpy(&dropped, CMSG_DATA(c), sizeof(dropped));
              local_.kernel_dropped = dropped;
            }
          }
          if (utime == 0) utime = clock_.now().us();
          const uint64_t sender = (uint64_t{ntohl(from[i].sin_addr.s_addr)} << 16) | ntohs(from[i].sin_port);
          const auto m = reassembler.feed(sender, {buffers.data() + i * kDatagram, msgs[i].msg_len}, utime);
          if (!m) continue;
          ++local_.received;
          auto ch = local_.channels.find(m->channel);
          if (ch == local_.channels.end()) ch = local_.channels.emplace(std::string(m->channel), ChannelCounters{}).first;
          ++ch->second.messages;
          ch->second.bytes += static_cast<int64_t>(m->data.size());
          ch->second.last_utime = m->utime;
          if (!accept(m->channel)) {
            ++local_.filtered;
            continue;
          }
          const int64_t size = static_cast<int64_t>(m->channel.size() + m->data.size());
          if (!queue_.has_room(static_cast<int64_t>(chunk->bytes.size()) + size)) {
            ++local_.queue_dropped;
            continue;
          }
          chunk->add(m->utime, m->channel, m->data);
          if (chunk->bytes.size() >= Chunk::kTargetBytes) {
            queue_.push(std::move(chunk));
            chunk = queue_.take_free();
            since_push.restart();
          }
        }
      }
      local_.queue_bytes_max = std::max(local_.queue_bytes_max, queue_.bytes());
      if (!chunk->records.empty() && since_push.seconds() >= 0.01) {
        queue_.push(std::move(chunk));
        chunk = queue_.take_free();
        since_push.restart();
      }
      if (since_publish.seconds() >= 0.1) {
        publish(reassembler);
        since_publish.restart();
      }
      if (stopping) break;
    }
    if (!chunk->records.empty()) queue_.push(std::move(chunk));
    publish(reassembler);
    queue_.close();
  }

  Status write_stats() {
    Counters c;
    {
      std::lock_guard lock(counters_mutex_);
      c = shared_;
    }
    driftlab::recorder_stats_t s{};
    s.header.seq = stats_seq_++;
    s.header.utime = clock_.now().us();
    s.header.frame_id = "";
    s.received = c.received;
    s.written = summary_.written;
    s.filtered = c.filtered;
    s.bytes_written = summary_.bytes_written + static_cast<int64_t>(writer_->bytes());
    s.queue_dropped = c.queue_dropped;
    s.kernel_dropped = c.kernel_dropped;
    s.garbage_datagrams = c.garbage;
    s.queue_bytes_max = c.queue_bytes_max;
    for (const auto& [key, sc] : c.senders) {
      driftlab::sender_stats_t out{};
      out.sender = sender_name(key);
      out.messages = sc.messages;
      out.bytes = sc.bytes;
      out.lost = sc.lost;
      out.gaps = sc.gaps;
      out.out_of_order = sc.out_of_order;
      out.fragments_incomplete = sc.fragments_incomplete;
      out.last_utime = sc.last_utime;
      s.lost += sc.lost;
      s.fragments_incomplete += sc.fragments_incomplete;
      s.senders.push_back(out);
    }
    s.nsenders = static_cast<int32_t>(s.senders.size());
    for (const auto& [name, cc] : c.channels) {
      s.channels.push_back({name, cc.messages, cc.bytes, cc.last_utime});
    }
    s.nchannels = static_cast<int32_t>(s.channels.size());
    std::vector<uint8_t> buf(static_cast<size_t>(s.getEncodedSize()));
    s.encode(buf.data(), 0, static_cast<int>(buf.size()));
    last_counters_ = std::move(c);
    last_stats_ = s;
    return writer_->write(s.header.utime, o_.stats_channel, buf);
  }

  /// The writer: queue -> log, with periodic sync, statistics and splitting. Runs on the calling thread.
  Status write() {
    Stopwatch since_sync, since_stats, since_status;
    Status failure;
    for (;;) {
      if (o_.duration_s > 0 && start_.seconds() >= o_.duration_s) stop_.store(true);
      auto chunk = queue_.pop(std::min(o_.flush_interval_s, 0.05));
      if (chunk) {
        for (const auto& r : chunk->records) {
          const std::string_view channel(reinterpret_cast<const char*>(chunk->bytes.data() + r.channel_offset),
                                         r.channel_size);
          failure = writer_->write(r.utime, channel, {chunk->bytes.data() + r.data_offset, r.data_size});
          if (!failure.ok()) break;
          ++summary_.written;
          // Checked after every message, not every chunk: a writer that fell behind pops chunks of many
          // megabytes, and a part must still end near its size.
          if (failure = maybe_split(); !failure.ok()) break;
        }
        queue_.recycle(std::move(chunk));
        if (!failure.ok()) break;
      }
      if (since_sync.seconds() >= o_.flush_interval_s) {
        if (failure = writer_->sync(); !failure.ok()) break;
        since_sync.restart();
      }
      if (since_stats.seconds() >= o_.stats_interval_s) {
        if (failure = write_stats(); !failure.ok()) break;
        since_stats.restart();
      }
      if (o_.on_status && since_status.seconds() >= 1.0) {
        o_.on_status(status_line());
        since_status.restart();
      }
      if (!chunk && queue_.drained()) break;
    }
    if (failure.ok()) failure = write_stats();
    summary_.bytes_written += static_cast<int64_t>(writer_->bytes());
    const Status closed = writer_->close();
    if (failure.ok()) failure = closed;
    fill_summary();
    return failure;
  }

  /// Closes this part and opens the next when it has reached its size or its duration.
  Status maybe_split() {
    if (!(o_.split_mb > 0 && static_cast<double>(writer_->bytes()) >= o_.split_mb * 1e6) &&
        !(o_.split_s > 0 && part_start_.seconds() >= o_.split_s))
      return {};
    if (Status s = write_stats(); !s.ok()) return s;
    summary_.bytes_written += static_cast<int64_t>(writer_->bytes());
    if (Status s = writer_->close(); !s.ok()) return s;
    return open_part();
  }

  std::string status_line() const {
    char buf[160];
    std::snprintf(buf, sizeof(buf), "recording %s: %lld messages, %.1f MB, %lld lost, %.1f MB queued",
                  summary_.files.back().c_str(), static_cast<long long>(summary_.written),
                  static_cast<double>(summary_.bytes_written + static_cast<int64_t>(writer_->bytes())) / 1e6,
                  static_cast<long long>(last_stats_.lost), static_cast<double>(queue_.bytes()) / 1e6);
    return buf;
  }

  void fill_summary() {
    const Counters& c = last_counters_;
    summary_.received = c.received;
    summary_.filtered = c.filtered;
    summary_.queue_dropped = c.queue_dropped;
    summary_.kernel_dropped = c.kernel_dropped;
    summary_.garbage = c.garbage;
    summary_.senders = static_cast<int64_t>(c.senders.size());
    for (const auto& [key, sc] : c.senders) {
      summary_.lost += sc.lost;
      summary_.gaps += sc.gaps;
      summary_.fragments_incomplete += sc.fragments_incomplete;
    }
  }

  const RecordOptions& o_;
  const WallClock& clock_;  ///< read from the receive and the writer threads
  std::atomic<bool>& stop_;
  const int fd_;
  ChunkQueue queue_;
  std::optional<std::regex> include_, exclude_;
  std::unordered_map<std::string, bool, StringHash, std::equal_to<>> decisions_;
  Counters local_;                // receiver thread only
  std::mutex counters_mutex_;
  Counters shared_;               // under counters_mutex_
  Counters last_counters_;        // writer thread only
  driftlab::recorder_stats_t last_stats_{};
  int64_t stats_seq_ = 0;
  std::optional<LogWriter> writer_;
  RecordSummary summary_;
  Stopwatch start_, part_start_;  ///< since the recording started, since the current part was opened
};

}  // namespace

std::string split_path(const std::string& out, int index) {
  char suffix[16];
  std::snprintf(suffix, sizeof(suffix), "_%04d", index);
  const size_t slash = out.rfind('/');
  const size_t dot = out.rfind('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return out + suffix;
  return out.substr(0, dot) + suffix + out.substr(dot);
}

Status check_options(const RecordOptions& options) {
  if (auto url = parse_udpm_url(options.url); !url) return url.error();
  for (const auto& [option, pattern] :
       {std::pair{"-c/--channels", &options.channels}, {"--exclude", &options.exclude}}) {
    try {
      std::regex check(*pattern, std::regex::ECMAScript);
    } catch (const std::regex_error& e) {
      return Error{std::string(option) + ": invalid channel regex '" + *pattern + "': " + e.what()};
    }
  }
  return {};
}

Recorder::Recorder(RecordOptions options, const WallClock& clock) : options_(std::move(options)), clock_(clock) {}

Result<RecordSummary> Recorder::run() {
  auto url = parse_udpm_url(options_.url);
  if (!url) return url.error();
  const int64_t buffer = url->recv_buf_size > 0 ? url->recv_buf_size : options_.socket_buffer_bytes;
  auto fd = open_socket(*url, options_.url, buffer);
  if (!fd) return fd.error();
  Session session(options_, clock_, stop_, *fd);
  Result<RecordSummary> result = Error{""};
  if (auto st = session.compile_filters(); !st) {
    result = st.error();
  } else if (auto opened = session.open_part(); !opened) {
    result = opened.error();
  } else {
    if (options_.on_listening) options_.on_listening();
    result = session.run();
  }
  ::close(*fd);
  return result;
}

std::string listening_line(const RecordOptions& o) {
  std::string what = o.channels == ".*" ? "every channel" : "channels matching '" + o.channels + "'";
  if (!o.exclude.empty()) what += " except '" + o.exclude + "'";
  const std::string until =
      o.duration_s > 0 ? "for " + short_number(o.duration_s) + " s or until Ctrl-C" : "until Ctrl-C";
  return "recording " + what + " on " + o.url + " to " +
         (o.split_mb > 0 || o.split_s > 0 ? o.out + " (in numbered parts)" : o.out) + ", " + until + "\n";
}

std::string record_text(const RecordSummary& s) {
  std::string files = s.files.front();
  if (s.files.size() > 1) files += " ... " + s.files.back() + " (" + std::to_string(s.files.size()) + " files)";
  std::string out;
  appendf(out, "recorded %s messages (%s) to %s in %.1f s\n", thousands(s.written).c_str(),
          human_bytes(static_cast<double>(s.bytes_written)).c_str(), files.c_str(), s.seconds);
  appendf(out, "received %s from %lld sender%s, %s left out by channel filters\n", thousands(s.received).c_str(),
          static_cast<long long>(s.senders), s.senders == 1 ? "" : "s", thousands(s.filtered).c_str());
  appendf(out,
          "lost: %s in %s sequence gaps, %s dropped by the kernel, %s by the recorder's queue, %s fragmented "
          "messages incomplete; %s garbage datagrams\n",
          thousands(s.lost).c_str(), thousands(s.gaps).c_str(), thousands(s.kernel_dropped).c_str(),
          thousands(s.queue_dropped).c_str(), thousands(s.fragments_incomplete).c_str(), thousands(s.garbage).c_str());
  return out;
}

}  // namespace driftlab::recorder
