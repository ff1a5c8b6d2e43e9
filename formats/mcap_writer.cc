// Writing an MCAP file (mcap.dev/spec): chunks built on the calling thread, compressed and written in order by
// threads of the writer's own, then the summary (schemas, channels, chunk and metadata indexes, statistics) and
// the footer with its CRC.
#include "formats/mcap.h"

#include <fcntl.h>
#include <pthread.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <exception>
#include <mutex>
#include <system_error>
#include <thread>

#include "core/check.h"
#include "formats/compression.h"
#include "formats/internal/mcap_records.h"

namespace driftlab::formats {

using namespace mcap;  // NOLINT(google-build-using-namespace): the records' own names, in the files that write them

namespace {

/// std::allocator, but what a vector grows by is left uninitialized rather than zero-filled: the chunk's bytes are
/// written as soon as they are appended (zero-filling them first was a pass over every byte exported).
template <typename T>
struct DefaultInit : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = DefaultInit<U>;
  };
  DefaultInit() = default;
  template <typename U>
  explicit DefaultInit(const DefaultInit<U>&) noexcept {}
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... A>
  void construct(U* p, A&&... a) {
    ::new (static_cast<void*>(p)) U(std::forward<A>(a)...);
  }
};
using Bytes = std::vector<uint8_t, DefaultInit<uint8_t>>;

class Buf {
 public:
  Bytes& v() { return b_; }
  /// n more bytes at the end, uninitialized, for the caller to fill.
  uint8_t* append(size_t n) {
    const size_t at = b_.size();
    b_.resize(at + n);
    return b_.data() + at;
  }
  size_t size() const { return b_.size(); }
  void u8(uint8_t x) { b_.push_back(x); }
  template <typename T>
  void put(T x) {
    const size_t n = b_.size();
    b_.resize(n + sizeof(T));
    std::memcpy(b_.data() + n, &x, sizeof(T));
  }
  void bytes(std::span<const uint8_t> s) { b_.insert(b_.end(), s.begin(), s.end()); }
  void str(std::string_view s) {
    put(static_cast<uint32_t>(s.size()));
    b_.insert(b_.end(), s.begin(), s.end());
  }
  /// Starts a record; end_record(at) fills in its length.
  size_t begin_record(uint8_t op) {
    u8(op);
    put<uint64_t>(0);
    return b_.size();
  }
  void end_record(size_t content_at) {
    const uint64_t len = b_.size() - content_at;
    std::memcpy(b_.data() + content_at - 8, &len, 8);
  }
  size_t begin_sized() {
    put<uint32_t>(0);
    return b_.size();
  }
  void end_sized(size_t at) {
    const auto len = static_cast<uint32_t>(b_.size() - at);
    std::memcpy(b_.data() + at - 4, &len, 4);
  }
  void string_map(const std::vector<std::pair<std::string, std::string>>& m) {
    const size_t at = begin_sized();
    for (const auto& [k, v] : m) {
      str(k);
      str(v);
    }
    end_sized(at);
  }

 private:
  Bytes b_;
};

struct SchemaEntry {
  uint16_t id;
  std::string name, encoding, data;
  bool written = false;
};
struct ChannelEntry {
  uint16_t id, schema_id;
  std::string topic, encoding;
  std::vector<std::pair<std::string, std::string>> metadata;
  bool written = false;
  uint64_t count = 0;
};
struct ChunkIndexEntry {
  uint64_t start, end, offset, length;
  std::vector<std::pair<uint16_t, uint64_t>> index_offsets;
  uint64_t index_length, compressed, uncompressed;
};
struct MetadataIndexEntry {
  uint64_t offset, length;
  std::string name;
};

void schema_record(Buf& b, const SchemaEntry& s) {
  const size_t at = b.begin_record(kSchema);
  b.put(s.id);
  b.str(s.name);
  b.str(s.encoding);
  b.str(s.data);
  b.end_record(at);
}
void channel_record(Buf& b, const ChannelEntry& c) {
  const size_t at = b.begin_record(kChannel);
  b.put(c.id);
  b.put(c.schema_id);
  b.str(c.topic);
  b.str(c.encoding);
  b.string_map(c.metadata);
  b.end_record(at);
}

}  // namespace

