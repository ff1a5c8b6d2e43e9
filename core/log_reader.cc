#include "core/log_reader.h"

#include <algorithm>
#include <optional>
#include <regex>
#include <unordered_map>

#include "core/internal/event_scanner.h"
#include "core/log_index.h"
#include "core/mapped_file.h"
#include "core/string_hash.h"

namespace driftlab {

struct LogReader::Impl {
  Impl(std::string path_in, MappedFile mapped_in, std::span<const uint8_t> bytes_in, ReadOptions options_in)
      : path(std::move(path_in)),
        mapped(std::move(mapped_in)),
        bytes(bytes_in),
        options(std::move(options_in)),
        scanner(bytes, &options.on_problem) {}

  /// Whether a channel passes the filter; the regex runs once per distinct channel name.
  bool accept(std::string_view channel) {
    if (!filter) return true;
    if (channel == last_channel) return last_accepted;
    auto it = decisions.find(channel);
    if (it == decisions.end()) {
      const bool ok = std::regex_match(channel.begin(), channel.end(), *filter) ||
                      std::find(options.also.begin(), options.also.end(), channel) != options.also.end();
      it = decisions.emplace(std::string(channel), ok).first;
    }
    last_channel = it->first;
    last_accepted = it->second;
    return last_accepted;
  }

  std::string path;
  MappedFile mapped;  // empty for from_memory
  std::span<const uint8_t> bytes;
  ReadOptions options;
  internal::EventScanner scanner;
  std::optional<std::regex> filter;
  std::unordered_map<std::string, bool, StringHash, std::equal_to<>> decisions;
  std::string_view last_channel;  // a key of decisions
  bool last_accepted = false;
  std::optional<LogIndex> index;
  bool in_memory = false;  // from_memory: no file to index
};

namespace {
Status compile_filter(const std::string& pattern, std::optional<std::regex>& out) {
  if (pattern.empty()) return {};
  try {
    out.emplace(pattern, std::regex::ECMAScript | std::regex::optimize);
  } catch (const std::regex_error& e) {
    return Error{"invalid channel regex '" + pattern + "': " + e.what()};
  }
  return {};
}
}  // namespace

LogReader::LogReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
LogReader::LogReader(LogReader&&) noexcept = default;
LogReader& LogReader::operator=(LogReader&&) noexcept = default;
LogReader::~LogReader() = default;

Result<LogReader> LogReader::open(const std::string& path, ReadOptions options) {
  auto mapped = MappedFile::open(path);
  if (!mapped) return mapped.error();
  const auto bytes = mapped->bytes();
  auto impl = std::make_unique<Impl>(path, std::move(*mapped), bytes, std::move(options));
  if (auto st = compile_filter(impl->options.channels, impl->filter); !st) return st.error();
  return LogReader(std::move(impl));
}

Result<LogReader> LogReader::from_memory(std::span<const uint8_t> bytes, ReadOptions options) {
  auto impl = std::make_unique<Impl>("<memory>", MappedFile(), bytes, std::move(options));
  impl->in_memory = true;
  if (auto st = compile_filter(impl->options.channels, impl->filter); !st) return st.error();
  return LogReader(std::move(impl));
}

bool LogReader::next(Event& out) {
  Impl& d = *impl_;
  while (d.scanner.next(out)) {
    d.mapped.release_before(out.offset);
    if (d.accept(out.channel)) return true;
  }
  return false;
}

Status LogReader::seek(int64_t utime) {
  Impl& d = *impl_;
  if (!d.index) {
    if (d.in_memory) {
      d.index = LogIndex::build(d.bytes);
    } else {
      auto index = LogIndex::load_or_build(d.path);
      if (!index) return index.error();
      d.index = std::move(*index);
    }
  }
  d.scanner.set_position(d.index->seek_offset(utime));
  // Skip forward to the first event at or after utime, without reporting problems twice.
  internal::EventScanner probe(d.bytes, nullptr);
  probe.set_position(d.scanner.position());
  Event e;
  uint64_t at = d.bytes.size();
  while (probe.next(e)) {
    if (e.utime >= utime) {
      at = e.offset;
      break;
    }
  }
  d.scanner.set_position(at);
  return {};
}

void LogReader::rewind() { impl_->scanner.set_position(0); }

std::optional<uint64_t> LogReader::event_at_or_after(uint64_t offset) const {
  return impl_->scanner.event_at_or_after(offset);
}

void LogReader::read_range(uint64_t begin, uint64_t end) {
  impl_->scanner.set_position(begin);
  impl_->scanner.stop_at(end);
}
const std::string& LogReader::path() const { return impl_->path; }
uint64_t LogReader::size_bytes() const { return impl_->bytes.size(); }
uint64_t LogReader::position() const { return impl_->scanner.position(); }
uint64_t LogReader::problems() const { return impl_->scanner.problems(); }

std::string not_an_event_log(const std::string& path, uint64_t bytes) {
  return path + ": not an LCM event log (no event in " + std::to_string(bytes) +
         " bytes; an event starts with the sync word 0xEDA1DA01)";
}

Status check_event_log(const std::string& path) {
  std::optional<Problem> first;
  auto reader = LogReader::open(path, {.on_problem = [&](const Problem& p) {
                                  if (!first) first = p;
                                }});
  if (!reader) return reader.error();
  Event e;
  if (reader->next(e)) return {};
  const uint64_t bytes = reader->size_bytes();
  if (bytes == 0) return Error{path + ": empty file (0 bytes): no events"};
  if (first && first->offset == 0 && first->kind == ProblemKind::kGarbage) return Error{not_an_event_log(path, bytes)};
  return Error{path + ": no intact event in " + std::to_string(bytes) +
               " bytes: every event is damaged (driftlab info lists where)"};
}

}  // namespace driftlab
