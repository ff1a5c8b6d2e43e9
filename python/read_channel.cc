#include "python/read_channel.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <tuple>
#include <unordered_map>

#include "core/log_format.h"
#include "core/log_reader.h"
#include "lcmtypes/schema.h"
#include "lcmtypes/type_registry.h"

namespace driftlab::python {
namespace {

/// NumPy's kind and item size of an LCM primitive.
std::pair<char, size_t> kind_of(const std::string& type) {
  if (type == "double") return {'f', 8};
  if (type == "float") return {'f', 4};
  if (type == "int64_t") return {'i', 8};
  if (type == "int32_t") return {'i', 4};
  if (type == "int16_t") return {'i', 2};
  if (type == "int8_t") return {'i', 1};
  if (type == "byte") return {'u', 1};
  if (type == "boolean") return {'b', 1};
  return {'O', 0};  // string
}

/// Reverses the bytes of each U-sized element of p[0, n) in place (n a multiple of sizeof(U)).
template <typename U, typename Swap>
void swap_each(uint8_t* p, size_t n, Swap swap) {
  for (size_t k = 0; k < n; k += sizeof(U)) {
    U v;
    std::memcpy(&v, p + k, sizeof(U));
    v = swap(v);
    std::memcpy(p + k, &v, sizeof(U));
  }
}

/// Appends n big-endian elements of `size` bytes to out in native order: copied (no zero-filling first, as resize
/// would), then swapped in place.
void append_swapped(std::vector<uint8_t>& out, std::span<const uint8_t> bytes, size_t size) {
  const size_t at = out.size();
  out.insert(out.end(), bytes.begin(), bytes.end());
  uint8_t* p = out.data() + at;
  const size_t n = bytes.size();
  switch (size) {
    case 8: swap_each<uint64_t>(p, n, [](uint64_t v) { return __builtin_bswap64(v); }); break;
    case 4: swap_each<uint32_t>(p, n, [](uint32_t v) { return __builtin_bswap32(v); }); break;
    case 2: swap_each<uint16_t>(p, n, [](uint16_t v) { return __builtin_bswap16(v); }); break;
    default: break;
  }
}

/// One channel's decoding state: its columns so far, filled message by message.
class ChannelReader {
 public:
  ChannelReader(std::string path, std::string channel, int64_t expected)
      : path_(std::move(path)),
        channel_(std::move(channel)),
        reserve_(static_cast<size_t>(std::max<int64_t>(expected, 0))) {
    out_.arrival.reserve(reserve_);
  }

  /// Decodes one message of the channel. Errors: the channel's first message is of no driftlab type.
  Result<bool> add(const Event& e) {
    const int64_t fp = logfmt::fingerprint(e.data);
    if (def_ == nullptr) {
      const char* name = e.data.size() >= 8 ? lcmtypes::type_name(fp) : nullptr;
      def_ = name != nullptr ? lcmtypes::find_struct(name) : nullptr;
      if (def_ == nullptr) {
        return Error{path_ + ": channel '" + channel_ + "' holds messages of no driftlab type (fingerprint " +
                     std::to_string(fp) + ")"};
      }
      out_.type = name;
      fingerprint_ = fp;
    }
    if (fp != fingerprint_) {
      ++out_.skipped;
      return true;
    }
    for (size_t k = 0; k < out_.columns.size(); ++k) {
      counts_[k] = 0;
      sizes_before_[k] = out_.columns[k].kind == 'O' ? out_.columns[k].strings.size() : out_.columns[k].data.size();
    }
    const size_t known = out_.columns.size();
    cursor_ = 0;
    const lcmtypes::RawFieldVisitor visit = [this](const std::string& column, const lcmtypes::FieldDef& field,
                                                   std::span<const uint8_t> bytes) {
      this->visit(column, field, bytes);
    };
    if (!lcmtypes::walk(*def_, e.data, visit)) {  // cut short: the message is left out whole
      for (size_t k = 0; k < known; ++k) {
        Column& c = out_.columns[k];
        if (c.kind == 'O') {
          c.strings.resize(sizes_before_[k]);
        } else {
          c.data.resize(sizes_before_[k]);
        }
      }
      for (size_t k = known; k < out_.columns.size(); ++k) {  // columns this message brought: none before
        out_.columns[k].data.clear();
        out_.columns[k].strings.clear();
      }
      ++out_.skipped;
      return true;
    }
    out_.arrival.push_back(e.utime);
    for (size_t k = 0; k < out_.columns.size(); ++k) out_.columns[k].counts.push_back(counts_[k]);
    return true;
  }