// The writer is two halves too: the calling thread builds a chunk's records; threads of the writer's own (kWriters
// of them: two chunks compressed at once) compress each closed chunk and compute the CRC of what is stored, then,
// in the order the jobs were handed on, write it with its message indexes, while the next ones fill. Bytes outside
// chunks (the header, metadata) go the same way, so the file is written in order. Hand-off: `jobs`, `in_flight`,
// `next_write`, `stop`, `spare` and `io_error` only under `mu`; a Job's bytes are the calling thread's until queued
// and the thread's that takes it after (mu orders both). The writing side's fields (fd, flushed, crc, head, the
// indexes) are touched only by the thread whose turn it is to write (its job's number is `next_write`, advanced under
// mu when it is done), and the calling thread reads them after joining the threads (close) or after waiting under
// mu for them to be idle (bytes()).
struct McapWriter::Impl {
  McapWriteOptions options;
  std::string path, file_path;
  std::string error;  // the first failure, as the calling thread knows it
  Buf out;            // the calling thread's bytes outside chunks, not yet handed on

  // The writing side.
  int fd = -1;
  uint64_t flushed = 0;
  uint32_t crc = 0;  // of every byte of the file so far (the data section, until Data End)
  Buf head;          // a chunk's fields and its message indexes on their way to the file
  std::vector<ChunkIndexEntry> chunk_indexes;
  std::vector<MetadataIndexEntry> metadata_indexes;

  std::vector<SchemaEntry> schemas;
  std::vector<ChannelEntry> channels;
  uint64_t messages = 0, start = UINT64_MAX, end = 0;

  Buf chunk;  // the open chunk's records
  uint64_t chunk_start = UINT64_MAX, chunk_end = 0;
  std::map<uint16_t, std::vector<std::pair<uint64_t, uint64_t>>> chunk_index;  // channel -> (log_time, offset)
  bool closed = false;

  /// What goes to a writing thread: a closed chunk, or bytes written as they are (a Metadata record, indexed).
  struct Job {
    Bytes bytes;  // the chunk's records, or the bytes
    bool chunk = false;
    uint64_t number = 0;          // handed on as the number-th job: written in this order
    uint64_t start = 0, end = 0;  // the chunk's log times
    uint32_t records_crc = 0;     // the chunk's records' CRC, computed by the calling thread
    std::map<uint16_t, std::vector<std::pair<uint64_t, uint64_t>>> index;
    bool is_metadata = false;
    std::string metadata;  // its name
  };
  /// A compressing context and its output: one per writing thread (and one for writing without threads).
  struct Packer {
    std::unique_ptr<Compressor> compressor;
    std::vector<uint8_t> compressed;
  };
  static constexpr size_t kWriters = 2;
  static constexpr size_t kMaxJobs = 3;  // queued or being compressed or written: with the open chunk, four chunks
  std::vector<std::thread> threads;
  std::mutex mu;
  std::condition_variable cv;
  std::deque<Job> jobs;
  size_t in_flight = 0;     // jobs taken by a thread and not done
  uint64_t handed = 0;      // jobs handed on so far (the next one's number)
  uint64_t next_write = 0;  // the number of the job whose turn it is to be written
  bool stop = false;
  std::string io_error;
  std::vector<Bytes> spare;  // chunk buffers back from the writing threads, for the next chunks
  Packer inline_packer;      // without threads

  uint64_t offset() const { return flushed + out.size(); }  // with no writing thread running
  Status io_failure(const std::string& what, int err) const {
    return Error(file_path + ": " + what + (err ? std::string(": ") + std::strerror(err) : ""),
                 ErrorCode::kCannotWrite);
  }
  /// Keeps the first failure (the calling thread's side) and returns it. Every failure of a writer is the output's.
  Status fail(const Status& st) {
    if (error.empty()) error = st.message();
    return failed();
  }
  Status failed() const { return Error(error, ErrorCode::kCannotWrite); }
  Status fail(const std::string& what, int err) { return fail(io_failure(what, err)); }

  std::unique_ptr<Compressor> make_compressor() const {
    if (options.compression == McapCompression::kZstd) return std::make_unique<Compressor>(Codec::kZstd, options.level);
    if (options.compression == McapCompression::kLz4)
      return std::make_unique<Compressor>(Codec::kLz4Frame, options.level);
    return nullptr;
  }

