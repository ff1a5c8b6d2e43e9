// ROS 1 bag format 2.0 (wiki.ros.org/Bags/Format/2.0): "#ROSBAG V2.0\n", then records, each
//   uint32 header_len, header (fields: uint32 len, "name=value"), uint32 data_len, data.
// op 0x03 bag header, 0x05 chunk (its data holds connection and message records), 0x07 connection, 0x02 message
// data, 0x04 index data and 0x06 chunk info (the index, not needed when reading front to back).
#include "formats/ros1_bag.h"

#include <pthread.h>

#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <string_view>
#include <system_error>
#include <thread>
#include <vector>

#include "formats/compression.h"

namespace driftlab::formats {
namespace {

constexpr std::string_view kMagic = "#ROSBAG V2.0\n";
constexpr uint8_t kOpMessage = 0x02, kOpBagHeader = 0x03, kOpChunk = 0x05, kOpConnection = 0x07;
// A record header holds a few short fields (a connection's, its topic); more than this is not a header.
constexpr uint32_t kMaxHeader = 1 << 20;

uint32_t le32(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

struct Record {
  uint8_t op = 0;
  std::vector<std::pair<std::string_view, std::string_view>> fields;
  std::span<const uint8_t> data;
  size_t end = 0;  // offset just past the record

  std::optional<std::string_view> field(std::string_view name) const {
    for (const auto& [k, v] : fields)
      if (k == name) return v;
    return std::nullopt;
  }
  std::optional<uint32_t> u32(std::string_view name) const {
    auto v = field(name);
    if (!v || v->size() != 4) return std::nullopt;
    return le32(reinterpret_cast<const uint8_t*>(v->data()));
  }
};

/// Parses "len name=value ..." fields filling exactly bytes.
bool parse_fields_into(std::span<const uint8_t> bytes,
                       std::vector<std::pair<std::string_view, std::string_view>>& out) {
  out.clear();
  size_t p = 0;
  while (p < bytes.size()) {
    if (bytes.size() - p < 4) return false;
    const uint32_t n = le32(bytes.data() + p);
    p += 4;
    if (n > bytes.size() - p) return false;
    std::string_view f(reinterpret_cast<const char*>(bytes.data() + p), n);
    p += n;
    const size_t eq = f.find('=');
    if (eq == std::string_view::npos) return false;
    out.emplace_back(f.substr(0, eq), f.substr(eq + 1));
  }
  return true;
}

/// The record at pos of bytes, or why it is not one. A record whose data runs past the end is returned with
/// its data cut at the end and `truncated` set.
std::optional<Record> parse_record(std::span<const uint8_t> bytes, size_t pos, std::string* why, bool* truncated) {
  *truncated = false;
  const size_t left = bytes.size() - pos;
  if (left < 4) {
    *why = "a record cut off in its length";
    return std::nullopt;
  }
  const uint32_t header_len = le32(bytes.data() + pos);
  if (header_len > kMaxHeader || header_len < 4) {
    *why = "a record header length of " + std::to_string(header_len);
    return std::nullopt;
  }
  if (header_len > left - 4 || left - 4 - header_len < 4) {
    *why = "a record cut off in its header";
    return std::nullopt;
  }
  Record r;
  if (!parse_fields_into(bytes.subspan(pos + 4, header_len), r.fields)) {
    *why = "a record header whose fields do not parse";
    return std::nullopt;
  }
  auto op = r.field("op");
  if (!op || op->size() != 1) {
    *why = "a record without an op field";
    return std::nullopt;
  }
  r.op = static_cast<uint8_t>((*op)[0]);
  const size_t data_at = pos + 4 + header_len + 4;
  const uint32_t data_len = le32(bytes.data() + data_at - 4);
  if (data_len > bytes.size() - data_at) {
    *truncated = true;
    r.data = bytes.subspan(data_at);
    r.end = bytes.size();
  } else {
    r.data = bytes.subspan(data_at, data_len);
    r.end = data_at + data_len;
  }
  return r;
}

/// The first offset at or after `from` where a whole record parses: a record's header carries an "op=" field
/// (length 4), so look for that, and for the record's start up to a header's reach before it.
size_t resync(std::span<const uint8_t> bytes, size_t from) {
  static constexpr uint8_t kOpField[] = {4, 0, 0, 0, 'o', 'p', '='};
  constexpr size_t kReach = 4096;  // the op field sits among a record's first fields, well within this
  const uint8_t* begin = bytes.data();
  const uint8_t* end = begin + bytes.size();
  for (const uint8_t* hit = begin + from;; ++hit) {
    hit = std::search(hit, end, std::begin(kOpField), std::end(kOpField));
    if (hit == end) return bytes.size();
    const auto p = static_cast<size_t>(hit - begin);
    for (size_t back = 4; back <= kReach && back <= p - from; ++back) {
      const size_t q = p - back;
      std::string why;
      bool truncated = false;
      if (parse_record(bytes, q, &why, &truncated) && !truncated && q + 4 + le32(begin + q) > p) return q;
    }
  }
}

/// The codec of a chunk's "compression" field; false for one rosbag does not write.
bool codec_of(std::string_view compression, Codec* codec) {
  if (compression == "none") {
    *codec = Codec::kNone;
  } else if (compression == "bz2") {
    *codec = Codec::kBz2;
  } else if (compression == "lz4") {
    *codec = Codec::kLz4Frame;
  } else {
    return false;
  }
  return true;
}

/// Decompresses the compressed chunks ahead of the reader on threads of its own (one per core, at least two and at
/// most eight), so that a bz2 bag's decoding, nearly all of its reading, runs on every core while the reader
/// converts. The reader
/// asks for each chunk when it comes to it (take()) and gets what decompressing it then would have given; chunks it
/// never asks for (skipped after damage) are dropped. Thread-safety: take() and look_ahead() from one thread.
class ChunkPrefetch {
 public:
  explicit ChunkPrefetch(std::span<const uint8_t> bytes) : bytes_(bytes), budget_(bytes.size()) {}
  ~ChunkPrefetch() {
    {
      std::lock_guard lk(mu_);
      stop_ = true;
    }
    cv_.notify_all();
    for (auto& t : threads_) t.join();
  }
  ChunkPrefetch(const ChunkPrefetch&) = delete;
  ChunkPrefetch& operator=(const ChunkPrefetch&) = delete;

  /// The compressed chunk record at pos, decompressed into out (as decompress() does): by a worker that has it (waited
  /// for), else here.
  std::string take(uint64_t pos, Codec codec, std::span<const uint8_t> data, size_t size, std::vector<uint8_t>& out) {
    std::shared_ptr<Job> job;
    {
      std::unique_lock lk(mu_);
      while (!jobs_.empty() && jobs_.front()->pos < pos) jobs_.pop_front();  // skipped: never asked for
      if (!jobs_.empty() && jobs_.front()->pos == pos) {
        job = jobs_.front();
        jobs_.pop_front();
        cv_.wait(lk, [&] { return job->state == Job::kDone; });
      }
    }
    if (!job) return decompress(codec, data, size, out);
    if (job->failure) std::rethrow_exception(job->failure);
    out.swap(job->out);
    return job->error;
  }

  /// Queues the compressed chunks after the record at `from` (found by their record headers) for the workers, up
  /// to ahead() waiting or being decompressed. Stops at the first record that does not parse.
  void look_ahead(uint64_t from) {
    if (!start()) return;
    std::lock_guard lk(mu_);
    uint64_t p = std::max(from, next_);
    // Chunks decoded at once hold their declared sizes: at most kAheadBytes of them are queued (at least one),
    // so that honest large chunks are not decoded several at once.
    uint64_t queued = 0;
    for (const auto& j : jobs_) queued += j->size;
    while (jobs_.size() < ahead() && p < bytes_.size()) {
      std::string why;
      bool cut = false;
      auto r = parse_record(bytes_, p, &why, &cut);
      if (!r || cut) {
        p = bytes_.size();  // damage or the end: the reader finds its way from here without help
        break;
      }
      Codec codec;
      if (r->op == kOpChunk && codec_of(r->field("compression").value_or(""), &codec) && codec != Codec::kNone) {
        const size_t size = r->u32("size").value_or(0);
        if (!jobs_.empty() && queued + size > kAheadBytes) break;  // this one waits until the reader is nearer
        // A chunk the reader refuses is not decoded (the reader's budget is the same and sees the same chunks).
        if (!block_size_problem(r->data.size(), size).empty()) {
          p = r->end;
          continue;
        }
        if (!budget_.take(size).empty()) {
          p = bytes_.size();
          break;
        }
        queued += size;
        auto job = std::make_shared<Job>();
        job->pos = p;
        job->codec = codec;
        job->in = r->data;
        job->size = size;  // decoding stops there
        jobs_.push_back(job);
        todo_.push_back(std::move(job));
        cv_.notify_all();
      }
      p = r->end;
    }
    next_ = p;
  }

 private:
  struct Job {
    enum State { kQueued, kRunning, kDone } state = kQueued;
    uint64_t pos = 0;
    Codec codec = Codec::kNone;
    std::span<const uint8_t> in;
    size_t size = 0;
    std::vector<uint8_t> out;
    std::string error;
    std::exception_ptr failure;
  };
  static constexpr size_t kMinWorkers = 2, kMaxWorkers = 8;
  static constexpr uint64_t kAheadBytes = uint64_t{256} << 20;
  // Chunks queued, being decompressed or waiting for the reader: two more than the workers (memory: that many
  // chunks, rosbag's are 768 KiB by default).
  size_t ahead() const { return threads_.size() + 2; }

  bool start() {
    if (started_) return !threads_.empty();
    started_ = true;
    try {
      const size_t workers = std::clamp<size_t>(std::thread::hardware_concurrency(), kMinWorkers, kMaxWorkers);
      for (size_t k = 0; k < workers; ++k) {
        threads_.emplace_back([this, k] {
          const std::string name = "bag-unzip" + std::to_string(k);  // its own line in top and perf
          pthread_setname_np(pthread_self(), name.c_str());
          run();
        });
      }
    } catch (const std::system_error&) {  // no threads to be had: the reader decompresses each chunk itself
      {
        std::lock_guard lk(mu_);
        stop_ = true;
      }
      cv_.notify_all();
      for (auto& t : threads_) t.join();
      threads_.clear();
    }
    return !threads_.empty();
  }
  void run() {
    for (;;) {
      std::shared_ptr<Job> job;
      {
        std::unique_lock lk(mu_);
        cv_.wait(lk, [&] { return stop_ || !todo_.empty(); });
        if (stop_) return;
        job = std::move(todo_.front());
        todo_.pop_front();
        job->state = Job::kRunning;
      }
      try {
        job->error = decompress(job->codec, job->in, job->size, job->out);
      } catch (...) {
        job->failure = std::current_exception();
      }
      {
        std::lock_guard lk(mu_);
        job->state = Job::kDone;
      }
      cv_.notify_all();
    }
  }

  std::span<const uint8_t> bytes_;
  DecodeBudget budget_;  // under mu_
  std::vector<std::thread> threads_;
  bool started_ = false;
  // Under mu_: the jobs in file order (waiting for the reader), those not started yet, the flags, each job's state.
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::shared_ptr<Job>> jobs_;
  std::deque<std::shared_ptr<Job>> todo_;
  uint64_t next_ = 0;  // where looking ahead goes on
  bool stop_ = false;
};

}  // namespace

bool Ros1BagReader::looks_like(std::span<const uint8_t> head) {
  return head.size() >= 9 && std::memcmp(head.data(), "#ROSBAG V", 9) == 0;
}

Result<Ros1BagReader> Ros1BagReader::check(const std::string& name, std::span<const uint8_t> bytes) {
  if (!looks_like(bytes)) return Error(name + ": not a ROS 1 bag (no #ROSBAG magic)");
  if (bytes.size() < kMagic.size() || std::memcmp(bytes.data(), kMagic.data(), kMagic.size()) != 0) {
    const auto* p = reinterpret_cast<const char*>(bytes.data());
    const std::string version(p + 9, std::min<size_t>(3, bytes.size() - 9));
    return Error(name + ": ROS bag format " + version + " is not supported (2.0 is; `rosbag fix` converts older bags)");
  }
  Ros1BagReader r;
  r.bytes_ = bytes;
  return r;
}

Result<Ros1BagReader> Ros1BagReader::open(const std::string& path) {
  auto file = MappedFile::open(path);
  if (!file) return file.error();
  auto r = check(path, file->bytes());
  if (r) r->file_ = std::move(*file);  // the mapping moves, the bytes stay where they are
  return r;
}

Result<Ros1BagReader> Ros1BagReader::from_memory(std::span<const uint8_t> bytes) { return check("bag", bytes); }

int64_t Ros1BagReader::read(const std::function<void(const BagMessage&)>& on_message,
                            const std::function<void(const BagProblem&)>& on_problem) {
  const auto bytes = bytes_;
  int64_t delivered = 0;
  std::vector<uint8_t> chunk;
  ChunkPrefetch prefetch(bytes);
  DecodeBudget budget(bytes.size());
  bool budget_spent = false;

  auto connection = [&](const Record& r, uint64_t where) {
    auto id = r.u32("conn");
    auto topic = r.field("topic");
    Record fields;
    if (!id || !topic || !parse_fields_into(r.data, fields.fields)) {
      on_problem({where, "a connection record without its id, topic or fields"});
      return;
    }
    if (connections_.count(*id)) return;  // each connection is written again after the chunks
    RosConnection c;
    c.id = *id;
    c.topic = std::string(*topic);
    c.type = std::string(fields.field("type").value_or(""));
    c.md5sum = std::string(fields.field("md5sum").value_or(""));
    c.definition = std::string(fields.field("message_definition").value_or(""));
    c.callerid = std::string(fields.field("callerid").value_or(""));
    c.latching = fields.field("latching").value_or("0") == "1";
    connections_.emplace(c.id, std::move(c));
  };
  // The connections the index section repeats after the chunks (a bag that was closed: the bag header's index_pos):
  // read once, when a message names a connection no record before it defined, as happens after a chunk that could
  // not be read (an unknown compression, damage) held that connection's record.
  bool index_read = false;
  auto from_index = [&] {
    index_read = true;
    std::string why;
    bool cut = false;
    auto head = parse_record(bytes, kMagic.size(), &why, &cut);
    auto at = head && head->op == kOpBagHeader ? head->field("index_pos") : std::nullopt;
    if (!at || at->size() != 8) return;
    uint64_t p = 0;
    std::memcpy(&p, at->data(), 8);
    while (p > kMagic.size() && p < bytes.size()) {
      auto r = parse_record(bytes, p, &why, &cut);
      if (!r || cut) break;
      if (r->op == kOpConnection) connection(*r, p);
      p = r->end;
    }
  };
  auto message = [&](const Record& r, uint64_t where) {
    auto id = r.u32("conn");
    auto time = r.field("time");
    if (!id || !time || time->size() != 8) {
      on_problem({where, "a message record without its connection or time"});
      return;
    }
    auto c = connections_.find(*id);
    if (c == connections_.end() && !index_read) {
      from_index();
      c = connections_.find(*id);
    }
    if (c == connections_.end()) {
      on_problem({where, "a message on connection " + std::to_string(*id) + ", which no record defines"});
      return;
    }
    const auto* t = reinterpret_cast<const uint8_t*>(time->data());
    const int64_t ns = int64_t{le32(t)} * 1'000'000'000 + le32(t + 4);
    on_message({&c->second, ns, r.data, where});
    ++delivered;
  };

  size_t pos = kMagic.size();
  while (pos < bytes.size()) {
    std::string why;
    bool truncated = false;
    auto rec = parse_record(bytes, pos, &why, &truncated);
    if (!rec) {
      const size_t next = resync(bytes, pos + 1);
      on_problem({pos, why + (next < bytes.size() ? "; " + std::to_string(next - pos) + " bytes skipped"
                                                  : "; nothing readable after it")});
      pos = next;
      continue;
    }
    if (truncated) {
      on_problem({pos, "the file ends inside this record (" + std::to_string(rec->data.size()) + " of its bytes)"});
    }
    if (rec->op == kOpConnection) {
      connection(*rec, pos);
    } else if (rec->op == kOpMessage) {
      if (!truncated) message(*rec, pos);
    } else if (rec->op == kOpChunk) {
      const auto compression = rec->field("compression").value_or("");
      const auto size = rec->u32("size").value_or(0);
      Codec codec;
      if (!codec_of(compression, &codec)) {
        on_problem({pos, "a chunk compressed with \"" + std::string(compression) +
                             "\", which is not known (rosbag's are none, bz2 and lz4); its messages are left out"});
        pos = rec->end;
        continue;
      }
      // An uncompressed chunk's records are read where they are; a compressed one's as a worker decompressed it
      // (the next ones are queued first, so they decompress while this one converts).
      std::string error;
      std::span<const uint8_t> records = rec->data;
      if (codec != Codec::kNone) {
        // A chunk declaring more than its bytes can honestly hold, or past what the whole file may decode to, is
        // refused before anything is decoded; a chunk decodes to its declared size at most.
        if (budget_spent) {  // said once, at the chunk that went past it
          pos = rec->end;
          continue;
        }
        std::string refused = block_size_problem(rec->data.size(), size);
        if (refused.empty()) {
          refused = budget.take(size);
          budget_spent = !refused.empty();
        }
        if (!refused.empty()) {
          on_problem({pos, "chunk: " + refused});
          pos = rec->end;
          continue;
        }
        if (pipelined_) prefetch.look_ahead(rec->end);
        error =
            pipelined_ ? prefetch.take(pos, codec, rec->data, size, chunk) : decompress(codec, rec->data, size, chunk);
        records = chunk;
      }
      if (!error.empty() && !truncated) on_problem({pos, "chunk: " + error});
      // Records inside the chunk: every whole one is read, up to the first that does not parse.
      size_t in = 0;
      while (in < records.size()) {
        bool cut = false;
        auto inner = parse_record(records, in, &why, &cut);
        if (!inner || cut) {
          if (error.empty() && !truncated) {
            on_problem({pos, "chunk: " + (inner ? std::string("a record cut off") : why) + " at byte " +
                                 std::to_string(in) + " of " + std::to_string(records.size())});
          }
          break;
        }
        if (inner->op == kOpConnection) connection(*inner, pos);
        if (inner->op == kOpMessage) message(*inner, pos);
        in = inner->end;
      }
    }
    pos = rec->end;
    file_.release_before(pos);
  }
  return delivered;
}

}  // namespace driftlab::formats
