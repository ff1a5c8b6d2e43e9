// PX4's ULog, written from PX4's "ULog File Format" specification (docs.px4.io, dev_log/ulog_file_format); no C++
// ULog library is packaged for Debian. Record types: B flag bits, F format, I info, M multi info, P parameter,
// Q parameter default, A add subscription, R remove subscription, D data, L logged string, C tagged logged
// string, S sync, O dropout. Every record starts with uint16_t size (of what follows the 3-byte header) and a type
// byte.
#include "formats/ulog.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <set>
#include <system_error>
#include <thread>
#include <vector>

namespace driftlab::formats {
namespace {

constexpr uint8_t kMagic[7] = {'U', 'L', 'o', 'g', 0x01, 0x12, 0x35};
constexpr uint8_t kSyncMagic[8] = {0x2F, 0x73, 0x13, 0x20, 0x25, 0x0C, 0xBB, 0x12};
constexpr size_t kHeaderSize = 16;
constexpr uint32_t kMaxMessage = 65535;  // a record's size is a uint16_t
/// Fields a resolved format may flatten into: one per byte of the largest message, and then some for empty
/// nested types (the bound keeps a hostile nesting of empty arrays from taking forever).
constexpr size_t kMaxFields = 1 << 17;
constexpr int kMaxDepth = 32;
/// The longest format or topic name [bytes]: PX4's are under 64; a longer one is damage.
constexpr size_t kMaxName = 255;
/// The bytes of a resolved format's flattened field names: PX4's largest take a few KB; the bound keeps a hostile
/// format (a long name in a nested type, in an array of 65535) from taking gigabytes.
constexpr size_t kMaxNameBytes = 1 << 20;

uint16_t le16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
uint32_t le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
}
uint64_t le64(const uint8_t* p) { return le32(p) | (static_cast<uint64_t>(le32(p + 4)) << 32); }

bool primitive(std::string_view t, UlogType* out, uint32_t* size) {
  static constexpr struct {
    std::string_view name;
    UlogType type;
    uint32_t size;
  } kPrimitives[] = {
      {"int8_t", UlogType::kInt8, 1},     {"uint8_t", UlogType::kUint8, 1},   {"int16_t", UlogType::kInt16, 2},
      {"uint16_t", UlogType::kUint16, 2}, {"int32_t", UlogType::kInt32, 4},   {"uint32_t", UlogType::kUint32, 4},
      {"int64_t", UlogType::kInt64, 8},   {"uint64_t", UlogType::kUint64, 8}, {"float", UlogType::kFloat, 4},
      {"double", UlogType::kDouble, 8},   {"bool", UlogType::kBool, 1},       {"char", UlogType::kChar, 1}};
  for (const auto& p : kPrimitives) {
    if (p.name == t) {
      *out = p.type;
      *size = p.size;
      return true;
    }
  }
  return false;
}

uint32_t size_of(UlogType t) {
  switch (t) {
    case UlogType::kInt8:
    case UlogType::kUint8:
    case UlogType::kBool:
    case UlogType::kChar: return 1;
    case UlogType::kInt16:
    case UlogType::kUint16: return 2;
    case UlogType::kInt32:
    case UlogType::kUint32:
    case UlogType::kFloat: return 4;
    case UlogType::kInt64:
    case UlogType::kUint64:
    case UlogType::kDouble: return 8;
  }
  return 1;
}

bool name_char(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }
bool is_name(std::string_view s) { return !s.empty() && std::all_of(s.begin(), s.end(), name_char); }
bool printable(std::span<const uint8_t> s) {
  return std::all_of(s.begin(), s.end(), [](uint8_t c) { return c >= 0x20 && c < 0x7f; });
}
std::string_view text_of(std::span<const uint8_t> s) { return {reinterpret_cast<const char*>(s.data()), s.size()}; }

struct FieldDecl {
  std::string type;
  std::string name;
  uint32_t count = 0;
  bool array = false;
};

/// "type name" or "type[n] name".
bool parse_field(std::string_view f, FieldDecl* out, std::string* why) {
  const size_t space = f.find(' ');
  if (space == std::string_view::npos) {
    *why = "field \"" + std::string(f) + "\" is not \"type name\"";
    return false;
  }
  std::string_view type = f.substr(0, space);
  const std::string_view name = f.substr(space + 1);
  if (!is_name(name)) {
    *why = "field \"" + std::string(f) + "\" has no name";
    return false;
  }
  out->array = false;
  out->count = 0;
  if (const size_t open = type.find('['); open != std::string_view::npos) {
    if (type.back() != ']' || open + 2 > type.size() - 1) {
      *why = "field \"" + std::string(f) + "\": an array without its size";
      return false;
    }
    const std::string_view digits = type.substr(open + 1, type.size() - open - 2);
    uint64_t n = 0;
    for (const char c : digits) {
      if (c < '0' || c > '9') {
        *why = "field \"" + std::string(f) + "\": an array size that is not a number";
        return false;
      }
      n = n * 10 + static_cast<uint64_t>(c - '0');
      if (n > kMaxMessage) {
        *why = "field \"" + std::string(f) + "\": an array larger than a ULog message can hold";
        return false;
      }
    }
    out->array = true;
    out->count = static_cast<uint32_t>(n);
    type = type.substr(0, open);
  }
  if (!is_name(type)) {
    *why = "field \"" + std::string(f) + "\" has no type";
    return false;
  }
  out->type = std::string(type);
  out->name = std::string(name);
  return true;
}

class Resolver {
 public:
  explicit Resolver(const std::map<std::string, std::string, std::less<>>& formats) : formats_(formats) {}