  /// Writes bytes whose CRC is known (bytes_crc) to the file, straight from the caller's memory. Writing side.
  Status write_direct(std::span<const uint8_t> b, uint32_t bytes_crc) {
    size_t done = 0;
    while (done < b.size()) {
      const ssize_t n = ::write(fd, b.data() + done, b.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        return io_failure("cannot write", errno);
      }
      done += static_cast<size_t>(n);
    }
    crc = static_cast<uint32_t>(::crc32_combine(crc, bytes_crc, static_cast<z_off_t>(b.size())));
    flushed += b.size();
    return {};
  }
  Status flush(Buf& b) {
    auto& v = b.v();
    if (Status s = write_direct(v, crc32_of(v)); !s) return s;
    v.clear();
    return {};
  }
  /// Writes out (with no writing thread running).
  Status flush_out() {
    if (Status st = flush(out); !st) return fail(st);
    return {};
  }

  /// Compresses a closed chunk (any thread: the packer is its own); what is to be stored, and its CRC.
  Status pack(const Job& j, Packer& p, std::span<const uint8_t>* payload, uint32_t* payload_crc) {
    *payload = j.bytes;
    *payload_crc = j.records_crc;  // stored as they are: the records' CRC serves the file's too
    if (!j.chunk || !p.compressor) return {};
    if (std::string e = p.compressor->run(j.bytes, p.compressed); !e.empty()) return io_failure(e, 0);
    *payload = p.compressed;
    *payload_crc = crc32_of(p.compressed);
    return {};
  }
  /// Writes a chunk, packed, with its message indexes. Writing side, in its turn.
  Status write_chunk(Job& j, std::span<const uint8_t> payload, uint32_t payload_crc) {
    const auto& records = j.bytes;
    const char* compression = options.compression == McapCompression::kZstd  ? "zstd"
                              : options.compression == McapCompression::kLz4 ? "lz4"
                                                                             : "";
    ChunkIndexEntry ci{};
    ci.start = j.start;
    ci.end = j.end;
    ci.offset = flushed;
    ci.compressed = payload.size();
    ci.uncompressed = records.size();
    // The chunk's head through the buffer, its records straight from memory (no copy).
    const uint64_t content = 8 + 8 + 8 + 4 + 4 + std::strlen(compression) + 8 + payload.size();
    head.u8(kChunk);
    head.put(content);
    head.put(j.start);
    head.put(j.end);
    head.put<uint64_t>(records.size());
    head.put(j.records_crc);
    head.str(compression);
    head.put<uint64_t>(payload.size());
    if (Status st = flush(head); !st) return st;
    if (Status st = write_direct(payload, payload_crc); !st) return st;
    ci.length = flushed - ci.offset;
    const uint64_t index_start = flushed;
    for (auto& [id, entries] : j.index) {
      ci.index_offsets.emplace_back(id, flushed + head.size());
      // Sorted by log time (stable: equal times keep file order), so readers can search them.
      std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      const size_t r = head.begin_record(kMessageIndex);
      head.put(id);
      head.put(static_cast<uint32_t>(entries.size() * 16));
      for (const auto& [t, o] : entries) {
        head.put(t);
        head.put(o);
      }
      head.end_record(r);
    }
    ci.index_length = flushed + head.size() - index_start;
    chunk_indexes.push_back(std::move(ci));
    return flush(head);
  }
  /// Writes a packed job. Writing side, in its turn.
  Status write_job(Job& j, std::span<const uint8_t> payload, uint32_t payload_crc) {
    if (j.chunk) return write_chunk(j, payload, payload_crc);
    if (j.is_metadata) metadata_indexes.push_back({flushed, j.bytes.size(), std::move(j.metadata)});
    return write_direct(j.bytes, crc32_of(j.bytes));
  }
  /// A writing thread: takes jobs in order, packs each (two threads: two chunks at once), then waits for its turn
  /// and writes it; after a failure nothing more is written (the turns still go round).
  void run(size_t k) {
    const std::string name = "mcap-write" + std::to_string(k);  // its own line in top and perf
    pthread_setname_np(pthread_self(), name.c_str());
    Packer p{make_compressor(), {}};
    for (;;) {
      Job j;
      bool failed = false;
      {
        std::unique_lock lk(mu);
        cv.wait(lk, [&] { return !jobs.empty() || stop; });
        if (jobs.empty()) return;
        j = std::move(jobs.front());
        jobs.pop_front();
        ++in_flight;
        failed = !io_error.empty();
      }
      Status st;
      std::span<const uint8_t> payload;
      uint32_t payload_crc = 0;
      try {
        if (!failed) st = pack(j, p, &payload, &payload_crc);
      } catch (const std::exception& e) {
        st = io_failure(e.what(), 0);
      }
      {
        std::unique_lock lk(mu);
        cv.wait(lk, [&] { return next_write == j.number; });
        failed = !io_error.empty();
      }
      try {
        if (!failed && st) st = write_job(j, payload, payload_crc);
      } catch (const std::exception& e) {
        st = io_failure(e.what(), 0);
      }
      std::lock_guard lk(mu);
      if (!st && io_error.empty()) io_error = st.message();
      if (j.chunk) {
        j.bytes.clear();
        spare.push_back(std::move(j.bytes));
      }
      ++next_write;
      --in_flight;
      cv.notify_all();
    }
  }
  /// Hands a job on, once fewer than kMaxJobs are queued or being packed or written (written here without threads).
  Status push(Job&& j) {
    if (threads.empty()) {
      std::span<const uint8_t> payload;
      uint32_t payload_crc = 0;
      Status st = pack(j, inline_packer, &payload, &payload_crc);
      if (st) st = write_job(j, payload, payload_crc);
      if (!st) return fail(st);
      if (j.chunk) {
        j.bytes.clear();
        spare.push_back(std::move(j.bytes));
      }
      return {};
    }
    std::unique_lock lk(mu);
    cv.wait(lk, [&] { return jobs.size() + in_flight < kMaxJobs; });
    if (!io_error.empty()) return fail(Error(io_error, ErrorCode::kCannotWrite));
    j.number = handed++;
    jobs.push_back(std::move(j));
    cv.notify_all();
    return {};
  }
  /// Hands on the bytes outside chunks written so far.
  Status hand_out() {
    if (out.v().empty()) return {};
    Job j;
    j.bytes.swap(out.v());
    return push(std::move(j));
  }
  Status close_chunk() {
    if (chunk.v().empty()) return {};
    if (Status st = hand_out(); !st) return st;
    Job j;
    j.chunk = true;
    j.records_crc = crc32_of(chunk.v());
    j.bytes.swap(chunk.v());
    j.start = chunk_start;
    j.end = chunk_end;
    j.index.swap(chunk_index);
    chunk_index.clear();
    chunk_start = UINT64_MAX;
    chunk_end = 0;
    {
      std::unique_lock lk(mu, std::defer_lock);
      if (!threads.empty()) lk.lock();
      if (!spare.empty()) {
        chunk.v().swap(spare.back());
        spare.pop_back();
      }
    }
    return push(std::move(j));
  }
  /// Lets the writing threads write everything handed on, and joins them.
  Status finish() {
    if (!threads.empty()) {
      {
        std::lock_guard lk(mu);
        stop = true;
      }
      cv.notify_all();
      for (auto& t : threads) t.join();
      threads.clear();
    }
    if (!io_error.empty()) return fail(Error(io_error, ErrorCode::kCannotWrite));
    return {};
  }
};

