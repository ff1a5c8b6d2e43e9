// Reading an MCAP file's data section (mcap.dev/spec): the records in file order, chunks decompressed on worker
// threads a few ahead of the calling thread, which parses them and runs every callback in file order.
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

using namespace mcap;  // NOLINT(google-build-using-namespace): the records' own names, in the files that read them

namespace {

/// A compressed chunk to decompress, on a worker thread (or inline when the read is not pipelined), and what it
/// gives. The worker also checks the records' CRC and computes the stored bytes' CRC for the data section's, while
/// both are in its cache.
struct Unzip {
  std::span<const uint8_t> in;  // the chunk's records as stored
  Codec codec = Codec::kZstd;
  uint64_t size = 0;  // the uncompressed size the chunk declares
  uint32_t crc = 0;   // the CRC its records must have (0: none)
  bool in_crc_wanted = false;
  // What it gives (written by the worker, read after `done` under the read's mutex).
  std::vector<uint8_t> out;  // the records (kept between uses: a reused buffer is not zero-filled again)
  std::string what;          // what is wrong with the chunk ("": nothing)
  uint32_t in_crc = 0;       // the CRC of `in`, when wanted
  std::exception_ptr error;  // what the decompression threw (rethrown where the chunk is read)
  bool done = false;
};

void unzip(Unzip& u, Decompressor& d) {
  try {
    u.what = d.run(u.codec, u.in, u.size, u.out);  // stops at the declared size
    if (u.what.empty() && u.out.size() != u.size) {
      u.what = "its records decompress to " + std::to_string(u.out.size()) + " bytes, not " + std::to_string(u.size);
    } else if (u.what.empty() && u.crc != 0 && crc32_of(u.out) != u.crc) {
      u.what = "its records fail their CRC";
    }
    if (u.in_crc_wanted) u.in_crc = crc32_of(u.in);
  } catch (...) {
    u.error = std::current_exception();
  }
}

/// One step of a read, in file order: a record outside chunks, a chunk's records (decompressed and checked), or a
/// problem the reading side found. Made by the reading side, handed to the calling thread.
struct Step {
  enum Kind : uint8_t { kRecord, kChunk, kProblem, kCrc, kDataEnd };
  Kind kind = kRecord;
  uint8_t op = 0;                  // kRecord: its opcode
  bool cut = false;                // kChunk: the file ends inside it
  uint64_t where = 0;              // the record's file offset
  uint64_t end = 0;                // kRecord, kChunk: the file offset after the record (0: none)
  std::span<const uint8_t> bytes;  // kRecord: its content; kChunk (stored uncompressed): its records
  std::string what;                // kProblem: the problem; kChunk: what is wrong with it ("": nothing)
                                   // kCrc: (bytes) the data section's next bytes, for its CRC
  Unzip* unzip = nullptr;          // kChunk, compressed: its decompression (records, problems, CRCs)
  uint32_t crc = 0;                // kCrc with crc_known: that of bytes; kDataEnd: the data section's
  bool crc_known = false;          // kCrc: bytes (the data section's next bytes) are not to be read again
};
using Batch = std::vector<Step>;

/// Thrown on the reading thread when the calling thread stopped (a callback threw): unwinds it.
struct Stopped {};

constexpr size_t kMaxBatches = 2;       // batches waiting for the calling thread
constexpr size_t kWorkers = 2;          // threads decompressing chunks (two chunks at once)
constexpr size_t kMaxDecompressed = 4;  // chunks being decompressed, waiting or being parsed
// The declared sizes of the chunks held at once (at least one): honest large chunks are not decoded several at once.
constexpr uint64_t kMaxInFlightBytes = uint64_t{256} << 20;
constexpr size_t kMaxBatchSteps = 4096;  // records outside chunks per batch

// The read is two halves joined by a bounded queue of batches of Steps. The reading half walks the data section's
// records and hands each compressed chunk to a worker, which decompresses it, checks its records' CRC and computes
// the CRC of its stored bytes for the data section's (kWorkers of them: two chunks decompressed at once, a few
// ahead of the calling thread); an uncompressed chunk's CRC the reading half checks itself, in the pass that serves
// the data section's too. The converting half (the calling thread) waits for each chunk's decompression in file
// order, checks the data section's CRC, parses the records of chunks, keeps schemas and channels, and runs every
// callback in file order. Pipelined, the reading half and the workers run on threads of their own; otherwise the
// reading half decompresses each chunk itself and hands each batch over by calling the converting half directly.
// Either way the callbacks see the same calls in the same order.
// Hand-off (what a race detector would check): the queue, the slots' free list and `todo_`, each slot's `done`, the
// counters and the flags are touched only under `mu_`. A Step's bytes are written by the reading half before it is
// queued and read by the calling thread after it is dequeued (the mutex orders them); a slot's input is written by
// the reading half before it is queued in `todo_`, its results by a worker before `done` is set, and read by the
// calling thread after it saw `done`, and it goes back to the free list under `mu_` too. The file's bytes are only
// read (release_before() only on the calling thread). The schemas, channels and the data section's running CRC
// are the calling thread's, except that resync() reads the channels after drain() has waited, under `mu_`, for every
// batch queued to be done, while the calling thread waits for more. The reading half alone fills in `found_` (the
// header's profile and library, the summary's statistics), which the caller reads after the threads are joined.
//
/// One read() of a file: the state both halves share, each half's steps, and the threads.
class Read {
 public:
  /// What read() fills in besides calling back: the file's header and its summary's statistics.
  struct Found {
    std::string& profile;
    std::string& library;
    McapStatistics& statistics;
    bool& has_statistics;
  };
  using OnMessage = std::function<void(const McapMessage&)>;
  using OnProblem = std::function<void(const McapProblem&)>;
  using OnMetadata = std::function<void(const McapMetadata&)>;

