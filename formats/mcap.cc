// MCAP, written from the specification (mcap.dev/spec): "\x89MCAP0\r\n", then records, each
//   uint8 opcode, uint64 content length, content;
// little-endian integers, strings and maps prefixed with a uint32 byte length. The data section ends with Data End
// (0x0F, a CRC of every byte before it); the optional summary repeats schemas and channels and indexes the chunks;
// the Footer (0x02) points at the summary and carries its CRC; the magic closes the file.
#include "formats/mcap.h"

#include <fcntl.h>
#include <isa-l/crc.h>
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

namespace driftlab::formats {
namespace {

constexpr uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
enum Op : uint8_t {
  kHeader = 0x01, kFooter = 0x02, kSchema = 0x03, kChannel = 0x04, kMessage = 0x05, kChunk = 0x06,
  kMessageIndex = 0x07, kChunkIndex = 0x08, kAttachment = 0x09, kAttachmentIndex = 0x0A, kStatistics = 0x0B,
  kMetadata = 0x0C, kMetadataIndex = 0x0D, kSummaryOffset = 0x0E, kDataEnd = 0x0F,
};
constexpr size_t kRecordHead = 9;      // opcode + uint64 length
constexpr size_t kFooterContent = 20;  // summary_start, summary_offset_start, summary_crc

/// CRC-32 (zlib's, as MCAP asks) by Intel's ISA-L (Debian's libisal), which folds with the CPU's carry-less
/// multiply, 512 bits at a time where the CPU has VPCLMULQDQ: 10.5 GB/s here on a 4 MiB buffer, against 4.3 for
/// libdeflate 1.14 and 1.4 for zlib 1.2 in the same run (with libdeflate, the CRCs of the records and of the data
/// section were 8% of a zstd MCAP import's CPU time). zlib still combines.
uint32_t crc32_of(std::span<const uint8_t> b, uint32_t crc = 0) { return crc32_gzip_refl(crc, b.data(), b.size()); }

template <typename T>
T le(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;  // MCAP is little endian, as is every machine driftlab builds for (checked below)
}
static_assert(std::endian::native == std::endian::little, "MCAP's integers are read in place");

/// A cursor over a record's content; every read checks the bounds, and a failed read makes the cursor bad.
class Fields {
 public:
  explicit Fields(std::span<const uint8_t> b) : b_(b) {}
  bool ok() const { return ok_; }
  size_t pos() const { return pos_; }
  size_t left() const { return b_.size() - pos_; }
  template <typename T>
  T get() {
    if (!need(sizeof(T))) return T{};
    T v = le<T>(b_.data() + pos_);
    pos_ += sizeof(T);
    return v;
  }
  std::string_view str() {
    const uint32_t n = get<uint32_t>();
    if (!need(n)) return {};
    std::string_view s(reinterpret_cast<const char*>(b_.data() + pos_), n);
    pos_ += n;
    return s;
  }
  std::span<const uint8_t> bytes(uint64_t n) {
    if (!need(n)) return {};
    auto s = b_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  std::vector<std::pair<std::string, std::string>> string_map() {
    std::vector<std::pair<std::string, std::string>> m;
    const uint32_t n = get<uint32_t>();
    if (!need(n)) return m;
    Fields inner(b_.subspan(pos_, n));
    pos_ += n;
    while (inner.ok() && inner.left() > 0) {
      std::string k(inner.str());
      std::string v(inner.str());
      if (inner.ok()) m.emplace_back(std::move(k), std::move(v));
    }
    if (!inner.ok()) ok_ = false;
    return m;
  }
  /// Skips a Map or Array (uint32 byte length, then the entries).
  void skip_sized() {
    const uint32_t n = get<uint32_t>();
    bytes(n);
  }

 private:
  bool need(uint64_t n) {
    if (!ok_ || n > left()) {
      ok_ = false;
      return false;
    }
    return true;
  }
  std::span<const uint8_t> b_;
  size_t pos_ = 0;
  bool ok_ = true;
};

std::string hex32(uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%08x", v);
  return buf;
}

}  // namespace

struct McapReader::Impl {
  std::map<uint16_t, std::unique_ptr<McapSchema>> schemas;
  std::map<uint16_t, std::unique_ptr<McapChannel>> channels;
  Decompressor decompressor;  // the reading half's, when the read is not pipelined (workers have their own)
};

McapReader::McapReader() : impl_(std::make_unique<Impl>()) {}
McapReader::McapReader(McapReader&&) noexcept = default;
McapReader& McapReader::operator=(McapReader&&) noexcept = default;
McapReader::~McapReader() = default;

bool McapReader::looks_like(std::span<const uint8_t> head) {
  return head.size() >= 5 && std::memcmp(head.data(), kMagic, 5) == 0;
}

Result<McapReader> McapReader::check(const std::string& name, std::span<const uint8_t> bytes) {
  if (!looks_like(bytes)) return Error(name + ": not an MCAP file (no MCAP magic)");
  if (bytes.size() < sizeof(kMagic) || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    return Error(name + ": MCAP major version " + std::string(1, static_cast<char>(bytes.size() > 5 ? bytes[5] : '?')) +
                 " is not supported (0 is)");
  }
  McapReader r;
  r.bytes_ = bytes;
  return r;
}

Result<McapReader> McapReader::open(const std::string& path) {
  auto file = MappedFile::open(path);
  if (!file) return file.error();
  auto r = check(path, file->bytes());
  if (r) r->file_ = std::move(*file);
  return r;
}

Result<McapReader> McapReader::from_memory(std::span<const uint8_t> bytes) { return check("mcap", bytes); }

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

constexpr size_t kMaxBatches = 2;        // batches waiting for the calling thread
constexpr size_t kWorkers = 2;           // threads decompressing chunks (two chunks at once)
constexpr size_t kMaxDecompressed = 4;   // chunks being decompressed, waiting or being parsed
// The declared sizes of the chunks held at once (at least one): honest large chunks are not decoded several at once.
constexpr uint64_t kMaxInFlightBytes = uint64_t{256} << 20;
constexpr size_t kMaxBatchSteps = 4096;  // records outside chunks per batch

}  // namespace

void McapReader::set_pipelined(bool on) { pipelined_ = on; }

// The read is two halves joined by a bounded queue of batches of Steps. The reading half walks the data section's
// records and hands each compressed chunk to a worker, which decompresses it, checks its records' CRC and computes
// the CRC of its stored bytes for the data section's (kWorkers of them: two chunks decompressed at once, a few
// ahead of the calling thread); an uncompressed chunk's CRC the reading half checks itself, in the pass that serves
// the data section's too. The converting half (the calling thread) waits for each chunk's decompression in file
// order, checks the data section's CRC, parses the records of chunks, keeps schemas and channels, and runs every
// callback in file order. Pipelined, the reading half and the workers run on threads of their own; otherwise the
// reading half decompresses each chunk itself and hands each batch over by calling the converting half directly.
// Either way the callbacks see the same calls in the same order.
// Hand-off (what a race detector would check): the queue, the slots' free list and `todo`, each slot's `done`, the
// counters and the flags are touched only under `mu`. A Step's bytes are written by the reading half before it is
// queued and read by the calling thread after it is dequeued (the mutex orders them); a slot's input is written by
// the reading half before it is queued in `todo`, its results by a worker before `done` is set, and read by the
// calling thread after it saw `done`, and it goes back to the free list under `mu` too. The file's bytes are only
// read (release_before() only on the calling thread). The schemas, channels and the data section's running CRC
// are the calling thread's, except that resync() reads the channels after drain() has waited, under `mu`, for every
// batch queued to be done, while the calling thread waits for more. The reading half alone uses
// profile_/library_/statistics_, which the caller reads after the threads are joined.
int64_t McapReader::read(const std::function<void(const McapMessage&)>& on_message,
                         const std::function<void(const McapProblem&)>& on_problem,
                         const std::function<void(const McapMetadata&)>& on_metadata) {
  const auto bytes = bytes_;
  Impl& s = *impl_;
  int64_t delivered = 0;
  has_statistics_ = false;
  statistics_ = {};

  // --- What the halves share (under `mu` when threaded) ----------------------------------------------------------

  bool threaded = pipelined_;
  std::mutex mu;
  std::condition_variable cv;  // every thread waits on it (several threads: notify_all)
  std::deque<Batch> queue;
  // The decompressions: kMaxDecompressed slots, free or held by a chunk's Step from the reading half taking one to
  // the calling thread giving it back; a worker takes those queued in `todo`.
  std::vector<std::unique_ptr<Unzip>> slots;
  std::vector<Unzip*> free_slots;
  uint64_t in_flight = 0;             // the declared sizes of the chunks in the slots taken
  DecodeBudget budget(bytes.size());  // the reading half's
  bool budget_spent = false;
  for (size_t i = 0; i < kMaxDecompressed; ++i) {
    slots.push_back(std::make_unique<Unzip>());
    free_slots.push_back(slots.back().get());
  }
  std::deque<Unzip*> todo;
  uint64_t pushed = 0, done = 0;
  bool finished = false, stopped = false;
  std::exception_ptr failure;

  // --- The converting half (the calling thread) ---------------------------------------------------------------

  auto schema = [&](std::span<const uint8_t> c, uint64_t where) {
    Fields f(c);
    McapSchema sc;
    sc.id = f.get<uint16_t>();
    sc.name = f.str();
    sc.encoding = f.str();
    sc.data = std::string(f.str());  // uint32-prefixed bytes: same layout as a string
    if (!f.ok()) {
      on_problem({where, "a schema record that does not parse"});
      return;
    }
    if (sc.id == 0 || s.schemas.count(sc.id)) return;  // id 0 is invalid; repeats must be identical
    s.schemas.emplace(sc.id, std::make_unique<McapSchema>(std::move(sc)));
  };
  auto channel = [&](std::span<const uint8_t> c, uint64_t where) {
    Fields f(c);
    McapChannel ch;
    ch.id = f.get<uint16_t>();
    ch.schema_id = f.get<uint16_t>();
    ch.topic = f.str();
    ch.message_encoding = f.str();
    ch.metadata = f.string_map();
    if (!f.ok()) {
      on_problem({where, "a channel record that does not parse"});
      return;
    }
    if (s.channels.count(ch.id)) return;
    if (ch.schema_id != 0) {
      auto it = s.schemas.find(ch.schema_id);
      if (it == s.schemas.end()) {
        on_problem({where, "channel " + std::to_string(ch.id) + " (" + ch.topic + ") names schema " +
                               std::to_string(ch.schema_id) + ", which no record before it defines"});
      } else {
        ch.schema = it->second.get();
      }
    }
    s.channels.emplace(ch.id, std::make_unique<McapChannel>(std::move(ch)));
  };
  auto message = [&](std::span<const uint8_t> c, uint64_t where, int64_t in_chunk) {
    if (c.size() < 22) {
      on_problem({where, "a message record of " + std::to_string(c.size()) + " bytes, shorter than its fields" +
                             (in_chunk >= 0 ? " (at byte " + std::to_string(in_chunk) + " of the chunk)" : "")});
      return;
    }
    const auto id = le<uint16_t>(c.data());
    auto it = s.channels.find(id);
    if (it == s.channels.end()) {
      on_problem({where, "a message on channel " + std::to_string(id) + ", which no record before it defines" +
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
    on_message(m);
    ++delivered;
  };
  auto metadata = [&](std::span<const uint8_t> c, uint64_t where) {
    Fields f(c);
    McapMetadata md;
    md.name = f.str();
    md.entries = f.string_map();
    if (!f.ok()) {
      on_problem({where, "a metadata record that does not parse"});
      return;
    }
    if (on_metadata) on_metadata(md);
  };
  // A chunk's records, as the reading half made them ready.
  uint32_t data_crc = 0;  // of the data section's bytes handed over so far
  auto chunk_records = [&](const Step& st) {
    auto records = st.bytes;
    const uint64_t where = st.where;
    std::string_view what = st.what;
    if (Unzip* u = st.unzip) {
      if (threaded) {  // decompressed on a worker: wait for it
        std::unique_lock lk(mu);
        cv.wait(lk, [&] { return u->done; });
      }
      if (u->error) std::rethrow_exception(u->error);
      records = u->out;
      what = u->what;
      // Its stored bytes in the data section's CRC, where they come (the reading half sent what precedes them).
      if (u->in_crc_wanted) {
        data_crc = static_cast<uint32_t>(::crc32_combine(data_crc, u->in_crc, static_cast<z_off_t>(u->in.size())));
      }
    }
    if (!what.empty() && !st.cut) on_problem({where, "chunk: " + std::string(what)});
    size_t in = 0;
    while (in < records.size()) {
      if (records.size() - in < kRecordHead || le<uint64_t>(records.data() + in + 1) > records.size() - in - kRecordHead) {
        if (what.empty() && !st.cut) {
          on_problem({where, "chunk: a record cut off at byte " + std::to_string(in) + " of " +
                                 std::to_string(records.size())});
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
  };
  auto consume = [&](const Batch& batch) {
    for (const Step& st : batch) {
      switch (st.kind) {
        case Step::kProblem: on_problem({st.where, st.what}); break;
        case Step::kCrc:
          data_crc =
              st.crc_known
                  ? static_cast<uint32_t>(::crc32_combine(data_crc, st.crc, static_cast<z_off_t>(st.bytes.size())))
                  : crc32_of(st.bytes, data_crc);
          break;
        case Step::kDataEnd:
          if (data_crc != st.crc) {
            on_problem(
                {st.where, "the data section fails its CRC (" + hex32(data_crc) + ", not " + hex32(st.crc) + ")"});
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
  };

  // --- The hand-off -------------------------------------------------------------------------------------------

  Batch batch;  // the reading half's batch being filled

  // The calling thread is done with a batch: its decompression slots go back (under mu when threaded).
  auto recycle = [&](Batch& b) {
    for (Step& st : b) {
      if (st.unzip == nullptr) continue;
      st.unzip->done = false;
      st.unzip->error = nullptr;
      in_flight -= st.unzip->size;
      // A large chunk's buffer is not kept for the next (four slots of a 1 GiB chunk each would be 4 GiB).
      if (st.unzip->out.capacity() > kFreeBlockBytes) std::vector<uint8_t>().swap(st.unzip->out);
      free_slots.push_back(st.unzip);
    }
    b.clear();
  };
  auto flush = [&] {
    if (batch.empty()) return;
    if (!threaded) {
      consume(batch);
      recycle(batch);
      return;
    }
    std::unique_lock lk(mu);
    cv.wait(lk, [&] { return stopped || queue.size() < kMaxBatches; });
    if (stopped) throw Stopped{};
    queue.push_back(std::move(batch));
    ++pushed;
    batch = Batch();
    cv.notify_all();
  };
  // A slot to decompress a chunk in, once one is free; decompressed by a worker (pipelined) or here, at once.
  auto decompress = [&](Unzip u) -> Unzip* {
    std::unique_lock lk(mu, std::defer_lock);
    if (threaded) {
      lk.lock();
      cv.wait(lk, [&] {
        return stopped || (!free_slots.empty() && (in_flight == 0 || in_flight + u.size <= kMaxInFlightBytes));
      });
      if (stopped) throw Stopped{};
    }
    in_flight += u.size;
    Unzip* slot = free_slots.back();
    free_slots.pop_back();
    u.out.swap(slot->out);
    *slot = std::move(u);
    if (!threaded) {
      unzip(*slot, s.decompressor);
      slot->done = true;
      return slot;
    }
    todo.push_back(slot);
    cv.notify_all();
    return slot;
  };
  // Waits until the calling thread has done every batch handed over (and is waiting for the next).
  auto drain = [&] {
    flush();
    if (!threaded) return;
    std::unique_lock lk(mu);
    cv.wait(lk, [&] { return stopped || done == pushed; });
    if (stopped) throw Stopped{};
  };
  auto problem = [&](uint64_t where, std::string what) {
    Step st;
    st.kind = Step::kProblem;
    st.where = where;
    st.what = std::move(what);
    batch.push_back(std::move(st));
  };
  auto record = [&](uint8_t op, uint64_t where, uint64_t end, std::span<const uint8_t> content) {
    Step st;
    st.op = op;
    st.where = where;
    st.end = end;
    st.bytes = content;
    batch.push_back(std::move(st));
    if (batch.size() >= kMaxBatchSteps) flush();
  };

  // Whether a record whose content parses exactly starts at q (to find where reading can go on after damage).
  // Reads the channels: on the reading thread only after drain().
  auto plausible = [&](size_t q) -> bool {
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
        if (len < 22 || !s.channels.count(le<uint16_t>(bytes.data() + q + kRecordHead))) return false;
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
  };
  // --- The reading half ---------------------------------------------------------------------------------------

  auto produce = [&] {
    // The Data End record's CRC, known from the footer before reading: computed while reading only when it is set.
    uint32_t want_data_crc = 0;
    uint64_t data_end_at = 0;
    {
      const size_t tail = kRecordHead + kFooterContent + sizeof(kMagic);
      if (bytes.size() >= sizeof(kMagic) + tail &&
          std::memcmp(bytes.data() + bytes.size() - sizeof(kMagic), kMagic, sizeof(kMagic)) == 0) {
        const uint8_t* f = bytes.data() + bytes.size() - tail;
        if (f[0] == kFooter && le<uint64_t>(f + 1) == kFooterContent) {
          const uint64_t summary_start = le<uint64_t>(f + kRecordHead);
          // A summary start inside the magic or past the footer is damage (its Data End cannot be found).
          const uint64_t end = summary_start != 0 ? summary_start : bytes.size() - tail;  // the Data End's end
          const bool where_it_can_be = end >= sizeof(kMagic) + 13 && end <= bytes.size() - tail;
          const uint64_t at = where_it_can_be ? end - 13 : 0;
          if (where_it_can_be && at >= sizeof(kMagic) && at + 13 <= bytes.size() && bytes[at] == kDataEnd &&
              le<uint64_t>(bytes.data() + at + 1) == 4) {
            data_end_at = at;
            want_data_crc = le<uint32_t>(bytes.data() + at + kRecordHead);
          }
        }
      }
    }
    // The data section's CRC is the calling thread's to compute (this one has the decompression to do): the
    // bytes [0, crc_done) are to be in it, [0, crc_sent) of them are handed over already, in order.
    uint64_t crc_done = 0, crc_sent = 0;
    auto crc_to = [&](uint64_t end) {
      if (want_data_crc == 0 || end <= crc_done || crc_done > data_end_at) return;
      crc_done = std::min<uint64_t>(end, data_end_at);
    };
    auto send_crc = [&] {
      if (crc_done <= crc_sent) return;
      Step st;
      st.kind = Step::kCrc;
      st.bytes = bytes.subspan(crc_sent, crc_done - crc_sent);
      batch.push_back(std::move(st));
      crc_sent = crc_done;
    };

    auto chunk = [&](std::span<const uint8_t> c, uint64_t where, uint64_t end, bool cut) {
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
        if (!cut && (crc != 0 || want_data_crc != 0)) {
          // One pass serves both CRCs: the chunk's, and the data section's (combined in, as zlib allows).
          const uint32_t got = crc32_of(records);
          if (crc != 0 && got != crc) st.what = "its records fail their CRC";
          const auto at = static_cast<uint64_t>(records.data() - bytes.data());
          if (want_data_crc != 0 && crc_done <= at && at + records.size() <= data_end_at) {
            crc_to(at);
            send_crc();
            Step known;
            known.kind = Step::kCrc;
            known.bytes = records;
            known.crc = got;
            known.crc_known = true;
            batch.push_back(std::move(known));
            crc_done = crc_sent = at + records.size();
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
        if (budget_spent) return;  // said once, at the chunk that went past it
        std::string refused = block_size_problem(records.size(), uncompressed_size);
        if (refused.empty()) {
          refused = budget.take(uncompressed_size);
          budget_spent = !refused.empty();
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
        const auto at = static_cast<uint64_t>(records.data() - bytes.data());
        if (!cut && want_data_crc != 0 && crc_done <= at && at + records.size() <= data_end_at) {
          crc_to(at);
          send_crc();
          u.in_crc_wanted = true;
          crc_done = crc_sent = at + records.size();
        }
        st.unzip = decompress(std::move(u));
      }
      st.bytes = records;
      if (!cut) {  // the data section's CRC through this record, computed before its records are parsed
        crc_to(end);
        send_crc();
      }
      batch.push_back(std::move(st));
      flush();
    };

    auto resync = [&](size_t from) {
      drain();
      for (size_t q = from; q + kRecordHead <= bytes.size(); ++q) {
        const uint8_t op = bytes[q];
        if ((op >= kSchema && op <= kMessageIndex) || op == kMetadata || op == kDataEnd) {
          if (plausible(q)) return q;
        }
      }
      return bytes.size();
    };

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
        if (op == kStatistics) {
          Fields f(content);
          statistics_.message_count = f.get<uint64_t>();
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
            statistics_.channel_message_counts[id] = f.get<uint64_t>();
          }
          has_statistics_ = f.ok();
        } else if (op == kFooter && len == kFooterContent) {
          const uint32_t want = le<uint32_t>(content.data() + 16);
          if (want != 0 && summary_start != 0 && summary_start <= pos) {
            const uint32_t got = crc32_of(bytes.subspan(summary_start, pos + kRecordHead + 16 - summary_start));
            if (got != want) problem(pos, "the summary fails its CRC (" + hex32(got) + ", not " + hex32(want) + ")");
          }
          break;
        }
        pos = end;
        continue;
      }
      switch (op) {
        case kHeader: {
          Fields f(content);
          profile_ = f.str();
          library_ = f.str();
          break;
        }
        case kSchema:
        case kChannel:
        case kMessage:
        case kMetadata: record(op, pos, end, content); break;
        case kChunk: chunk(content, pos, end, false); break;
        case kDataEnd: {
          crc_to(pos);
          if (want_data_crc != 0 && pos == data_end_at) {
            send_crc();
            Step st;
            st.kind = Step::kDataEnd;
            st.where = pos;
            st.crc = want_data_crc;
            batch.push_back(std::move(st));
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
  };

  if (!threaded) {
    produce();
    return delivered;
  }
  // The workers: each decompresses the chunks queued in `todo`, one at a time, with a context of its own.
  auto work = [&](size_t k) {
    const std::string name = "mcap-unzip" + std::to_string(k);  // its own line in top and perf
    pthread_setname_np(pthread_self(), name.c_str());
    Decompressor d;
    for (;;) {
      Unzip* u = nullptr;
      {
        std::unique_lock lk(mu);
        cv.wait(lk, [&] { return stopped || !todo.empty(); });
        if (todo.empty()) return;
        u = todo.front();
        todo.pop_front();
      }
      unzip(*u, d);
      {
        std::lock_guard lk(mu);
        u->done = true;
      }
      cv.notify_all();
    }
  };
  std::vector<std::thread> workers;
  std::thread reader;
  // However the read ends (a callback may throw), the threads are stopped and joined.
  auto stop_threads = [&] {
    {
      std::lock_guard lk(mu);
      stopped = true;
    }
    cv.notify_all();
    if (reader.joinable()) reader.join();
    for (auto& w : workers) w.join();
    workers.clear();
  };
  try {
    for (size_t k = 0; k < kWorkers; ++k) workers.emplace_back(work, k);
    reader = std::thread([&] {
      pthread_setname_np(pthread_self(), "mcap-read");
      std::exception_ptr e;
      try {
        produce();
      } catch (const Stopped&) {
      } catch (...) {
        e = std::current_exception();
      }
      std::lock_guard lk(mu);
      failure = e;
      finished = true;
      cv.notify_all();
    });
  } catch (const std::system_error&) {  // no threads to be had: read on this one
    stop_threads();
    stopped = false;
    threaded = false;
    produce();
    return delivered;
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
      std::unique_lock lk(mu);
      cv.wait(lk, [&] { return !queue.empty() || finished; });
      if (queue.empty()) break;
      b = std::move(queue.front());
      queue.pop_front();
      cv.notify_all();
    }
    consume(b);
    std::lock_guard lk(mu);
    recycle(b);
    ++done;
    cv.notify_all();
  }
  std::lock_guard lk(mu);
  if (failure) std::rethrow_exception(failure);
  return delivered;
}

// ---------------------------------------------------------------------------------------------------------------

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
  Buf head;  // a chunk's fields and its message indexes on their way to the file
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
    return Error(file_path + ": " + what + (err ? std::string(": ") + std::strerror(err) : ""));
  }
  /// Keeps the first failure (the calling thread's side) and returns it.
  Status fail(const Status& st) {
    if (error.empty()) error = st.message();
    return Error(error);
  }
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
      std::stable_sort(entries.begin(), entries.end(),
                       [](const auto& a, const auto& b) { return a.first < b.first; });
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
    if (!io_error.empty()) return fail(Error(io_error));
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
    if (!io_error.empty()) return fail(Error(io_error));
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
  s.options = options;
  s.path = path;
  s.file_path = options.atomic ? path + ".partial" : path;
  s.fd = ::open(s.file_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (s.fd < 0) return Error(path + ": cannot create: " + std::strerror(errno));
  s.inline_packer.compressor = s.make_compressor();
  s.out.bytes(kMagic);
  const size_t at = s.out.begin_record(kHeader);
  s.out.str(options.profile);
  s.out.str(options.library);
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
  if (!s.error.empty()) return Error(s.error);
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
  if (!s.error.empty()) return Error(s.error);
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
  if (s.closed) return s.error.empty() ? Status{} : Status(Error(s.error));
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