  /// Lays out type `name` (fields relative to its start) into out; its definition lines are appended to
  /// definition_ (each type once).
  bool layout(const std::string& name, UlogLayout* out, size_t* out_name_bytes, int depth, std::string* why) {
    if (auto it = done_.find(name); it != done_.end()) {
      *out = it->second.layout;
      *out_name_bytes = it->second.name_bytes;
      return true;
    }
    if (depth > kMaxDepth) {
      *why = "types nested deeper than " + std::to_string(kMaxDepth);
      return false;
    }
    if (std::find(stack_.begin(), stack_.end(), name) != stack_.end()) {
      *why = "type " + name + " contains itself";
      return false;
    }
    const auto f = formats_.find(name);
    if (f == formats_.end()) {
      *why = "type " + name + " is not defined";
      return false;
    }
    stack_.push_back(name);
    if (defined_.insert(name).second) definition_ += (definition_.empty() ? "" : "\n") + f->second;
    const std::string_view text = f->second;
    std::string_view body = text.substr(text.find(':') + 1);
    UlogLayout l;
    l.name = name;
    uint64_t offset = 0;
    uint64_t written = 0;
    size_t name_bytes = 0;
    while (!body.empty()) {
      const size_t semi = body.find(';');
      std::string_view decl = body.substr(0, semi);
      body = semi == std::string_view::npos ? std::string_view() : body.substr(semi + 1);
      if (decl.empty()) continue;
      FieldDecl d;
      if (!parse_field(decl, &d, why)) {
        *why = "type " + name + ": " + *why;
        return false;
      }
      const uint64_t n = d.array ? d.count : 1;
      UlogType p;
      uint32_t psize = 0;
      if (primitive(d.type, &p, &psize)) {
        if (!d.name.starts_with("_padding")) {
          l.fields.push_back({d.name, p, static_cast<uint32_t>(offset), d.array ? d.count : 0});
          name_bytes += d.name.size();
          if (d.name == "timestamp" && p == UlogType::kUint64 && !d.array)
            l.timestamp_offset = static_cast<int64_t>(offset);
        }
        offset += n * psize;
      } else {
        UlogLayout inner;
        size_t inner_name_bytes = 0;
        if (!layout(d.type, &inner, &inner_name_bytes, depth + 1, why)) return false;
        for (uint64_t i = 0; i < n && !inner.fields.empty(); ++i) {
          const std::string prefix = d.name + (d.array ? "[" + std::to_string(i) + "]." : ".");
          if (l.fields.size() + inner.fields.size() > kMaxFields ||
              name_bytes + inner.fields.size() * prefix.size() + inner_name_bytes > kMaxNameBytes) {
            *why = "type " + name + " flattens into more fields, or longer names, than a ULog message can use";
            return false;
          }
          for (const auto& fi : inner.fields) {
            l.fields.push_back(
                {prefix + fi.name, fi.type, static_cast<uint32_t>(offset + i * inner.size + fi.offset), fi.count});
          }
          name_bytes += inner.fields.size() * prefix.size() + inner_name_bytes;
          // Bounded even for empty nested types: n <= 65535 and each step costs little.
          if ((offset + (i + 1) * inner.size) > kMaxMessage) break;
        }
        offset += n * inner.size;
      }
      if (offset > kMaxMessage) {
        *why = "type " + name + " is larger than a ULog message can hold (65535 bytes)";
        return false;
      }
      if (!d.name.starts_with("_padding")) written = offset;
    }
    l.size = static_cast<uint32_t>(offset);
    l.size_written = static_cast<uint32_t>(written);
    stack_.pop_back();
    done_.emplace(name, Laid{l, name_bytes});
    *out = std::move(l);
    *out_name_bytes = name_bytes;
    return true;
  }
  std::string definition_;

