// MCAP, written from the specification (mcap.dev/spec): "\x89MCAP0\r\n", then records, each
//   uint8 opcode, uint64 content length, content;
// little-endian integers, strings and maps prefixed with a uint32 byte length. The data section ends with Data End
// (0x0F, a CRC of every byte before it); the optional summary repeats schemas and channels and indexes the chunks;
// the Footer (0x02) points at the summary and carries its CRC; the magic closes the file.
#include "formats/mcap.h"

#include <fcntl.h>
#include <libdeflate.h>
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

/// CRC-32 (zlib's, as MCAP asks) by libdeflate, which folds with the CPU's carry-less multiply: about 4 times zlib
/// 1.2's speed here (5.7 against 1.5 GB/s), where the CRCs were a fifth of an import's time. zlib still combines.
uint32_t crc32_of(std::span<const uint8_t> b, uint32_t crc = 0) { return libdeflate_crc32(crc, b.data(), b.size()); }

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
  Decompressor decompressor;  // the reading half's
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

/// One step of a read, in file order: a record outside chunks, a chunk's records (decompressed and checked), or a
/// problem the reading side found. Made by the reading side, handed to the calling thread.
struct Step {
  enum Kind : uint8_t { kRecord, kChunk, kProblem, kCrc, kDataEnd };
  Kind kind = kRecord;
  uint8_t op = 0;                  // kRecord: its opcode
  bool cut = false;                // kChunk: the file ends inside it
  uint64_t where = 0;              // the record's file offset
  uint64_t end = 0;                // kRecord, kChunk: the file offset after the record (0: none)
  std::span<const uint8_t> bytes;  // kRecord: its content; kChunk: its records, in the file or in buffer
  std::string what;                // kProblem: the problem; kChunk: what is wrong with it ("": nothing)
                                   // kCrc: (bytes) the data section's next bytes, for its CRC
  std::vector<uint8_t> buffer;     // kChunk: the decompressed records (a moved vector keeps its bytes in place)
  bool decompressed = false;       // kChunk: holds one of the decompression buffers
  uint32_t crc = 0;                // kChunk, decompressed whole: the CRC its records must have (0: none);
                                   // kCrc with crc_known: that of bytes; kDataEnd: the data section's
  bool crc_known = false;          // kCrc: bytes (the data section's next bytes) are not to be read again
};
using Batch = std::vector<Step>;

/// Thrown on the reading thread when the calling thread stopped (a callback threw): unwinds it.
struct Stopped {};

constexpr size_t kMaxBatches = 2;        // batches waiting for the calling thread
constexpr int kMaxDecompressed = 3;      // decompressed chunks alive: one being filled, two waiting or parsed
constexpr size_t kMaxBatchSteps = 4096;  // records outside chunks per batch

}  // namespace

void McapReader::set_pipelined(bool on) { pipelined_ = on; }