  Read(std::span<const uint8_t> bytes, ReaderState& s, MappedFile& file, bool pipelined, Found found,
       const OnMessage& on_message, const OnProblem& on_problem, const OnMetadata& on_metadata)
      : bytes_(bytes),
        s_(s),
        file_(file),
        threaded_(pipelined),
        found_(found),
        on_message_(on_message),
        on_problem_(on_problem),
        on_metadata_(on_metadata),
        budget_(bytes.size()) {
    for (size_t i = 0; i < kMaxDecompressed; ++i) {
      slots_.push_back(std::make_unique<Unzip>());
      free_slots_.push_back(slots_.back().get());
    }
  }

  /// Reads the file; returns the messages delivered.
  int64_t run();

 private:
  // The converting half (the calling thread).
  void schema(std::span<const uint8_t> c, uint64_t where);
  void channel(std::span<const uint8_t> c, uint64_t where);
  void message(std::span<const uint8_t> c, uint64_t where, int64_t in_chunk);
  void metadata(std::span<const uint8_t> c, uint64_t where);
  /// A chunk's records, as the reading half made them ready.
  void chunk_records(const Step& st);
  void consume(const Batch& batch);

  // The hand-off.
  /// The calling thread is done with a batch: its decompression slots go back (under mu_ when threaded).
  void recycle(Batch& b);
  void flush();
  /// A slot to decompress a chunk in, once one is free; decompressed by a worker (pipelined) or here, at once.
  Unzip* decompress(Unzip u);
  /// Waits until the calling thread has done every batch handed over (and is waiting for the next).
  void drain();
  void problem(uint64_t where, std::string what);
  void record(uint8_t op, uint64_t where, uint64_t end, std::span<const uint8_t> content);

  // The reading half.
  void produce();
  /// Whether a record whose content parses exactly starts at q (to find where reading can go on after damage).
  /// Reads the channels: on the reading thread only after drain().
  bool plausible(size_t q) const;
  size_t resync(size_t from);
  /// The Data End record's CRC, known from the footer before reading: computed while reading only when it is set.
  void find_data_end();
  void crc_to(uint64_t end);
  void send_crc();
  void chunk(std::span<const uint8_t> c, uint64_t where, uint64_t end, bool cut);
  /// A record of the summary, after Data End (statistics, the footer); false at its end.
  bool summary_record(uint8_t op, uint64_t pos, std::span<const uint8_t> content, uint64_t summary_start);