 private:
  const std::map<std::string, std::string, std::less<>>& formats_;
  std::vector<std::string> stack_;
  std::set<std::string> defined_;
  struct Laid {
    UlogLayout layout;
    size_t name_bytes;
  };
  std::map<std::string, Laid> done_;
};

const char* type_name(uint8_t t) {
  switch (t) {
    case 'B': return "flag bits";
    case 'F': return "format";
    case 'I': return "information";
    case 'M': return "multi information";
    case 'P': return "parameter";
    case 'Q': return "parameter default";
    case 'A': return "subscription";
    case 'R': return "unsubscription";
    case 'D': return "data";
    case 'L': return "logged string";
    case 'C': return "tagged logged string";
    case 'S': return "sync";
    case 'O': return "dropout";
  }
  return nullptr;
}

/// The bytes a record at pos and the header of the one after it may take: its header, the largest content, the
/// next header.
constexpr uint64_t kRecordReach = 3 + 65535 + 3;

/// The log's bytes as the reader walks them, forward (every position asked for is at or after the one before): a
/// log in memory whole; a file read ahead by a thread of its own with pread(2), a chunk at a time into a few reused
/// buffers, each part read once, so the kernel's copy overlaps the conversion. (A mapping of the file costs more:
/// each of its pages faults in when first read, which on virtual machines costs more than the copy.) want(pos, n)
/// makes [pos, pos + n) readable (as far as the log goes; n at most kRecordReach) and may drop what lies before pos:
/// spans taken before it are not read after it.
class Bytes {
 public:
  explicit Bytes(std::span<const uint8_t> whole) : data_(whole.data()), size_(whole.size()), end_(whole.size()) {}
  /// fd: open for reading (closed by ~Bytes), size bytes long.
  Bytes(int fd, uint64_t size) : fd_(fd), size_(size) {
    for (int i = 0; i < kAhead; ++i) ahead_.free.push_back(std::make_unique<uint8_t[]>(kHead + kChunk));
    try {
      ahead_.thread = std::thread([this] { read_ahead(); });
    } catch (const std::system_error&) {  // no thread to be had: want() reads each chunk when it needs it
    }
  }
  Bytes(const Bytes&) = delete;
  Bytes& operator=(const Bytes&) = delete;
  ~Bytes() {
    if (fd_ < 0) return;
    {
      std::lock_guard lock(ahead_.mutex);
      ahead_.stop = true;
    }
    ahead_.changed.notify_all();
    if (ahead_.thread.joinable()) ahead_.thread.join();
    ::close(fd_);
  }

  uint64_t size() const { return size_; }
  uint8_t operator[](uint64_t pos) const { return data_[pos - start_]; }
  const uint8_t* at(uint64_t pos) const { return data_ + (pos - start_); }
  std::span<const uint8_t> subspan(uint64_t pos, uint64_t n) const { return {at(pos), n}; }
  /// The read error that ended the file early ("" when none): the bytes past it read as zeros.
  const std::string& error() const { return error_; }

  void want(uint64_t pos, uint64_t n) {
    const uint64_t need = std::min(size_, pos + std::min(n, kRecordReach));
    while (need > end_) {
      // The next chunk, with what is kept of this one ([pos, end_), less than a record's reach) copied before it.
      if (!ahead_.thread.joinable()) (void)read_chunk(unread_);  // no thread: read here
      Chunk c;
      {
        std::unique_lock lock(ahead_.mutex);
        ahead_.changed.wait(lock, [&] { return !ahead_.filled.empty(); });
        c = std::move(ahead_.filled.front());
        ahead_.filled.pop_front();
      }
      const uint64_t keep = pos < end_ ? end_ - pos : 0;
      uint8_t* base = c.data.get() + kHead - keep;
      if (keep > 0) std::memcpy(base, at(pos), keep);
      if (!c.error.empty() && error_.empty()) error_ = c.error;
      if (current_) give_back(std::move(current_));
      current_ = std::move(c.data);
      data_ = base;
      start_ = c.start - keep;
      end_ = c.start + kChunk < size_ ? c.start + kChunk : size_;
    }
  }