  Channel take() { return std::move(out_); }

 private:
  void visit(const std::string& column, const lcmtypes::FieldDef& field, std::span<const uint8_t> bytes) {
    size_t k = cursor_ < out_.columns.size() && out_.columns[cursor_].name == column ? cursor_ : SIZE_MAX;
    if (k == SIZE_MAX) {
      auto it = index_.find(column);
      if (it == index_.end()) {  // a column first met now: none in the messages before
        Column c;
        c.name = column;
        std::tie(c.kind, c.item_bytes) = kind_of(field.type);
        bool fixed = true;
        for (const auto& d : field.dims) {
          if (!std::isdigit(static_cast<unsigned char>(d[0]))) fixed = false;
        }
        if (fixed) {
          for (const auto& d : field.dims) c.dims.push_back(static_cast<size_t>(std::atoll(d.c_str())));
        }
        c.counts.assign(out_.arrival.size(), 0);
        size_t per_message = c.item_bytes;
        for (size_t d : c.dims) per_message *= d;
        if (c.kind != 'O') c.data.reserve(reserve_ * per_message);
        it = index_.emplace(column, out_.columns.size()).first;
        out_.columns.push_back(std::move(c));
        counts_.push_back(0);
        sizes_before_.push_back(0);
      }
      k = it->second;
    }
    cursor_ = k + 1;
    Column& c = out_.columns[k];
    if (c.kind == 'O') {
      c.strings.emplace_back(reinterpret_cast<const char*>(bytes.data()), bytes.size());
      ++counts_[k];
    } else {
      append_swapped(c.data, bytes, c.item_bytes);
      counts_[k] += static_cast<int64_t>(bytes.size() / c.item_bytes);
    }
  }

  std::string path_;
  std::string channel_;
  size_t reserve_;
  Channel out_;
  const lcmtypes::StructDef* def_ = nullptr;
  int64_t fingerprint_ = 0;
  std::unordered_map<std::string, size_t> index_;  // column name -> columns[]
  std::vector<int64_t> counts_;                    // elements of each column in the message being read
  std::vector<size_t> sizes_before_;               // data and strings sizes before it, to undo a cut-short message
  size_t cursor_ = 0;  // the column the next primitive most likely belongs to (fields come in the same order)
};

}  // namespace

Result<std::vector<Channel>> read_channels(const std::string& path,
                                           const std::vector<std::pair<std::string, int64_t>>& channels) {
  auto reader = LogReader::open(path);
  if (!reader) return reader.error();
  std::vector<ChannelReader> readers;
  readers.reserve(channels.size());
  for (const auto& [name, expected] : channels) readers.emplace_back(path, name, expected);
  Event e;
  while (reader->next(e)) {
    size_t k = 0;  // a log holds a few dozen channels at most: a scan is as quick as a hash
    while (k < channels.size() && channels[k].first != e.channel) ++k;
    if (k == channels.size()) continue;
    if (auto r = readers[k].add(e); !r) return r.error();
  }
  std::vector<Channel> out;
  out.reserve(readers.size());
  for (auto& r : readers) out.push_back(r.take());
  return out;
}

Result<Channel> read_channel(const std::string& path, const std::string& channel, int64_t expected) {
  auto r = read_channels(path, {{channel, expected}});
  if (!r) return r.error();
  return std::move(r->front());
}

}  // namespace driftlab::python