  // The threads.
  /// A worker: decompresses the chunks queued in todo_, one at a time, with a context of its own.
  void work(size_t k);
  int64_t run_threaded();

  const std::span<const uint8_t> bytes_;
  ReaderState& s_;
  MappedFile& file_;
  bool threaded_;
  Found found_;
  const OnMessage& on_message_;
  const OnProblem& on_problem_;
  const OnMetadata& on_metadata_;
  int64_t delivered_ = 0;

  // What the halves share (under mu_ when threaded).
  std::mutex mu_;
  std::condition_variable cv_;  // every thread waits on it (several threads: notify_all)
  std::deque<Batch> queue_;
  // The decompressions: kMaxDecompressed slots, free or held by a chunk's Step from the reading half taking one to
  // the calling thread giving it back; a worker takes those queued in todo_.
  std::vector<std::unique_ptr<Unzip>> slots_;
  std::vector<Unzip*> free_slots_;
  uint64_t in_flight_ = 0;  // the declared sizes of the chunks in the slots taken
  std::deque<Unzip*> todo_;
  uint64_t pushed_ = 0, done_ = 0;
  bool finished_ = false, stopped_ = false;
  std::exception_ptr failure_;

  // The calling thread's.
  uint32_t data_crc_ = 0;  // of the data section's bytes handed over so far