 private:
  static constexpr uint64_t kChunk = 1 << 20;
  static constexpr int kAhead = 3;                 // buffers the thread may fill ahead of the one being read
  static constexpr uint64_t kHead = kRecordReach;  // room before a chunk for the end of the one before it

  struct Chunk {
    std::unique_ptr<uint8_t[]> data;  // kHead bytes of room, then the chunk
    uint64_t start = 0;               // the file offset of its first byte
    std::string error;                // a read error in it: the bytes from there on are zeros
  };

  void give_back(std::unique_ptr<uint8_t[]> buffer) {
    {
      std::lock_guard lock(ahead_.mutex);
      ahead_.free.push_back(std::move(buffer));
    }
    ahead_.changed.notify_all();
  }

  /// The thread: reads the file from its start, chunk after chunk, while buffers are free.
  void read_ahead() {
    for (uint64_t at = 0; at < size_;) {
      if (!read_chunk(at)) return;
    }
  }

  /// Reads the chunk at `at` into a free buffer (waiting for one), queues it and moves `at` past it; false when
  /// the reader is being destroyed.
  bool read_chunk(uint64_t& at) {
    Chunk c;
    {
      std::unique_lock lock(ahead_.mutex);
      ahead_.changed.wait(lock, [&] { return ahead_.stop || !ahead_.free.empty(); });
      if (ahead_.stop) return false;
      c.data = std::move(ahead_.free.back());
      ahead_.free.pop_back();
    }
    c.start = at;
    const uint64_t until = std::min(size_, at + kChunk);
    uint8_t* out = c.data.get() + kHead;
    uint64_t end = at;
    while (end < until) {
      const ssize_t got = ::pread(fd_, out + (end - at), until - end, static_cast<off_t>(end));
      if (got > 0) {
        end += static_cast<uint64_t>(got);
        continue;
      }
      if (got < 0 && errno == EINTR) continue;
      c.error = got < 0 ? std::strerror(errno) : "the file is shorter than when it was opened";
      std::memset(out + (end - at), 0, until - end);
      end = until;
    }
    at = until;
    {
      std::lock_guard lock(ahead_.mutex);
      ahead_.filled.push_back(std::move(c));
    }
    ahead_.changed.notify_all();
    return true;
  }

  int fd_ = -1;
  const uint8_t* data_ = nullptr;  // the byte at start_
  uint64_t size_ = 0;
  uint64_t start_ = 0;  // the offset of data_[0]
  uint64_t end_ = 0;    // where what data_ holds ends
  std::unique_ptr<uint8_t[]> current_;  // the buffer data_ points into (a file)
  uint64_t unread_ = 0;                 // without a thread: where the next chunk to read starts
  std::string error_;
  struct {
    std::mutex mutex;
    std::condition_variable changed;
    std::deque<Chunk> filled;  // in the file's order
    std::vector<std::unique_ptr<uint8_t[]>> free;
    bool stop = false;
    std::thread thread;
  } ahead_;
};

/// One pass over a file's records.
class Pass {
 public:
  Pass(Bytes& b, const UlogReader::Callbacks& cb, uint64_t start_us, uint64_t* last_us,
       std::map<char, int64_t>* unknown)
      : b_(b), cb_(cb), start_us_(start_us), last_us_(last_us), unknown_(unknown) {}

  void problem(uint64_t offset, const std::string& what) {
    if (cb_.problem) cb_.problem(offset, what);
  }

  /// Reads the records of [pos, end).
  void section(uint64_t pos, uint64_t end) {
    while (pos < end) {
      b_.want(pos, kRecordReach);
      if (!b_.error().empty()) return;
      if (end - pos < 3) {
        problem(pos, cut_text(end, "a record's header"));
        return;
      }
      const uint16_t size = le16(b_.at(pos));
      const uint8_t type = b_[pos + 2];
      if (pos + 3 + size > end) {
        if (plausible_header(pos, end)) {
          problem(pos,
                  cut_text(end, std::string("a ") + type_name(type) + " record of " + std::to_string(size) + " bytes"));
          return;
        }
        pos = resync(pos, end,
                     "a record of " + std::to_string(size) + " bytes (type " + type_text(type) + ") runs past the end");
        continue;
      }
      const std::span<const uint8_t> msg = b_.subspan(pos + 3, size);
      if (std::string why = check(type, msg, pos, false); !why.empty()) {
        pos = resync(pos, end, why);
        continue;
      }
      if (!type_name(type)) {
        // A type this reader does not know is skipped whole only when a known record follows it (or the end):
        // damage to a known record's type byte is reported, not skipped silently.
        const uint64_t next = pos + 3 + size;
        if (next != end && end - next >= 3 && !type_name(b_[next + 2])) {
          pos = resync(pos, end, "not a record (type " + type_text(type) + ", " + std::to_string(size) + " bytes)");
          continue;
        }
      }
      handle(type, msg, pos);
      pos += 3 + size;
    }
  }

