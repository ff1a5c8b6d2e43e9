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

/// Appends n big-endian elements of `size` bytes to out in native order.
void append_swapped(std::vector<uint8_t>& out, std::span<const uint8_t> bytes, size_t size) {
  const size_t at = out.size();
  out.resize(at + bytes.size());
  uint8_t* dst = out.data() + at;
  const uint8_t* src = bytes.data();
  switch (size) {
    case 8:
      for (size_t k = 0; k < bytes.size(); k += 8) {
        uint64_t v;
        std::memcpy(&v, src + k, 8);
        v = __builtin_bswap64(v);
        std::memcpy(dst + k, &v, 8);
      }
      break;
    case 4:
      for (size_t k = 0; k < bytes.size(); k += 4) {
        uint32_t v;
        std::memcpy(&v, src + k, 4);
        v = __builtin_bswap32(v);
        std::memcpy(dst + k, &v, 4);
      }
      break;
    case 2:
      for (size_t k = 0; k < bytes.size(); k += 2) {
        uint16_t v;
        std::memcpy(&v, src + k, 2);
        v = __builtin_bswap16(v);
        std::memcpy(dst + k, &v, 2);
      }
      break;
    default: std::memcpy(dst, src, bytes.size());
  }
}

}  // namespace

Result<Channel> read_channel(const std::string& path, const std::string& channel, int64_t expected) {
  auto reader = LogReader::open(path);
  if (!reader) return reader.error();
  Channel out;
  const lcmtypes::StructDef* def = nullptr;
  int64_t fingerprint = 0;
  std::unordered_map<std::string, size_t> index;  // column name -> columns[]
  std::vector<int64_t> counts;                    // elements of each column in the message being read
  std::vector<size_t> sizes_before;               // data and strings sizes before it, to undo a cut-short message
  const auto reserve = static_cast<size_t>(std::max<int64_t>(expected, 0));
  out.arrival.reserve(reserve);
  size_t cursor = 0;  // the column the next primitive most likely belongs to (fields come in the same order)
  const lcmtypes::RawFieldVisitor visit = [&](const std::string& column, const lcmtypes::FieldDef& field,
                                              std::span<const uint8_t> bytes) {
    size_t k = cursor < out.columns.size() && out.columns[cursor].name == column ? cursor : SIZE_MAX;
    if (k == SIZE_MAX) {
      auto it = index.find(column);
      if (it == index.end()) {  // a column first met now: none in the messages before
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
        c.counts.assign(out.arrival.size(), 0);
        size_t per_message = c.item_bytes;
        for (size_t d : c.dims) per_message *= d;
        if (c.kind != 'O') c.data.reserve(reserve * per_message);
        it = index.emplace(column, out.columns.size()).first;
        out.columns.push_back(std::move(c));
        counts.push_back(0);
        sizes_before.push_back(0);
      }
      k = it->second;
    }
    cursor = k + 1;
    Column& c = out.columns[k];
    if (c.kind == 'O') {
      c.strings.emplace_back(reinterpret_cast<const char*>(bytes.data()), bytes.size());
      ++counts[k];
    } else {
      append_swapped(c.data, bytes, c.item_bytes);
      counts[k] += static_cast<int64_t>(bytes.size() / c.item_bytes);
    }
  };
  Event e;
  while (reader->next(e)) {
    if (e.channel != channel) continue;
    const int64_t fp = logfmt::fingerprint(e.data);
    if (def == nullptr) {
      const char* name = e.data.size() >= 8 ? lcmtypes::type_name(fp) : nullptr;
      def = name != nullptr ? lcmtypes::find_struct(name) : nullptr;
      if (def == nullptr) {
        return Error{path + ": channel '" + channel + "' holds messages of no driftlab type (fingerprint " +
                     std::to_string(fp) + ")"};
      }
      out.type = name;
      fingerprint = fp;
    }
    if (fp != fingerprint) {
      ++out.skipped;
      continue;
    }
    for (size_t k = 0; k < out.columns.size(); ++k) {
      counts[k] = 0;
      sizes_before[k] = out.columns[k].kind == 'O' ? out.columns[k].strings.size() : out.columns[k].data.size();
    }
    const size_t known = out.columns.size();
    cursor = 0;
    if (!lcmtypes::walk(*def, e.data, visit)) {  // cut short: the message is left out whole
      for (size_t k = 0; k < known; ++k) {
        Column& c = out.columns[k];
        if (c.kind == 'O') {
          c.strings.resize(sizes_before[k]);
        } else {
          c.data.resize(sizes_before[k]);
        }
      }
      for (size_t k = known; k < out.columns.size(); ++k) {  // columns this message brought: none before
        out.columns[k].data.clear();
        out.columns[k].strings.clear();
      }
      ++out.skipped;
      continue;
    }
    out.arrival.push_back(e.utime);
    for (size_t k = 0; k < out.columns.size(); ++k) out.columns[k].counts.push_back(counts[k]);
  }
  return out;
}

}  // namespace driftlab::python
