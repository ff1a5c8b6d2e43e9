#include "core/log_index.h"

#include <sys/stat.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <unordered_map>

#include "core/internal/event_scanner.h"
#include "core/log_format.h"
#include "core/mapped_file.h"
#include "core/string_hash.h"
#include "core/text_file.h"

namespace driftlab {
namespace {

constexpr char kMagic[8] = {'D', 'L', 'I', 'D', 'X', '0', '0', '3'};
constexpr uint64_t kSampleBytes = 64 << 10;

uint64_t fnv1a(std::span<const uint8_t> bytes, uint64_t h = 1469598103934665603ull) {
  for (uint8_t b : bytes) h = (h ^ b) * 1099511628211ull;
  return h;
}

/// What identifies a version of a log file: if any of it changed, the cached index is stale.
struct FileIdentity {
  uint64_t size = 0;
  int64_t mtime_ns = 0;
  uint64_t inode = 0;
  uint64_t sample_hash = 0;  // first and last 64 KiB
  bool operator==(const FileIdentity&) const = default;
};

FileIdentity identify(const std::string& path, std::span<const uint8_t> bytes) {
  FileIdentity id;
  struct stat st {};
  if (stat(path.c_str(), &st) == 0) {
    id.mtime_ns = static_cast<int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
    id.inode = st.st_ino;
  }
  id.size = bytes.size();
  const uint64_t n = std::min<uint64_t>(kSampleBytes, bytes.size());
  id.sample_hash = fnv1a(bytes.last(n), fnv1a(bytes.first(n)));
  return id;
}

// Native-endian serialisation: the cache is local to this machine.
class Out {
 public:
  template <typename T>
  void put(const T& v) {
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    buf_.insert(buf_.end(), p, p + sizeof(T));
  }
  void put_string(const std::string& s) {
    put(static_cast<uint32_t>(s.size()));
    buf_.insert(buf_.end(), s.begin(), s.end());
  }
  std::vector<uint8_t>& bytes() { return buf_; }