  // The reading half's.
  Batch batch_;  // being filled
  DecodeBudget budget_;
  bool budget_spent_ = false;
  uint32_t want_data_crc_ = 0;
  uint64_t data_end_at_ = 0;
  // The data section's CRC is the calling thread's to compute (this one has the decompression to do): the bytes
  // [0, crc_done_) are to be in it, [0, crc_sent_) of them are handed over already, in order.
  uint64_t crc_done_ = 0, crc_sent_ = 0;
};

void Read::schema(std::span<const uint8_t> c, uint64_t where) {
  Fields f(c);
  McapSchema sc;
  sc.id = f.get<uint16_t>();
  sc.name = f.str();
  sc.encoding = f.str();
  sc.data = std::string(f.str());  // uint32-prefixed bytes: same layout as a string
  if (!f.ok()) {
    on_problem_({where, "a schema record that does not parse"});
    return;
  }
  const uint16_t id = sc.id;
  if (id == 0 || s_.schemas.count(id)) return;  // id 0 is invalid; repeats must be identical
  s_.schemas.emplace(id, std::make_unique<McapSchema>(std::move(sc)));
}

void Read::channel(std::span<const uint8_t> c, uint64_t where) {
  Fields f(c);
  McapChannel ch;
  ch.id = f.get<uint16_t>();
  ch.schema_id = f.get<uint16_t>();
  ch.topic = f.str();
  ch.message_encoding = f.str();
  ch.metadata = f.string_map();
  if (!f.ok()) {
    on_problem_({where, "a channel record that does not parse"});
    return;
  }
  if (s_.channels.count(ch.id)) return;
  if (ch.schema_id != 0) {
    auto it = s_.schemas.find(ch.schema_id);
    if (it == s_.schemas.end()) {
      on_problem_({where, "channel " + std::to_string(ch.id) + " (" + ch.topic + ") names schema " +
                              std::to_string(ch.schema_id) + ", which no record before it defines"});
    } else {
      ch.schema = it->second.get();
    }
  }
  const uint16_t id = ch.id;
  s_.channels.emplace(id, std::make_unique<McapChannel>(std::move(ch)));
}

void Read::message(std::span<const uint8_t> c, uint64_t where, int64_t in_chunk) {
  if (c.size() < 22) {
    on_problem_({where, "a message record of " + std::to_string(c.size()) + " bytes, shorter than its fields" +
                            (in_chunk >= 0 ? " (at byte " + std::to_string(in_chunk) + " of the chunk)" : "")});
    return;
  }
  const auto id = le<uint16_t>(c.data());
  auto it = s_.channels.find(id);
  if (it == s_.channels.end()) {
    on_problem_({where, "a message on channel " + std::to_string(id) + ", which no record before it defines" +
                            (in_chunk >= 0 ? " (at byte " + std::to_string(in_chunk) + " of the chunk)" : "")});
    return;
  }
  McapMessage m;
  m.channel = it->second.get();
  m.sequence = le<uint32_t>(c.data() + 2);
  m.log_time = le<uint64_t>(c.data() + 6);
  m.publish_time = le<uint64_t>(c.data() + 14);
  m.data = c.subspan(22);
  m.offset = where;
  m.offset_in_chunk = in_chunk;
  on_message_(m);
  ++delivered_;
}

void Read::metadata(std::span<const uint8_t> c, uint64_t where) {
  Fields f(c);
  McapMetadata md;
  md.name = f.str();
  md.entries = f.string_map();
  if (!f.ok()) {
    on_problem_({where, "a metadata record that does not parse"});
    return;
  }
  if (on_metadata_) on_metadata_(md);
}

void Read::chunk_records(const Step& st) {
  auto records = st.bytes;
  const uint64_t where = st.where;
  std::string_view what = st.what;
  if (Unzip* u = st.unzip) {
    if (threaded_) {  // decompressed on a worker: wait for it
      std::unique_lock lk(mu_);
      cv_.wait(lk, [&] { return u->done; });
    }
    if (u->error) std::rethrow_exception(u->error);
    records = u->out;
    what = u->what;
    // Its stored bytes in the data section's CRC, where they come (the reading half sent what precedes them).
    if (u->in_crc_wanted) {
      data_crc_ = static_cast<uint32_t>(::crc32_combine(data_crc_, u->in_crc, static_cast<z_off_t>(u->in.size())));
    }
  }
  if (!what.empty() && !st.cut) on_problem_({where, "chunk: " + std::string(what)});
  size_t in = 0;
  while (in < records.size()) {
    if (records.size() - in < kRecordHead ||
        le<uint64_t>(records.data() + in + 1) > records.size() - in - kRecordHead) {
      if (what.empty() && !st.cut) {
        on_problem_(
            {where, "chunk: a record cut off at byte " + std::to_string(in) + " of " + std::to_string(records.size())});
      }
      break;
    }
    const uint8_t op = records[in];
    const auto len = le<uint64_t>(records.data() + in + 1);
    const auto content = records.subspan(in + kRecordHead, len);
    if (op == kMessage) {
      message(content, where, static_cast<int64_t>(in));
    } else if (op == kSchema) {
      schema(content, where);
    } else if (op == kChannel) {
      channel(content, where);
    }
    in += kRecordHead + len;
  }
}

void Read::consume(const Batch& batch) {
  for (const Step& st : batch) {
    switch (st.kind) {
      case Step::kProblem: on_problem_({st.where, st.what}); break;
      case Step::kCrc:
        data_crc_ =
            st.crc_known
                ? static_cast<uint32_t>(::crc32_combine(data_crc_, st.crc, static_cast<z_off_t>(st.bytes.size())))
                : crc32_of(st.bytes, data_crc_);
        break;
      case Step::kDataEnd:
        if (data_crc_ != st.crc) {
          on_problem_(
              {st.where, "the data section fails its CRC (" + hex32(data_crc_) + ", not " + hex32(st.crc) + ")"});
        }
        break;
      case Step::kChunk: chunk_records(st); break;
      case Step::kRecord:
        switch (st.op) {
          case kSchema: schema(st.bytes, st.where); break;
          case kChannel: channel(st.bytes, st.where); break;
          case kMessage: message(st.bytes, st.where, -1); break;
          case kMetadata: metadata(st.bytes, st.where); break;
          default: break;
        }
        break;
    }
    if (st.end != 0) file_.release_before(st.end);
  }
}

void Read::recycle(Batch& b) {
  for (Step& st : b) {
    if (st.unzip == nullptr) continue;
    st.unzip->done = false;
    st.unzip->error = nullptr;
    in_flight_ -= st.unzip->size;
    // A large chunk's buffer is not kept for the next (four slots of a 1 GiB chunk each would be 4 GiB).
    if (st.unzip->out.capacity() > kFreeBlockBytes) std::vector<uint8_t>().swap(st.unzip->out);
    free_slots_.push_back(st.unzip);
  }
  b.clear();
}

void Read::flush() {
  if (batch_.empty()) return;
  if (!threaded_) {
    consume(batch_);
    recycle(batch_);
    return;
  }
  std::unique_lock lk(mu_);
  cv_.wait(lk, [&] { return stopped_ || queue_.size() < kMaxBatches; });
  if (stopped_) throw Stopped{};
  queue_.push_back(std::move(batch_));
  ++pushed_;
  batch_ = Batch();
  cv_.notify_all();
}

Unzip* Read::decompress(Unzip u) {
  std::unique_lock lk(mu_, std::defer_lock);
  if (threaded_) {
    lk.lock();
    cv_.wait(lk, [&] {
      return stopped_ || (!free_slots_.empty() && (in_flight_ == 0 || in_flight_ + u.size <= kMaxInFlightBytes));
    });
    if (stopped_) throw Stopped{};
  }
  in_flight_ += u.size;
  Unzip* slot = free_slots_.back();
  free_slots_.pop_back();
  u.out.swap(slot->out);
  *slot = std::move(u);
  if (!threaded_) {
    unzip(*slot, s_.decompressor);
    slot->done = true;
    return slot;
  }
  todo_.push_back(slot);
  cv_.notify_all();
  return slot;
}

void Read::drain() {
  flush();
  if (!threaded_) return;
  std::unique_lock lk(mu_);
  cv_.wait(lk, [&] { return stopped_ || done_ == pushed_; });
  if (stopped_) throw Stopped{};
}

void Read::problem(uint64_t where, std::string what) {
  Step st;
  st.kind = Step::kProblem;
  st.where = where;
  st.what = std::move(what);
  batch_.push_back(std::move(st));
}

void Read::record(uint8_t op, uint64_t where, uint64_t end, std::span<const uint8_t> content) {
  Step st;
  st.op = op;
  st.where = where;
  st.end = end;
  st.bytes = content;
  batch_.push_back(std::move(st));
  if (batch_.size() >= kMaxBatchSteps) flush();
}

bool Read::plausible(size_t q) const {
  const auto bytes = bytes_;
  if (bytes.size() - q < kRecordHead) return false;
  const uint8_t op = bytes[q];
  const auto len = le<uint64_t>(bytes.data() + q + 1);
  if (len > bytes.size() - q - kRecordHead) return false;
  Fields f(bytes.subspan(q + kRecordHead, len));
  switch (op) {
    case kChunk: {
      f.get<uint64_t>();
      f.get<uint64_t>();
      f.get<uint64_t>();
      f.get<uint32_t>();
      const auto comp = f.str();
      const uint64_t n = f.get<uint64_t>();
      return f.ok() && comp.size() <= 8 && n == f.left();
    }
    case kSchema:
      f.get<uint16_t>();
      f.str();
      f.str();
      f.str();
      return f.ok() && f.left() == 0;
    case kChannel:
      f.get<uint16_t>();
      f.get<uint16_t>();
      f.str();
      f.str();
      f.skip_sized();
      return f.ok() && f.left() == 0;
    case kMessage:
      if (len < 22 || !s_.channels.count(le<uint16_t>(bytes.data() + q + kRecordHead))) return false;
      // The next record must start right after it (or the file end there).
      return q + kRecordHead + len == bytes.size() ||
             (bytes.size() - (q + kRecordHead + len) >= kRecordHead && bytes[q + kRecordHead + len] != 0 &&
              le<uint64_t>(bytes.data() + q + kRecordHead + len + 1) <= bytes.size() - q - 2 * kRecordHead - len);
    case kMessageIndex: {
      f.get<uint16_t>();
      const uint32_t n = f.get<uint32_t>();
      return f.ok() && n % 16 == 0 && n == f.left();
    }
    case kMetadata:
      f.str();
      f.skip_sized();
      return f.ok() && f.left() == 0;
    case kDataEnd: return len == 4;
    default: return false;
  }
}

size_t Read::resync(size_t from) {
  drain();
  for (size_t q = from; q + kRecordHead <= bytes_.size(); ++q) {
    const uint8_t op = bytes_[q];
    if ((op >= kSchema && op <= kMessageIndex) || op == kMetadata || op == kDataEnd) {
      if (plausible(q)) return q;
    }
  }
  return bytes_.size();
}

void Read::find_data_end() {
  const auto bytes = bytes_;
  const size_t tail = kRecordHead + kFooterContent + sizeof(kMagic);
  if (bytes.size() < sizeof(kMagic) + tail ||
      std::memcmp(bytes.data() + bytes.size() - sizeof(kMagic), kMagic, sizeof(kMagic)) != 0) {
    return;
  }
  const uint8_t* f = bytes.data() + bytes.size() - tail;
  if (f[0] != kFooter || le<uint64_t>(f + 1) != kFooterContent) return;
  const uint64_t summary_start = le<uint64_t>(f + kRecordHead);
  // A summary start inside the magic or past the footer is damage (its Data End cannot be found).
  const uint64_t end = summary_start != 0 ? summary_start : bytes.size() - tail;  // the Data End's end
  const bool where_it_can_be = end >= sizeof(kMagic) + 13 && end <= bytes.size() - tail;
  const uint64_t at = where_it_can_be ? end - 13 : 0;
  if (where_it_can_be && at >= sizeof(kMagic) && at + 13 <= bytes.size() && bytes[at] == kDataEnd &&
      le<uint64_t>(bytes.data() + at + 1) == 4) {
    data_end_at_ = at;
    want_data_crc_ = le<uint32_t>(bytes.data() + at + kRecordHead);
  }
}

void Read::crc_to(uint64_t end) {
  if (want_data_crc_ == 0 || end <= crc_done_ || crc_done_ > data_end_at_) return;
  crc_done_ = std::min<uint64_t>(end, data_end_at_);
}

void Read::send_crc() {
  if (crc_done_ <= crc_sent_) return;
  Step st;
  st.kind = Step::kCrc;
  st.bytes = bytes_.subspan(crc_sent_, crc_done_ - crc_sent_);
  batch_.push_back(std::move(st));
  crc_sent_ = crc_done_;
}

void Read::chunk(std::span<const uint8_t> c, uint64_t where, uint64_t end, bool cut) {
  Fields f(c);
  f.get<uint64_t>();  // message_start_time
  f.get<uint64_t>();  // message_end_time
  const uint64_t uncompressed_size = f.get<uint64_t>();
  const uint32_t crc = f.get<uint32_t>();
  const std::string_view compression = f.str();
  const uint64_t records_len = f.get<uint64_t>();
  if (!f.ok()) {
    problem(where, "a chunk whose fields do not parse");
    return;
  }
  std::span<const uint8_t> records = c.subspan(f.pos());
  if (records_len < records.size()) {
    records = records.first(records_len);
  } else if (records_len > records.size() && !cut) {
    problem(where, "a chunk whose records (" + std::to_string(records_len) + " bytes) run past the record");
    return;
  }
  Step st;
  st.kind = Step::kChunk;
  st.where = where;
  st.end = end;
  st.cut = cut;
  if (compression.empty()) {
    if (!cut && (crc != 0 || want_data_crc_ != 0)) {
      // One pass serves both CRCs: the chunk's, and the data section's (combined in, as zlib allows).
      const uint32_t got = crc32_of(records);
      if (crc != 0 && got != crc) st.what = "its records fail their CRC";
      const auto at = static_cast<uint64_t>(records.data() - bytes_.data());
      if (want_data_crc_ != 0 && crc_done_ <= at && at + records.size() <= data_end_at_) {
        crc_to(at);
        send_crc();
        Step known;
        known.kind = Step::kCrc;
        known.bytes = records;
        known.crc = got;
        known.crc_known = true;
        batch_.push_back(std::move(known));
        crc_done_ = crc_sent_ = at + records.size();
      }
    }
  } else {
    Codec codec;
    if (compression == "zstd") {
      codec = Codec::kZstd;
    } else if (compression == "lz4") {
      codec = Codec::kLz4Frame;
    } else {
      problem(where, "a chunk compressed with \"" + std::string(compression) + "\", which is not known " +
                         "(MCAP's are zstd and lz4); its messages are left out");
      return;
    }
    // A chunk declaring more than its bytes can honestly hold, or past what the whole file may decode to, is
    // refused before anything is decoded (one line); a chunk decodes to its declared size at most.
    if (budget_spent_) return;  // said once, at the chunk that went past it
    std::string refused = block_size_problem(records.size(), uncompressed_size);
    if (refused.empty()) {
      refused = budget_.take(uncompressed_size);
      budget_spent_ = !refused.empty();
    }
    if (!refused.empty()) {
      problem(where, "chunk: " + refused);
      return;
    }
    Unzip u;
    u.in = records;
    u.codec = codec;
    u.size = uncompressed_size;
    u.crc = crc;
    // The stored bytes' CRC, for the data section's, by the worker that reads them anyway.
    const auto at = static_cast<uint64_t>(records.data() - bytes_.data());
    if (!cut && want_data_crc_ != 0 && crc_done_ <= at && at + records.size() <= data_end_at_) {
      crc_to(at);
      send_crc();
      u.in_crc_wanted = true;
      crc_done_ = crc_sent_ = at + records.size();
    }
    st.unzip = decompress(std::move(u));
  }
  st.bytes = records;
  if (!cut) {  // the data section's CRC through this record, computed before its records are parsed
    crc_to(end);
    send_crc();
  }
  batch_.push_back(std::move(st));
  flush();
}

bool Read::summary_record(uint8_t op, uint64_t pos, std::span<const uint8_t> content, uint64_t summary_start) {
  if (op == kStatistics) {
    Fields f(content);
    found_.statistics.message_count = f.get<uint64_t>();
    f.get<uint16_t>();
    f.get<uint32_t>();
    f.get<uint32_t>();
    f.get<uint32_t>();
    f.get<uint32_t>();
    f.get<uint64_t>();
    f.get<uint64_t>();
    const uint32_t n = f.get<uint32_t>();
    for (uint32_t i = 0; f.ok() && i + 10 <= n; i += 10) {
      const auto id = f.get<uint16_t>();
      found_.statistics.channel_message_counts[id] = f.get<uint64_t>();
    }
    found_.has_statistics = f.ok();
  } else if (op == kFooter && content.size() == kFooterContent) {
    const uint32_t want = le<uint32_t>(content.data() + 16);
    if (want != 0 && summary_start != 0 && summary_start <= pos) {
      const uint32_t got = crc32_of(bytes_.subspan(summary_start, pos + kRecordHead + 16 - summary_start));
      if (got != want) problem(pos, "the summary fails its CRC (" + hex32(got) + ", not " + hex32(want) + ")");
    }
    return false;
  }
  return true;
}

void Read::produce() {
  const auto bytes = bytes_;
  find_data_end();
  size_t pos = sizeof(kMagic);
  bool in_summary = false;
  uint64_t summary_start = 0;
  while (pos < bytes.size()) {
    if (bytes.size() - pos < kRecordHead) {
      problem(pos, in_summary ? "the file ends inside its summary (every message was read)"
                              : "the file ends inside a record's opcode and length");
      break;
    }
    const uint8_t op = bytes[pos];
    const auto len = le<uint64_t>(bytes.data() + pos + 1);
    const bool cut = len > bytes.size() - pos - kRecordHead;
    if (op == kFooter && !in_summary) break;  // the end of a file without summary (or Data End)
    if ((op == 0 || cut) && in_summary) {     // a damaged summary: the messages are all read already
      problem(pos, cut ? "the file ends inside its summary (every message was read)"
                       : "the summary is damaged here (every message was read)");
      break;
    }
    if (op == 0 || cut) {
      // A record running past the end is the file cut inside it, unless a readable record follows: then its
      // length (or opcode) is damaged and reading goes on there.
      const size_t next = resync(pos + 1);
      if (op != 0 && next == bytes.size()) {
        problem(pos, "the file ends inside this record (" + std::to_string(bytes.size() - pos - kRecordHead) +
                         " of its " + std::to_string(len) + " bytes)");
        if (op == kChunk) chunk(bytes.subspan(pos + kRecordHead), pos, bytes.size(), true);
        break;
      }
      problem(pos, (op == 0 ? std::string("opcode 0, not a record") : "a record length of " + std::to_string(len)) +
                       (next < bytes.size() ? "; " + std::to_string(next - pos) + " bytes skipped"
                                            : "; nothing readable after it"));
      pos = next;
      continue;
    }
    const auto content = bytes.subspan(pos + kRecordHead, len);
    const size_t end = pos + kRecordHead + len;
    if (in_summary) {
      if (!summary_record(op, pos, content, summary_start)) break;
      pos = end;
      continue;
    }
    switch (op) {
      case kHeader: {
        Fields f(content);
        found_.profile = f.str();
        found_.library = f.str();
        break;
      }
      case kSchema:
      case kChannel:
      case kMessage:
      case kMetadata: record(op, pos, end, content); break;
      case kChunk: chunk(content, pos, end, false); break;
      case kDataEnd: {
        crc_to(pos);
        if (want_data_crc_ != 0 && pos == data_end_at_) {
          send_crc();
          Step st;
          st.kind = Step::kDataEnd;
          st.where = pos;
          st.crc = want_data_crc_;
          batch_.push_back(std::move(st));
        }
        in_summary = true;
        summary_start = end;
        break;
      }
      default: break;  // indexes, attachments, records of later versions and private ones: not needed here
    }
    crc_to(end);
    pos = end;
  }
  flush();
}

void Read::work(size_t k) {
  const std::string name = "mcap-unzip" + std::to_string(k);  // its own line in top and perf
  pthread_setname_np(pthread_self(), name.c_str());
  Decompressor d;
  for (;;) {
    Unzip* u = nullptr;
    {
      std::unique_lock lk(mu_);
      cv_.wait(lk, [&] { return stopped_ || !todo_.empty(); });
      if (todo_.empty()) return;
      u = todo_.front();
      todo_.pop_front();
    }
    unzip(*u, d);
    {
      std::lock_guard lk(mu_);
      u->done = true;
    }
    cv_.notify_all();
  }
}

int64_t Read::run() {
  if (!threaded_) {
    produce();
    return delivered_;
  }
  return run_threaded();
}

int64_t Read::run_threaded() {
  std::vector<std::thread> workers;
  std::thread reader;
  // However the read ends (a callback may throw), the threads are stopped and joined.
  auto stop_threads = [&] {
    {
      std::lock_guard lk(mu_);
      stopped_ = true;
    }
    cv_.notify_all();
    if (reader.joinable()) reader.join();
    for (auto& w : workers) w.join();
    workers.clear();
  };
  try {
    for (size_t k = 0; k < kWorkers; ++k) workers.emplace_back([this, k] { work(k); });
    reader = std::thread([this] {
      pthread_setname_np(pthread_self(), "mcap-read");
      std::exception_ptr e;
      try {
        produce();
      } catch (const Stopped&) {
      } catch (...) {
        e = std::current_exception();
      }
      std::lock_guard lk(mu_);
      failure_ = e;
      finished_ = true;
      cv_.notify_all();
    });
  } catch (const std::system_error&) {  // no threads to be had: read on this one
    stop_threads();
    stopped_ = false;
    threaded_ = false;
    produce();
    return delivered_;
  }
  struct Join {
    const std::function<void()>& stop;
    ~Join() { stop(); }
  };
  const std::function<void()> stop = stop_threads;
  Join join{stop};
  for (;;) {
    Batch b;
    {
      std::unique_lock lk(mu_);
      cv_.wait(lk, [&] { return !queue_.empty() || finished_; });
      if (queue_.empty()) break;
      b = std::move(queue_.front());
      queue_.pop_front();
      cv_.notify_all();
    }
    consume(b);
    std::lock_guard lk(mu_);
    recycle(b);
    ++done_;
    cv_.notify_all();
  }
  std::lock_guard lk(mu_);
  if (failure_) std::rethrow_exception(failure_);
  return delivered_;
}

}  // namespace

int64_t McapReader::read(const std::function<void(const McapMessage&)>& on_message,
                         const std::function<void(const McapProblem&)>& on_problem,
                         const std::function<void(const McapMetadata&)>& on_metadata) {
  has_statistics_ = false;
  statistics_ = {};
  Read r(bytes_, *impl_, file_, pipelined_, {profile_, library_, statistics_, has_statistics_}, on_message, on_problem,
         on_metadata);
  return r.run();
}

}  // namespace driftlab::formats