  bool in_data = false;
  std::map<std::string, std::string, std::less<>> formats;

 private:
  std::string cut_text(uint64_t end, const std::string& what) const {
    return end == b_.size()
               ? "the file ends inside " + what + " (cut short); everything before it is read"
               : what + " runs past the appended data's offset " + std::to_string(end) + "; reading goes on there";
  }
  static std::string type_text(uint8_t t) {
    if (t >= 0x20 && t < 0x7f) return std::string("'") + static_cast<char>(t) + "'";
    static constexpr char kHex[] = "0123456789abcdef";
    return std::string("0x") + kHex[t >> 4] + kHex[t & 15];
  }

  /// Whether a record starting at pos whose content lies past end could be a real record cut there: a known
  /// type of a size it can have (for data: the size of its subscription's messages).
  bool plausible_header(uint64_t pos, uint64_t end) const {
    const uint16_t size = le16(b_.at(pos));
    const uint8_t type = b_[pos + 2];
    if (!type_name(type) || size == 0) return false;
    if (type == 'R' || type == 'O') return size == 2;
    if (type == 'S') return size == 8;
    if (type == 'D') {
      if (pos + 5 > end) return true;
      const UlogSubscription* sub = subscriptions_[le16(b_.at(pos + 3))].get();
      if (sub == nullptr) return false;
      const auto& l = sub->layout;
      return !l || (size >= 2u + l->size_written && size <= 2u + l->size);
    }
    return true;
  }

  /// After a record at pos that does not parse: the next record that does (a whole record whose content fits,
  /// followed by another record's header or the end). Reports the stretch once; returns where reading goes on.
  uint64_t resync(uint64_t pos, uint64_t end, const std::string& why) {
    for (uint64_t q = pos + 1; q + 3 <= end; ++q) {
      b_.want(q, kRecordReach);
      if (!b_.error().empty()) return end;
      const uint16_t size = le16(b_.at(q));
      const uint8_t type = b_[q + 2];
      if (!type_name(type) || q + 3 + size > end) continue;
      const uint64_t next = q + 3 + size;
      if (next != end && !(end - next < 3 || type_name(b_[next + 2]))) continue;
      if (!check(type, b_.subspan(q + 3, size), q, true).empty()) continue;
      problem(pos, why + "; " + std::to_string(q - pos) + " bytes skipped, reading again at byte " + std::to_string(q));
      return q;
    }
    problem(pos, why + "; nothing after it parses (" + std::to_string(end - pos) + " bytes skipped)");
    return end;
  }

  static std::string key_problem(std::span<const uint8_t> m) {
    if (m.empty()) return "no key";
    const size_t n = m[0];
    if (1 + n > m.size()) return "a key of " + std::to_string(n) + " bytes in " + std::to_string(m.size() - 1);
    const std::string_view key = text_of(m.subspan(1, n));
    const size_t space = key.find(' ');
    // Names are not only C names: PX4 writes perf counters' as "perf_counter_preflight-00".
    if (space == std::string_view::npos || space == 0 || space + 1 == key.size() || !printable(m.subspan(1, n))) {
      return "a key that is not \"type name\"";
    }
    return {};
  }