// The read is two halves joined by a bounded queue of batches of Steps. The reading half walks the data section's
// records and decompresses chunks; the converting half (the calling thread) checks the CRCs of decompressed chunks
// and of the data section (the reading half has the decompression to do; it checks an uncompressed chunk's, in
// the pass that serves the data section's too), parses the records of chunks, keeps schemas and channels, and
// runs every callback in file order. Pipelined, the reading half runs on a thread of its own, a few chunks ahead;
// otherwise it hands each batch over by calling the converting half directly. Either way the callbacks see the
// same calls in the same order.
// Hand-off (what a race detector would check): the queue, the spare decompression buffers, the counters and the
// flags are touched only under `mu`. A Step's bytes are written by the reading half before it is queued and read
// by the calling thread after it is dequeued (the mutex orders them); buffers go back through `spare` the same
// way. The file's bytes are only read (release_before() only on the calling thread). The schemas, channels and
// the data section's running CRC are the calling thread's, except that resync() reads the channels after drain()
// has waited, under `mu`, for every batch queued to be done, while the calling thread waits for more. The reading
// half alone uses the decompressor and profile_/library_/statistics_, which the caller reads after the thread is
// joined.
int64_t McapReader::read(const std::function<void(const McapMessage&)>& on_message,
                         const std::function<void(const McapProblem&)>& on_problem,
                         const std::function<void(const McapMetadata&)>& on_metadata) {
  const auto bytes = bytes_;
  Impl& s = *impl_;
  int64_t delivered = 0;
  has_statistics_ = false;
  statistics_ = {};

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
  auto chunk_records = [&](const Step& st) {
    const auto records = st.bytes;
    const uint64_t where = st.where;
    std::string_view what = st.what;
    if (st.crc != 0 && crc32_of(records) != st.crc) what = "its records fail their CRC";
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
  uint32_t data_crc = 0;  // of the data section's bytes handed over so far
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

  bool threaded = pipelined_;
  std::mutex mu;
  std::condition_variable cv;  // both sides wait on it (two threads: notify_all)
  std::deque<Batch> queue;
  std::vector<std::vector<uint8_t>> spare;  // decompression buffers back from the calling thread
  int decompressed_alive = 0;
  uint64_t pushed = 0, done = 0;
  bool finished = false, stopped = false;
  std::exception_ptr failure;
  Batch batch;  // the reading half's batch being filled

  // The calling thread is done with a batch: its decompression buffers go back (under mu when threaded).
  auto recycle = [&](Batch& b) {
    for (Step& st : b) {
      if (!st.decompressed) continue;
      spare.push_back(std::move(st.buffer));
      --decompressed_alive;
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
  // A buffer to decompress a chunk into, once fewer than kMaxDecompressed are alive.
  auto take_buffer = [&] {
    std::unique_lock lk(mu, std::defer_lock);
    if (threaded) {
      lk.lock();
      cv.wait(lk, [&] { return stopped || decompressed_alive < kMaxDecompressed; });
      if (stopped) throw Stopped{};
    }
    ++decompressed_alive;
    std::vector<uint8_t> b;
    if (!spare.empty()) {
      b = std::move(spare.back());
      spare.pop_back();
    }
    return b;
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
        // A size beyond what the compressed bytes can expand to is a lie: do not allocate for it.
        const size_t hint = plausible_size(records.size(), uncompressed_size) ? uncompressed_size : 0;
        st.buffer = take_buffer();
        st.decompressed = true;
        st.what = s.decompressor.run(codec, records, hint, st.buffer);
        records = st.buffer;
        if (st.what.empty() && records.size() != uncompressed_size) {
          st.what = "its records decompress to " + std::to_string(records.size()) + " bytes, not " +
                    std::to_string(uncompressed_size);
        } else if (st.what.empty()) {
          st.crc = crc;  // checked by the calling thread, which has less to do than this one
        }
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
  std::thread reader;
  try {
    reader = std::thread([&] {
      pthread_setname_np(pthread_self(), "mcap-read");  // its own line in top and perf
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
  } catch (const std::system_error&) {  // no thread to be had: read on this one
    threaded = false;
    produce();
    return delivered;
  }
  // However the calling side ends (a callback may throw), the reading thread is stopped and joined.
  struct Join {
    std::thread& t;
    std::mutex& mu;
    std::condition_variable& cv;
    bool& stopped;
    ~Join() {
      {
        std::lock_guard lk(mu);
        stopped = true;
      }
      cv.notify_all();
      t.join();
    }
  } join{reader, mu, cv, stopped};
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

class Buf {
 public:
  std::vector<uint8_t>& v() { return b_; }
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
  std::vector<uint8_t> b_;
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

// The writer is two halves too: the calling thread builds a chunk's records; a thread of the writer's own
// compresses each closed chunk, computes its CRCs and writes it with its message indexes, while the next one fills.
// Bytes outside chunks (the header, metadata) go the same way, so the file is written in order. Hand-off: `jobs`,
// `busy`, `stop`, `spare` and `io_error` only under `mu`; a Job's bytes are the calling thread's until queued and
// the writing thread's after it takes them (mu orders both); while the writing thread runs, only it touches the
// writing side's fields (fd, flushed, crc, the compressor, the indexes), and the calling thread reads them after
// joining it (close) or after waiting under mu for it to be idle (bytes()).
struct McapWriter::Impl {
  McapWriteOptions options;
  std::string path, file_path;
  std::string error;  // the first failure, as the calling thread knows it
  Buf out;            // the calling thread's bytes outside chunks, not yet handed on

  // The writing side.
  int fd = -1;
  uint64_t flushed = 0;
  uint32_t crc = 0;    // of every byte of the file so far (the data section, until Data End)
  std::unique_ptr<Compressor> compressor;
  std::vector<uint8_t> compressed;
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

  /// What goes to the writing thread: a closed chunk, or bytes written as they are (a Metadata record, indexed).
  struct Job {
    std::vector<uint8_t> bytes;  // the chunk's records, or the bytes
    bool chunk = false;
    uint64_t start = 0, end = 0;  // the chunk's log times
    uint32_t records_crc = 0;     // the chunk's records' CRC, computed by the calling thread (less busy)
    std::map<uint16_t, std::vector<std::pair<uint64_t, uint64_t>>> index;
    bool is_metadata = false;
    std::string metadata;  // its name
  };
  static constexpr size_t kMaxJobs = 2;  // queued or being written: with the open chunk, three chunks in memory
  std::thread thread;
  std::mutex mu;
  std::condition_variable cv;
  std::deque<Job> jobs;
  bool busy = false, stop = false;
  std::string io_error;
  std::vector<std::vector<uint8_t>> spare;  // chunk buffers back from the writing thread, for the next chunks

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

  /// Compresses a closed chunk and writes it with its message indexes. Writing side.
  Status write_chunk(Job& j) {
    const auto& records = j.bytes;
    const uint32_t records_crc = j.records_crc;
    std::span<const uint8_t> payload = records;
    const char* compression = "";
    if (compressor) {
      if (std::string e = compressor->run(records, compressed); !e.empty()) return io_failure(e, 0);
      payload = compressed;
      compression = options.compression == McapCompression::kZstd ? "zstd" : "lz4";
    }
    ChunkIndexEntry ci{};
    ci.start = j.start;
    ci.end = j.end;
    ci.offset = flushed;
    ci.compressed = payload.size();
    ci.uncompressed = records.size();
    // The chunk's head through the buffer, its records straight from memory (no copy; for uncompressed records
    // the CRC already computed serves the file's too).
    const uint64_t content = 8 + 8 + 8 + 4 + 4 + std::strlen(compression) + 8 + payload.size();
    head.u8(kChunk);
    head.put(content);
    head.put(j.start);
    head.put(j.end);
    head.put<uint64_t>(records.size());
    head.put(records_crc);
    head.str(compression);
    head.put<uint64_t>(payload.size());
    if (Status st = flush(head); !st) return st;
    if (Status st = write_direct(payload, compressor ? crc32_of(payload) : records_crc); !st) return st;
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
  Status write_job(Job& j) {
    if (j.chunk) return write_chunk(j);
    if (j.is_metadata) metadata_indexes.push_back({flushed, j.bytes.size(), std::move(j.metadata)});
    return write_direct(j.bytes, crc32_of(j.bytes));
  }
  /// The writing thread: jobs in order until stopped and none is left; after a failure nothing more is written.
  void run() {
    pthread_setname_np(pthread_self(), "mcap-write");  // its own line in top and perf
    for (;;) {
      Job j;
      bool failed = false;
      {
        std::unique_lock lk(mu);
        cv.wait(lk, [&] { return !jobs.empty() || stop; });
        if (jobs.empty()) return;
        j = std::move(jobs.front());
        jobs.pop_front();
        busy = true;
        failed = !io_error.empty();
      }
      Status st;
      try {
        if (!failed) st = write_job(j);
      } catch (const std::exception& e) {
        st = io_failure(e.what(), 0);
      }
      std::lock_guard lk(mu);
      if (!st && io_error.empty()) io_error = st.message();
      if (j.chunk) {
        j.bytes.clear();
        spare.push_back(std::move(j.bytes));
      }
      busy = false;
      cv.notify_all();
    }
  }
  /// Hands a job on, once fewer than kMaxJobs are queued or being written (written here without a thread).
  Status push(Job&& j) {
    if (!thread.joinable()) {
      if (Status st = write_job(j); !st) return fail(st);
      if (j.chunk) {
        j.bytes.clear();
        spare.push_back(std::move(j.bytes));
      }
      return {};
    }
    std::unique_lock lk(mu);
    cv.wait(lk, [&] { return jobs.size() + (busy ? 1 : 0) < kMaxJobs; });
    if (!io_error.empty()) return fail(Error(io_error));
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
      if (thread.joinable()) lk.lock();
      if (!spare.empty()) {
        chunk.v().swap(spare.back());
        spare.pop_back();
      }
    }
    return push(std::move(j));
  }
  /// Lets the writing thread write everything handed on, and joins it.
  Status finish() {
    if (thread.joinable()) {
      {
        std::lock_guard lk(mu);
        stop = true;
      }
      cv.notify_all();
      thread.join();
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
  if (options.compression == McapCompression::kZstd) {
    s.compressor = std::make_unique<Compressor>(Codec::kZstd, options.level);
  } else if (options.compression == McapCompression::kLz4) {
    s.compressor = std::make_unique<Compressor>(Codec::kLz4Frame, options.level);
  }
  s.out.bytes(kMagic);
  const size_t at = s.out.begin_record(kHeader);
  s.out.str(options.profile);
  s.out.str(options.library);
  s.out.end_record(at);
  try {
    s.thread = std::thread([impl = &s] { impl->run(); });
  } catch (const std::system_error&) {  // no thread to be had: chunks are written on the calling thread
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
  Impl& s = *impl_;
  if (!s.error.empty()) return Error(s.error);
  if (channel_id >= s.channels.size()) std::abort();  // a broken invariant: channels come from add_channel
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
  s.chunk.bytes(data);
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
  if (!s.thread.joinable()) return s.offset();
  std::unique_lock lk(s.mu);  // what was handed on, once written
  s.cv.wait(lk, [&] { return s.jobs.empty() && !s.busy; });
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