 private:
  std::vector<uint8_t> buf_;
};

class In {
 public:
  explicit In(std::span<const uint8_t> b) : b_(b) {}
  template <typename T>
  bool get(T& v) {
    if (b_.size() - pos_ < sizeof(T)) return false;
    std::memcpy(&v, b_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool get_string(std::string& s) {
    uint32_t n = 0;
    if (!get(n) || b_.size() - pos_ < n) return false;
    s.assign(reinterpret_cast<const char*>(b_.data() + pos_), n);
    pos_ += n;
    return true;
  }
  /// A count of items of at least min_item_bytes each that can still be in the buffer.
  bool get_count(uint64_t& n, size_t min_item_bytes) {
    return get(n) && n <= (b_.size() - pos_) / min_item_bytes;
  }
  bool at_end() const { return pos_ == b_.size(); }

 private:
  std::span<const uint8_t> b_;
  size_t pos_ = 0;
};

std::vector<uint8_t> serialise(const LogSummary& s, const std::vector<LogIndex::Entry>& entries,
                               const FileIdentity& id) {
  Out o;
  for (char c : kMagic) o.put(c);
  o.put(id);
  o.put(s.file_bytes);
  o.put(s.events);
  o.put(s.start_utime);
  o.put(s.end_utime);
  o.put(s.problems_total);
  o.put(static_cast<uint8_t>(s.stamps_counted));
  o.put(static_cast<uint64_t>(s.channels.size()));
  for (const auto& c : s.channels) {
    o.put_string(c.name);
    o.put(c.count);
    o.put(c.bytes);
    o.put(c.first_utime);
    o.put(c.last_utime);
    o.put(c.fingerprint);
    o.put(static_cast<uint8_t>(c.mixed_fingerprints));
    o.put(c.times_back);
    o.put(c.stamped);
    o.put(c.stamps_repeated);
  }
  o.put(static_cast<uint64_t>(s.problems.size()));
  for (const auto& p : s.problems) {
    o.put(p.offset);
    o.put(static_cast<uint8_t>(p.kind));
    o.put_string(p.detail);
  }
  o.put(static_cast<uint64_t>(entries.size()));
  for (const auto& e : entries) o.put(e);
  o.put(fnv1a(o.bytes()));
  return std::move(o.bytes());
}

bool deserialise(std::span<const uint8_t> bytes, const FileIdentity& expected, LogSummary& s,
                 std::vector<LogIndex::Entry>& entries) {
  if (bytes.size() < sizeof(kMagic) + 8 || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) return false;
  uint64_t checksum = 0;
  std::memcpy(&checksum, bytes.data() + bytes.size() - 8, 8);
  if (fnv1a(bytes.first(bytes.size() - 8)) != checksum) return false;
  In in(bytes.subspan(sizeof(kMagic), bytes.size() - sizeof(kMagic) - 8));
  FileIdentity id;
  uint64_t n = 0;
  uint8_t stamps_counted = 0;
  if (!in.get(id) || !(id == expected)) return false;
  if (!in.get(s.file_bytes) || !in.get(s.events) || !in.get(s.start_utime) || !in.get(s.end_utime) ||
      !in.get(s.problems_total) || !in.get(stamps_counted) || !in.get_count(n, 4 + 8 * 8 + 1))
    return false;
  s.stamps_counted = stamps_counted != 0;
  s.channels.resize(n);
  for (auto& c : s.channels) {
    uint8_t mixed = 0;
    if (!in.get_string(c.name) || !in.get(c.count) || !in.get(c.bytes) || !in.get(c.first_utime) ||
        !in.get(c.last_utime) || !in.get(c.fingerprint) || !in.get(mixed) || !in.get(c.times_back) ||
        !in.get(c.stamped) || !in.get(c.stamps_repeated))
      return false;
    c.mixed_fingerprints = mixed != 0;
  }
  if (!in.get_count(n, 8 + 1 + 4)) return false;
  s.problems.resize(n);
  for (auto& p : s.problems) {
    uint8_t kind = 0;
    if (!in.get(p.offset) || !in.get(kind) || !in.get_string(p.detail) ||
        kind > static_cast<uint8_t>(ProblemKind::kBadChannelLength))
      return false;
    p.kind = static_cast<ProblemKind>(kind);
  }
  if (!in.get_count(n, sizeof(LogIndex::Entry))) return false;
  entries.resize(n);
  for (auto& e : entries)
    if (!in.get(e)) return false;
  return in.at_end();
}

/// Writes the cache atomically, through a partial file of its own (processes may index one log at once); failures
/// are ignored: the cache is optional.
void save_cache(const std::string& path, const std::vector<uint8_t>& bytes) {
  (void)write_file_atomically(path, {reinterpret_cast<const char*>(bytes.data()), bytes.size()},
                              {.partial_of_its_own = true});
}

}  // namespace

LogIndex LogIndex::build(std::span<const uint8_t> bytes, const std::function<void(uint64_t)>& on_progress,
                         const HeaderReader& headers) {
  LogIndex index;
  LogSummary& s = index.summary_;
  s.stamps_counted = static_cast<bool>(headers);
  s.file_bytes = bytes.size();
  ProblemCallback on_problem = [&s](const Problem& p) {
    if (s.problems.size() < kMaxStoredProblems) s.problems.push_back(p);
  };
  internal::EventScanner scanner(bytes, &on_problem);
  std::unordered_map<std::string, size_t, StringHash, std::equal_to<>> by_name;
  std::vector<ChannelSummary> channels;
  ChannelSummary* last = nullptr;
  struct Previous {
    int64_t utime = 0;
    bool stamped = false;
    int64_t seq = 0, stamp = 0;
  };
  std::vector<Previous> previous;  // per channel, by index in `channels`
  size_t last_index = 0;
  int64_t prefix_max = std::numeric_limits<int64_t>::min();
  uint64_t next_block = 0;
  Event e;
  while (scanner.next(e)) {
    if (e.offset >= next_block) {
      index.entries_.push_back({e.offset, e.utime, prefix_max});
      next_block = (e.offset / kBlockBytes + 1) * kBlockBytes;
      if (on_progress) on_progress(e.offset);
    }
    prefix_max = std::max(prefix_max, e.utime);
    if (last == nullptr || last->name != e.channel) {
      auto it = by_name.find(e.channel);
      if (it == by_name.end()) {
        it = by_name.emplace(std::string(e.channel), channels.size()).first;
        channels.push_back(ChannelSummary{std::string(e.channel), 0, 0, e.utime, e.utime,
                                          logfmt::fingerprint(e.data), false});
        previous.push_back({e.utime});
      }
      last = &channels[it->second];
      last_index = it->second;
    }
    ChannelSummary& c = *last;
    Previous& before = previous[last_index];
    if (c.count > 0 && e.utime < before.utime) ++c.times_back;
    before.utime = e.utime;
    const std::optional<HeaderFields> header = headers ? headers(e.data, e.utime) : std::nullopt;
    if (header) {
      ++c.stamped;
      if (before.stamped && header->utime == before.stamp && header->seq != before.seq) ++c.stamps_repeated;
      before.seq = header->seq;
      before.stamp = header->utime;
    }
    before.stamped = header.has_value();
    ++c.count;
    c.bytes += static_cast<int64_t>(e.data.size());
    c.first_utime = std::min(c.first_utime, e.utime);
    c.last_utime = std::max(c.last_utime, e.utime);
    if (!c.mixed_fingerprints && logfmt::fingerprint(e.data) != c.fingerprint) c.mixed_fingerprints = true;
    if (s.events == 0) s.start_utime = s.end_utime = e.utime;
    s.start_utime = std::min(s.start_utime, e.utime);
    s.end_utime = std::max(s.end_utime, e.utime);
    ++s.events;
  }
  s.problems_total = scanner.problems();
  std::sort(channels.begin(), channels.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  s.channels = std::move(channels);
  return index;
}

Result<LogIndex> LogIndex::load_or_build(const std::string& log_path,
                                         const std::function<void(uint64_t, uint64_t)>& on_progress,
                                         uint64_t cache_min_bytes, const HeaderReader& headers) {
  auto mapped = MappedFile::open(log_path);
  if (!mapped) return mapped.error();
  const FileIdentity id = identify(log_path, mapped->bytes());
  const std::string cache = cache_path(log_path);
  LogIndex index;
  if (auto cached = MappedFile::open(cache); cached &&
                                             deserialise(cached->bytes(), id, index.summary_, index.entries_) &&
                                             (!headers || index.summary_.stamps_counted)) {
    index.from_cache_ = true;
    return index;
  }
  const uint64_t total = mapped->bytes().size();
  index = build(
      mapped->bytes(),
      [&](uint64_t offset) {
        mapped->release_before(offset);
        if (on_progress) on_progress(offset, total);
      },
      headers);
  if (total >= cache_min_bytes && index.summary_.events > 0) {
    save_cache(cache, serialise(index.summary_, index.entries_, id));
  }
  return index;
}

uint64_t LogIndex::seek_offset(int64_t utime) const {
  // Last entry all of whose predecessors are earlier than utime.
  auto it = std::partition_point(entries_.begin(), entries_.end(),
                                 [utime](const Entry& e) { return e.prefix_max < utime; });
  if (it == entries_.begin()) return 0;
  return std::prev(it)->offset;
}

}  // namespace driftlab