  /// Empty when a record of this type can hold msg; else why not. strict: for finding the next record after
  /// damage, what a real writer always writes (a subscription to a defined format, a logged string's level).
  std::string check(uint8_t type, std::span<const uint8_t> m, uint64_t pos, bool strict) const {
    auto bad = [&](const std::string& why) { return std::string("a ") + type_name(type) + " record: " + why; };
    switch (type) {
      case 'B': return pos == kHeaderSize && !strict ? std::string() : "a flag bits record after the first";
      case 'F': {
        // The name only (its fields are checked when a subscription resolves the format): every check here costs
        // at most a few hundred bytes, so finding the next record after damage stays linear in the file.
        const size_t colon = text_of(m.first(std::min<size_t>(m.size(), kMaxName + 1))).find(':');
        if (colon == std::string_view::npos || !is_name(text_of(m.first(colon)))) {
          return bad("not \"name:type field;...\"");
        }
        return {};
      }
      case 'I':
      case 'P':
        if (std::string k = key_problem(m); !k.empty()) return bad(k);
        return {};
      case 'M':
      case 'Q':
        if (m.size() < 2) return bad("too short");
        if (std::string k = key_problem(m.subspan(1)); !k.empty()) return bad(k);
        return {};
      case 'A': {
        if (m.size() < 4) return bad("too short");
        const auto name = m.subspan(3);
        if (name.size() > kMaxName || !is_name(text_of(name))) return bad("no topic name (a name of 1 to 255 bytes)");
        if (strict && !formats.count(text_of(name))) return bad("an undefined format");
        return {};
      }
      case 'R':
      case 'O': return m.size() == 2 ? std::string() : bad("not 2 bytes");
      case 'S':
        return m.size() == 8 && std::memcmp(m.data(), kSyncMagic, 8) == 0 ? std::string() : bad("not the sync magic");
      case 'L':
      case 'C': {
        const size_t min = type == 'L' ? 9 : 11;
        if (m.size() < min) return bad("too short");
        if (strict && !((m[0] >= '0' && m[0] <= '7') || m[0] <= 7)) return bad("not a level");
        return {};
      }
      case 'D': {
        if (m.size() < 2) return bad("too short");
        const uint16_t id = le16(m.data());
        const UlogSubscription* sub = subscriptions_[id].get();
        if (sub == nullptr) return bad("msg_id " + std::to_string(id) + ", which no subscription names");
        const auto& l = sub->layout;
        if (l && (m.size() - 2 < l->size_written || m.size() - 2 > l->size)) {
          return bad(std::to_string(m.size() - 2) + " bytes of " + sub->name + ", whose messages are " +
                     std::to_string(l->size_written) +
                     (l->size != l->size_written ? " to " + std::to_string(l->size) : "") + " bytes");
        }
        if (strict && !l) return bad("a subscription whose format does not resolve");
        return {};
      }
    }
    // A record type this reader does not know: skipped whole (the specification lets writers add types), when
    // its type is a letter; anything else is damage.
    if (!strict && std::isalpha(type) && !m.empty()) return {};
    return "not a record (type " + type_text(type) + ", " + std::to_string(m.size()) + " bytes)";
  }

  void handle(uint8_t type, std::span<const uint8_t> m, uint64_t pos) {
    switch (type) {
      case 'B': return;  // read before the records
      case 'F': {
        const std::string_view t = text_of(m);
        std::string name(t.substr(0, t.find(':')));
        formats[name] = std::string(t);
        return;
      }
      case 'I':
      case 'M':
      case 'P':
      case 'Q': {
        UlogValue v;
        v.kind = static_cast<char>(type);
        std::span<const uint8_t> rest = m;
        if (type == 'M') {
          v.continued = m[0] != 0;
          rest = m.subspan(1);
        } else if (type == 'Q') {
          v.default_types = m[0];
          rest = m.subspan(1);
        }
        const size_t n = rest[0];
        const std::string_view key = text_of(rest.subspan(1, n));
        const size_t space = key.find(' ');
        v.type = key.substr(0, space);
        v.key = key.substr(space + 1);
        v.value = rest.subspan(1 + n);
        v.in_definitions = !in_data;
        v.time = in_data ? *last_us_ : start_us_;
        v.offset = pos;
        if (cb_.value) cb_.value(v);
        return;
      }
      case 'A': {
        in_data = true;
        auto s = std::make_unique<UlogSubscription>();
        s->multi_id = m[0];
        s->msg_id = le16(&m[1]);
        s->name = std::string(text_of(m.subspan(3)));
        if (auto it = layouts_.find(s->name); it != layouts_.end()) {
          s->layout = it->second.first;
          s->layout_error = it->second.second;
        } else {
          auto r = resolve_ulog_format(formats, s->name);
          if (r) {
            s->layout = std::make_shared<const UlogLayout>(std::move(*r));
          } else {
            s->layout_error = r.error().message;
            problem(pos, "the subscription to " + s->name + ": " + s->layout_error + "; its messages are left out");
          }
          layouts_[s->name] = {s->layout, s->layout_error};
        }
        if (cb_.subscription) cb_.subscription(*s);
        subscriptions_[s->msg_id] = std::move(s);
        return;
      }
      case 'R': subscriptions_[le16(m.data())].reset(); return;
      case 'D': {
        in_data = true;
        const UlogSubscription& s = *subscriptions_[le16(m.data())];  // check() found it
        UlogData d;
        d.subscription = &s;
        d.payload = m.subspan(2);
        d.offset = pos;
        d.timestamp = *last_us_;
        if (s.layout && s.layout->timestamp_offset >= 0 &&
            static_cast<uint64_t>(s.layout->timestamp_offset) + 8 <= d.payload.size()) {
          d.timestamp = le64(&d.payload[static_cast<size_t>(s.layout->timestamp_offset)]);
          *last_us_ = std::max(*last_us_, d.timestamp);
        }
        if (cb_.data) cb_.data(d);
        return;
      }
      case 'L':
      case 'C': {
        in_data = true;
        UlogLogged l;
        l.level = m[0];
        l.tagged = type == 'C';
        size_t at = 1;
        if (l.tagged) {
          l.tag = le16(&m[1]);
          at = 3;
        }
        l.timestamp = le64(&m[at]);
        l.text = text_of(m.subspan(at + 8));
        l.offset = pos;
        if (cb_.logged) cb_.logged(l);
        return;
      }
      case 'S': return;
      case 'O': {
        UlogDropout d;
        d.timestamp = *last_us_;
        d.duration_ms = le16(m.data());
        d.offset = pos;
        if (cb_.dropout) cb_.dropout(d);
        return;
      }
    }
    ++(*unknown_)[static_cast<char>(type)];
  }