McapWriter::McapWriter() : impl_(std::make_unique<Impl>()) {}
McapWriter::McapWriter(McapWriter&&) noexcept = default;
McapWriter& McapWriter::operator=(McapWriter&&) noexcept = default;
McapWriter::~McapWriter() {
  if (impl_ && !impl_->closed) (void)close();
}

Result<McapWriter> McapWriter::create(const std::string& path, McapWriteOptions options) {
  McapWriter w;
  Impl& s = *w.impl_;
  s.options = std::move(options);
  s.path = path;
  s.file_path = s.options.atomic ? path + ".partial" : path;
  s.fd = ::open(s.file_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (s.fd < 0) return Error(path + ": cannot create: " + std::strerror(errno), ErrorCode::kCannotWrite);
  s.inline_packer.compressor = s.make_compressor();
  s.out.bytes(kMagic);
  const size_t at = s.out.begin_record(kHeader);
  s.out.str(s.options.profile);
  s.out.str(s.options.library);
  s.out.end_record(at);
  try {
    for (size_t k = 0; k < Impl::kWriters; ++k) s.threads.emplace_back([impl = &s, k] { impl->run(k); });
  } catch (const std::system_error&) {  // no threads to be had: chunks are written on the calling thread
    (void)s.finish();
  }
  return w;
}

uint16_t McapWriter::add_schema(std::string_view name, std::string_view encoding, std::string_view data) {
  const auto id = static_cast<uint16_t>(impl_->schemas.size() + 1);
  impl_->schemas.push_back({id, std::string(name), std::string(encoding), std::string(data)});
  return id;
}

uint16_t McapWriter::add_channel(uint16_t schema_id, std::string_view topic, std::string_view message_encoding,
                                 const std::vector<std::pair<std::string, std::string>>& metadata) {
  const auto id = static_cast<uint16_t>(impl_->channels.size());
  impl_->channels.push_back({id, schema_id, std::string(topic), std::string(message_encoding), metadata});
  return id;
}

Status McapWriter::write(uint16_t channel_id, uint32_t sequence, uint64_t log_time, uint64_t publish_time,
                         std::span<const uint8_t> data) {
  return write(channel_id, sequence, log_time, publish_time, data.size(),
               [&](uint8_t* to) { std::memcpy(to, data.data(), data.size()); });
}

Status McapWriter::write(uint16_t channel_id, uint32_t sequence, uint64_t log_time, uint64_t publish_time, size_t size,
                         const std::function<void(uint8_t*)>& fill) {
  Impl& s = *impl_;
  if (!s.error.empty()) return s.failed();
  DRIFTLAB_CHECK(channel_id < s.channels.size(), "a channel id comes from add_channel");
  ChannelEntry& c = s.channels[channel_id];
  if (!c.written) {
    if (c.schema_id != 0 && !s.schemas[c.schema_id - 1].written) {
      schema_record(s.chunk, s.schemas[c.schema_id - 1]);
      s.schemas[c.schema_id - 1].written = true;
    }
    channel_record(s.chunk, c);
    c.written = true;
  }
  s.chunk_index[channel_id].emplace_back(log_time, s.chunk.v().size());
  const size_t at = s.chunk.begin_record(kMessage);
  s.chunk.put(channel_id);
  s.chunk.put(sequence);
  s.chunk.put(log_time);
  s.chunk.put(publish_time);
  if (size > 0) fill(s.chunk.append(size));
  s.chunk.end_record(at);
  s.chunk_start = std::min(s.chunk_start, log_time);
  s.chunk_end = std::max(s.chunk_end, log_time);
  s.start = std::min(s.start, log_time);
  s.end = std::max(s.end, log_time);
  ++s.messages;
  ++c.count;
  if (s.chunk.v().size() >= s.options.chunk_bytes) return s.close_chunk();
  return {};
}

Status McapWriter::add_metadata(std::string_view name,
                                const std::vector<std::pair<std::string, std::string>>& entries) {
  Impl& s = *impl_;
  if (!s.error.empty()) return s.failed();
  if (Status st = s.close_chunk(); !st) return st;
  if (Status st = s.hand_out(); !st) return st;
  Buf record;
  const size_t at = record.begin_record(kMetadata);
  record.str(name);
  record.string_map(entries);
  record.end_record(at);
  Impl::Job j;
  j.bytes = std::move(record.v());
  j.is_metadata = true;
  j.metadata = std::string(name);
  return s.push(std::move(j));
}

uint64_t McapWriter::messages() const { return impl_->messages; }
uint64_t McapWriter::bytes() const {
  Impl& s = *impl_;
  if (s.threads.empty()) return s.offset();
  std::unique_lock lk(s.mu);  // what was handed on, once written
  s.cv.wait(lk, [&] { return s.jobs.empty() && s.in_flight == 0; });
  return s.flushed + s.out.size();
}

Status McapWriter::close() {
  Impl& s = *impl_;
  if (s.closed) return s.error.empty() ? Status{} : s.failed();
  s.closed = true;
  Status st = s.close_chunk();
  if (st) st = s.hand_out();
  // Every chunk written (and the writing thread joined): the rest is written here.
  if (Status f = s.finish(); st) st = f;
  if (st) {
    // Data End: the CRC of every byte before it.
    const size_t at = s.out.begin_record(kDataEnd);
    s.out.put(s.crc);
    s.out.end_record(at);
    st = s.flush_out();
  }
  if (st) {
    const uint64_t summary_start = s.offset();
    struct Group {
      uint8_t op;
      uint64_t start, length;
    };
    std::vector<Group> groups;
    auto group = [&](uint8_t op, const std::function<void()>& write_records) {
      const uint64_t g = s.offset();
      write_records();
      if (s.offset() > g) groups.push_back({op, g, s.offset() - g});
    };
    group(kSchema, [&] {
      for (const auto& sc : s.schemas) schema_record(s.out, sc);
    });
    group(kChannel, [&] {
      for (const auto& c : s.channels) channel_record(s.out, c);
    });
    group(kStatistics, [&] {
      const size_t at = s.out.begin_record(kStatistics);
      s.out.put(s.messages);
      s.out.put(static_cast<uint16_t>(s.schemas.size()));
      s.out.put(static_cast<uint32_t>(s.channels.size()));
      s.out.put<uint32_t>(0);  // attachments
      s.out.put(static_cast<uint32_t>(s.metadata_indexes.size()));
      s.out.put(static_cast<uint32_t>(s.chunk_indexes.size()));
      s.out.put(s.messages ? s.start : uint64_t{0});
      s.out.put(s.messages ? s.end : uint64_t{0});
      const size_t m = s.out.begin_sized();
      for (const auto& c : s.channels) {
        s.out.put(c.id);
        s.out.put(c.count);
      }
      s.out.end_sized(m);
      s.out.end_record(at);
    });
    group(kChunkIndex, [&] {
      for (const auto& ci : s.chunk_indexes) {
        const size_t at = s.out.begin_record(kChunkIndex);
        s.out.put(ci.start);
        s.out.put(ci.end);
        s.out.put(ci.offset);
        s.out.put(ci.length);
        const size_t m = s.out.begin_sized();
        for (const auto& [id, off] : ci.index_offsets) {
          s.out.put(id);
          s.out.put(off);
        }
        s.out.end_sized(m);
        s.out.put(ci.index_length);
        s.out.str(s.options.compression == McapCompression::kZstd  ? "zstd"
                  : s.options.compression == McapCompression::kLz4 ? "lz4"
                                                                   : "");
        s.out.put(ci.compressed);
        s.out.put(ci.uncompressed);
        s.out.end_record(at);
      }
    });
    group(kMetadataIndex, [&] {
      for (const auto& mi : s.metadata_indexes) {
        const size_t at = s.out.begin_record(kMetadataIndex);
        s.out.put(mi.offset);
        s.out.put(mi.length);
        s.out.str(mi.name);
        s.out.end_record(at);
      }
    });
    const uint64_t summary_offset_start = s.offset();
    for (const auto& g : groups) {
      const size_t at = s.out.begin_record(kSummaryOffset);
      s.out.u8(g.op);
      s.out.put(g.start);
      s.out.put(g.length);
      s.out.end_record(at);
    }
    // The footer's CRC covers the summary, the summary offsets and the footer up to its own CRC field.
    const size_t summary_at = static_cast<size_t>(summary_start - s.flushed);
    s.out.u8(kFooter);
    s.out.put<uint64_t>(kFooterContent);
    s.out.put(summary_start);
    s.out.put(summary_offset_start);
    const uint32_t summary_crc = crc32_of(std::span<const uint8_t>(s.out.v()).subspan(summary_at));
    s.out.put(summary_crc);
    s.out.bytes(kMagic);
    st = s.flush_out();
  }
  if (::close(s.fd) != 0 && st) st = s.fail("cannot close", errno);
  s.fd = -1;
  if (st && s.options.atomic && std::rename(s.file_path.c_str(), s.path.c_str()) != 0) {
    st = s.fail("cannot rename into place", errno);
  }
  if (!st && s.options.atomic) std::remove(s.file_path.c_str());
  return st;
}

void McapWriter::discard() {
  Impl& s = *impl_;
  if (s.closed) return;
  s.closed = true;
  {
    std::lock_guard lk(s.mu);
    if (s.io_error.empty()) s.io_error = "discarded";  // what is queued is not written
  }
  (void)s.finish();
  if (s.fd >= 0) ::close(s.fd);
  s.fd = -1;
  if (s.options.atomic) std::remove(s.file_path.c_str());
}

}  // namespace driftlab::formats