  Bytes& b_;
  const UlogReader::Callbacks& cb_;
  uint64_t start_us_;
  uint64_t* last_us_;
  std::map<char, int64_t>* unknown_;
  // By msg_id (a vector of every id, not a map: looked up twice for each data message).
  std::vector<std::unique_ptr<UlogSubscription>> subscriptions_ = std::vector<std::unique_ptr<UlogSubscription>>(65536);
  std::map<std::string, std::pair<std::shared_ptr<const UlogLayout>, std::string>, std::less<>> layouts_;
};

std::string header_problem(std::span<const uint8_t> b) {
  if (b.size() < kHeaderSize) return "shorter than a ULog header (16 bytes)";
  if (std::memcmp(b.data(), kMagic, sizeof kMagic) != 0) return "not a ULog (no ULog magic)";
  return {};
}

}  // namespace

const UlogLayout::Field* UlogLayout::find(std::string_view field) const {
  if (!index.empty()) {
    const auto it = index.find(std::string(field));
    return it == index.end() ? nullptr : &fields[it->second];
  }
  for (const auto& f : fields)
    if (f.name == field) return &f;
  return nullptr;
}

std::optional<uint64_t> UlogLayout::u64(std::span<const uint8_t> data, std::string_view field) const {
  return u64(data, find(field));
}

std::optional<uint64_t> UlogLayout::u64(std::span<const uint8_t> data, const Field* f) const {
  if (!f || f->type != UlogType::kUint64 || f->count != 0 || f->offset + 8ull > data.size()) return std::nullopt;
  return le64(data.data() + f->offset);
}

double UlogLayout::number(std::span<const uint8_t> data, std::string_view field, uint32_t i) const {
  return number(data, find(field), i);
}

double UlogLayout::number(std::span<const uint8_t> data, const Field* f, uint32_t i) const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!f || (f->count == 0 ? i != 0 : i >= f->count) || f->type == UlogType::kChar) return nan;
  const uint64_t at = f->offset + static_cast<uint64_t>(i) * size_of(f->type);
  if (at + size_of(f->type) > data.size()) return nan;
  const uint8_t* p = data.data() + at;
  switch (f->type) {
    case UlogType::kInt8: return static_cast<int8_t>(p[0]);
    case UlogType::kUint8:
    case UlogType::kBool: return p[0];
    case UlogType::kInt16: return static_cast<int16_t>(le16(p));
    case UlogType::kUint16: return le16(p);
    case UlogType::kInt32: return static_cast<int32_t>(le32(p));
    case UlogType::kUint32: return le32(p);
    case UlogType::kInt64: return static_cast<double>(static_cast<int64_t>(le64(p)));
    case UlogType::kUint64: return static_cast<double>(le64(p));
    case UlogType::kFloat: {
      const uint32_t u = le32(p);
      float v;
      std::memcpy(&v, &u, 4);
      return v;
    }
    case UlogType::kDouble: {
      const uint64_t u = le64(p);
      double v;
      std::memcpy(&v, &u, 8);
      return v;
    }
    case UlogType::kChar: break;
  }
  return nan;
}

Result<UlogLayout> resolve_ulog_format(const std::map<std::string, std::string, std::less<>>& formats,
                                       const std::string& name) {
  Resolver r(formats);
  UlogLayout l;
  std::string why;
  size_t name_bytes = 0;
  if (!r.layout(name, &l, &name_bytes, 0, &why)) return Error(why);
  l.definition = std::move(r.definition_);
  for (size_t i = 0; i < l.fields.size(); ++i) l.index.emplace(l.fields[i].name, static_cast<uint32_t>(i));
  return l;
}

bool UlogReader::looks_like(std::span<const uint8_t> head) {
  return head.size() >= sizeof kMagic && std::memcmp(head.data(), kMagic, sizeof kMagic) == 0;
}

Result<UlogReader> UlogReader::open(const std::string& path) {
  auto f = MappedFile::open(path);
  if (!f) return f.error();
  if (std::string why = header_problem(f->bytes()); !why.empty()) return Error(path + ": " + why);
  UlogReader r;
  r.file_ = std::move(*f);
  r.path_ = path;
  return r;
}

Result<UlogReader> UlogReader::from_memory(std::vector<uint8_t> bytes) {
  if (std::string why = header_problem(bytes); !why.empty()) return Error(why);
  UlogReader r;
  r.memory_ = std::move(bytes);
  r.in_memory_ = true;
  return r;
}

Status UlogReader::read(const Callbacks& callbacks) {
  // A file is read again through its own descriptor (its mapping only when it cannot be opened again).
  const int fd = in_memory_ ? -1 : ::open(path_.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  Bytes w =
      fd >= 0 ? Bytes(fd, file_.bytes().size()) : Bytes(in_memory_ ? std::span<const uint8_t>(memory_) : file_.bytes());
  const uint64_t n = w.size();
  w.want(0, kHeaderSize + kRecordReach);
  const std::span<const uint8_t> b = w.subspan(0, std::min(n, kHeaderSize + kRecordReach));
  version_ = b[7];
  start_us_ = le64(&b[8]);
  last_us_ = start_us_;
  unknown_types_.clear();
  Pass pass(w, callbacks, start_us_, &last_us_, &unknown_types_);
  // The flag bits, when present, are the first record: incompatible flags this reader does not know make the rest
  // unreadable; the appended data's offsets say where further sections start.
  std::vector<uint64_t> starts{kHeaderSize};
  if (n >= kHeaderSize + 3 && b[kHeaderSize + 2] == 'B') {
    const uint16_t size = le16(&b[kHeaderSize]);
    if (size < 40 && kHeaderSize + 3 + size <= n) {
      pass.problem(kHeaderSize,
                   "a flag bits record of " + std::to_string(size) + " bytes (40 or more); read as if it set no flag");
    }
  }
  if (n >= kHeaderSize + 3 + 40 && b[kHeaderSize + 2] == 'B' && le16(&b[kHeaderSize]) >= 40 &&
      kHeaderSize + 3 + le16(&b[kHeaderSize]) <= n) {
    const uint8_t* f = &b[kHeaderSize + 3];
    const uint8_t* incompat = f + 8;
    for (int i = 0; i < 8; ++i) {
      const uint8_t unknown = i == 0 ? (incompat[0] & ~1u) : incompat[i];
      if (unknown) {
        int bit = 0;
        while (!((unknown >> bit) & 1)) ++bit;
        return Error("at byte " + std::to_string(kHeaderSize + 3 + 8 + i) + ": incompatible flag bit " +
                     std::to_string(i * 8 + bit) + " is set, which this reader does not know; the log cannot be read");
      }
    }
    if (incompat[0] & 1) {
      for (int i = 0; i < 3; ++i) {
        const uint64_t off = le64(f + 16 + 8 * static_cast<ptrdiff_t>(i));
        if (off == 0) continue;
        if (off <= starts.back() || off > n) {
          pass.problem(
              kHeaderSize + 3 + 16 + 8 * static_cast<uint64_t>(i),
              "appended data at offset " + std::to_string(off) + ", outside the file or before the data; left out");
          continue;
        }
        starts.push_back(off);
      }
    }
  }
  for (size_t i = 0; i < starts.size(); ++i) {
    pass.section(starts[i], i + 1 < starts.size() ? starts[i + 1] : n);
  }
  if (!w.error().empty()) return Error("cannot read " + path_ + ": " + w.error());
  return {};
}

}  // namespace driftlab::formats
