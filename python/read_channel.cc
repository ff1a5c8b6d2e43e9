#include "python/read_channel.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <new>
#include <optional>
#include <system_error>
#include <thread>
#include <tuple>
#include <unordered_map>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

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

/// The column of a field, without elements: its kind, element size and fixed dimensions (none when one is another
/// field's value).
Column empty_column(const std::string& name, const lcmtypes::FieldDef& field) {
  Column c;
  c.name = name;
  std::tie(c.kind, c.item_bytes) = kind_of(field.type);
  bool fixed = true;
  for (const auto& d : field.dims) {
    if (!std::isdigit(static_cast<unsigned char>(d[0]))) fixed = false;
  }
  if (fixed) {
    for (const auto& d : field.dims) c.dims.push_back(static_cast<size_t>(std::atoll(d.c_str())));
  }
  return c;
}

/// Copies the U-sized elements of src[0, bytes) to dst, each with its bytes reversed.
template <typename U, typename Swap>
void copy_each_swapped(uint8_t* dst, const uint8_t* src, size_t bytes, Swap swap) {
  for (size_t k = 0; k < bytes; k += sizeof(U)) {
    U v;
    std::memcpy(&v, src + k, sizeof(U));
    v = swap(v);
    std::memcpy(dst + k, &v, sizeof(U));
  }
}

/// Copies bytes (elements of `size` bytes, big-endian) to dst in native order.
inline void copy_swapped(uint8_t* dst, const uint8_t* src, size_t bytes, size_t size) {
  switch (size) {
    case 8: copy_each_swapped<uint64_t>(dst, src, bytes, [](uint64_t v) { return __builtin_bswap64(v); }); break;
    case 4: copy_each_swapped<uint32_t>(dst, src, bytes, [](uint32_t v) { return __builtin_bswap32(v); }); break;
    case 2: copy_each_swapped<uint16_t>(dst, src, bytes, [](uint16_t v) { return __builtin_bswap16(v); }); break;
    default: std::memcpy(dst, src, bytes); break;
  }
}

/// Appends n big-endian elements of `size` bytes to out in native order.
void append_swapped(Bytes& out, std::span<const uint8_t> bytes, size_t size) {
  const size_t at = out.size();
  out.resize(at + bytes.size());  // uninitialized: written next
  copy_swapped(out.data() + at, bytes.data(), bytes.size(), size);
}

/// One channel's decoding state through lcmtypes::walk (the reference): its columns so far, filled message by
/// message, each column made when a message first holds its field.
class WalkReader {
 public:
  WalkReader(std::string path, std::string channel, int64_t expected)
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
        Column c = empty_column(column, field);
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
      c.strings.push_back({reinterpret_cast<const char*>(bytes.data()), bytes.size()});
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

/// Events read ahead of the one decoded (EventTable::prefetch).
constexpr size_t kPrefetchAhead = 4;

/// The events of `channels` handed to their readers (a WalkReader or a PlanReader), each channel's in file order.
template <typename Reader>
Result<std::vector<Channel>> read_with(const EventTable& log,
                                       const std::vector<std::pair<std::string, int64_t>>& channels,
                                       std::vector<Reader>& readers) {
  for (size_t k = 0; k < channels.size(); ++k) {
    const std::vector<uint64_t>* offsets = log.offsets(channels[k].first);
    if (offsets == nullptr) continue;
    const size_t n = offsets->size();
    for (size_t i = 0; i < n; ++i) {
      // The events of a channel are scattered through the log: the next ones' first lines asked for ahead.
      if (i + kPrefetchAhead < n) log.prefetch((*offsets)[i + kPrefetchAhead]);
      if (auto r = readers[k].add(log.event_at((*offsets)[i])); !r) return r.error();
    }
  }
  std::vector<Channel> out;
  out.reserve(readers.size());
  for (auto& r : readers) out.push_back(r.take());
  return out;
}

/// Bytes of one element of an LCM primitive of fixed size; 0 for strings and structs (the walk's fixed_size).
size_t primitive_bytes(const std::string& type) {
  const auto [kind, size] = kind_of(type);
  return kind == 'O' ? 0 : size;
}

/// A message type compiled once for decoding: its fields flattened, in the walk's order, into ops that each copy
/// one field's numbers into its column (a scalar, or a whole array of numbers, swapped to native order), read one
/// string, or repeat the ops of an array of structs or strings. Array lengths held by earlier integer fields are
/// resolved at compile time to slots the decoder fills as it reads those fields.
struct DecodePlan {
  enum class Kind : uint8_t { kNumbers, kString, kLoop, kEnd };
  struct Op {
    Kind kind = Kind::kNumbers;
    uint8_t size = 0;         ///< kNumbers: bytes of one element
    bool is_byte = false;     ///< an LCM byte: unsigned when it is a length
    int32_t slot = -1;        ///< a scalar integer a later field takes its length from: where its value goes
    uint32_t column = 0;      ///< kNumbers, kString: the destination
    uint32_t end = 0;         ///< kLoop: the index of its kEnd
    int64_t count = 1;        ///< elements (kLoop: iterations): the product of the fixed dimensions
    uint32_t dims_begin = 0;  ///< dim_slots[dims_begin, dims_end): the slots of the variable dimensions
    uint32_t dims_end = 0;
  };
  std::vector<Op> ops;
  std::vector<int32_t> dim_slots;
  std::vector<Column> columns;  ///< name, kind, item_bytes, dims and fixed_count of each op's column
  int32_t slots = 0;
  size_t depth = 0;  ///< the deepest nesting of loops
};

/// Compiles a DecodePlan from a struct, recursing into its structs as lcmtypes::walk does.
class PlanCompiler {
 public:
  static DecodePlan compile(const lcmtypes::StructDef& def) {
    PlanCompiler c;
    c.fields(def, "", 1, 0);
    return std::move(c.plan_);
  }

 private:
  /// Fields of s, prefixed by prefix; repeat: elements of each column per message when every enclosing loop has a
  /// fixed count (else -1); depth: the enclosing loops.
  void fields(const lcmtypes::StructDef& s, const std::string& prefix, int64_t repeat, size_t depth) {
    plan_.depth = std::max(plan_.depth, depth);
    std::vector<std::pair<const std::string*, size_t>> ints;  // integer scalars so far: name, op
    for (const lcmtypes::FieldDef& f : s.fields) {
      const std::string column = prefix + f.name;
      DecodePlan::Op op;
      op.dims_begin = static_cast<uint32_t>(plan_.dim_slots.size());
      bool fixed = true;
      for (const auto& dim : f.dims) {
        if (std::isdigit(static_cast<unsigned char>(dim[0]))) {
          op.count *= std::atoll(dim.c_str());
          continue;
        }
        fixed = false;
        auto it = std::find_if(ints.rbegin(), ints.rend(), [&](const auto& i) { return *i.first == dim; });
        if (it == ints.rend()) {  // no such field: the walk takes 0
          op.count = 0;
          continue;
        }
        DecodePlan::Op& length = plan_.ops[it->second];
        if (length.slot < 0) length.slot = plan_.slots++;
        plan_.dim_slots.push_back(length.slot);
      }
      op.dims_end = static_cast<uint32_t>(plan_.dim_slots.size());
      const size_t size = primitive_bytes(f.type);
      const lcmtypes::StructDef* nested = size == 0 && f.type != "string" ? lcmtypes::find_struct(f.type) : nullptr;
      const int64_t per_message = repeat >= 0 && fixed ? repeat * op.count : -1;
      if (size > 0) {  // numbers: a scalar or a whole array in one op
        op.kind = DecodePlan::Kind::kNumbers;
        op.size = static_cast<uint8_t>(size);
        op.is_byte = f.type == "byte";
        op.column = add_column(column, f, per_message);
        if (f.dims.empty() && f.type != "double" && f.type != "float") ints.emplace_back(&f.name, plan_.ops.size());
        plan_.ops.push_back(op);
        continue;
      }
      if (f.dims.empty() && nested != nullptr) {
        fields(*nested, column + ".", repeat, depth);
        continue;
      }
      DecodePlan::Op string;
      string.kind = DecodePlan::Kind::kString;
      if (f.dims.empty()) {
        string.column = add_column(column, f, repeat);
        plan_.ops.push_back(string);
        continue;
      }
      op.kind = DecodePlan::Kind::kLoop;  // an array of structs or strings: its element's ops, repeated
      const size_t loop = plan_.ops.size();
      plan_.ops.push_back(op);
      if (nested != nullptr) {
        fields(*nested, column + ".", per_message, depth + 1);
      } else {
        plan_.depth = std::max(plan_.depth, depth + 1);
        string.column = add_column(column, f, per_message);
        plan_.ops.push_back(string);
      }
      DecodePlan::Op end;
      end.kind = DecodePlan::Kind::kEnd;
      plan_.ops[loop].end = static_cast<uint32_t>(plan_.ops.size());
      plan_.ops.push_back(end);
    }
  }

  uint32_t add_column(const std::string& name, const lcmtypes::FieldDef& field, int64_t per_message) {
    Column c = empty_column(name, field);
    c.fixed_count = per_message;
    plan_.columns.push_back(std::move(c));
    return static_cast<uint32_t>(plan_.columns.size() - 1);
  }

  DecodePlan plan_;
};

/// The plans of the types met in one read, each compiled once.
class PlanCache {
 public:
  const DecodePlan& get(const lcmtypes::StructDef& def) {
    auto& plan = plans_[&def];
    if (!plan) plan = std::make_unique<DecodePlan>(PlanCompiler::compile(def));
    return *plan;
  }

 private:
  std::unordered_map<const lcmtypes::StructDef*, std::unique_ptr<DecodePlan>> plans_;
};

/// A big-endian integer of `size` bytes, sign-extended unless an LCM byte (as the walk reads lengths).
inline int64_t integer_at(const uint8_t* p, size_t size, bool is_byte) {
  uint64_t word = 0;
  for (size_t k = 0; k < size; ++k) word = (word << 8) | p[k];
  const int shift = static_cast<int>(64 - 8 * size);
  return is_byte ? static_cast<int64_t>(word) : static_cast<int64_t>(word << shift) >> shift;
}

/// One channel's decoding state through its type's DecodePlan: the columns, sized from the index's count and
/// written in place, message after message, by one loop over the plan's ops.
class PlanReader {
 public:
  PlanReader(std::string path, std::string channel, int64_t expected, PlanCache* plans)
      : path_(std::move(path)),
        channel_(std::move(channel)),
        expected_(static_cast<size_t>(std::max<int64_t>(expected, 0))),
        plans_(plans) {
    out_.arrival.reserve(expected_);
  }

  /// Decodes one message of the channel. Errors: the channel's first message is of no driftlab type.
  Result<bool> add(const Event& e) {
    const int64_t fp = logfmt::fingerprint(e.data);
    if (plan_ == nullptr) {
      const char* name = e.data.size() >= 8 ? lcmtypes::type_name(fp) : nullptr;
      const lcmtypes::StructDef* def = name != nullptr ? lcmtypes::find_struct(name) : nullptr;
      if (def == nullptr) {
        return Error{path_ + ": channel '" + channel_ + "' holds messages of no driftlab type (fingerprint " +
                     std::to_string(fp) + ")"};
      }
      out_.type = name;
      fingerprint_ = fp;
      start(plans_->get(*def));
    }
    if (fp != fingerprint_) {
      ++out_.skipped;
      return true;
    }
    for (uint32_t k : variable_) before_[k] = filled(k);
    if (!decode(e.data)) {  // cut short: the message is left out whole
      for (size_t k = 0; k < columns_.size(); ++k) {
        const int64_t per_message = columns_[k].fixed_count;
        unfill(k, per_message >= 0 ? rows_ * static_cast<size_t>(per_message) : before_[k]);
      }
      ++out_.skipped;
      return true;
    }
    out_.arrival.push_back(e.utime);
    ++rows_;
    for (uint32_t k : variable_) columns_[k].counts.push_back(static_cast<int64_t>(filled(k) - before_[k]));
    if (rows_ == 1) size_variable_columns();
    return true;
  }

  /// The columns a message held, in the order the messages first held them (as the walk makes them).
  Channel take() {
    for (uint32_t k : order_) {
      Column& c = columns_[k];
      if (c.kind != 'O') c.data.resize(fill_[k]);
      out_.columns.push_back(std::move(c));
    }
    return std::move(out_);
  }

 private:
  void start(const DecodePlan& plan) {
    plan_ = &plan;
    columns_ = plan.columns;
    const size_t n = columns_.size();
    base_.assign(n, nullptr);
    fill_.assign(n, 0);
    capacity_.assign(n, 0);
    before_.assign(n, 0);
    seen_.assign(n, 0);
    slots_.assign(static_cast<size_t>(plan.slots), 0);
    loops_.assign(plan.depth + 1, {});
    for (uint32_t k = 0; k < n; ++k) {
      Column& c = columns_[k];
      if (c.fixed_count < 0) {
        variable_.push_back(k);
        c.counts.reserve(expected_);
      }
      const size_t per_message = c.fixed_count >= 0 ? static_cast<size_t>(c.fixed_count) : 1;
      if (c.kind == 'O') {
        c.strings.reserve(expected_ * per_message);
      } else {
        resize(k, expected_ * per_message * c.item_bytes);
      }
    }
  }

  /// Columns of varying counts sized as if every message held as many elements as the first: most channels keep
  /// their counts (a scan's beams, a TF's transforms), and growing by doubling would copy and over-allocate.
  void size_variable_columns() {
    for (uint32_t k : variable_) {
      Column& c = columns_[k];
      const auto first = static_cast<size_t>(c.counts.front());
      if (c.kind == 'O') {
        c.strings.reserve(expected_ * first);
      } else if (expected_ * first * c.item_bytes > capacity_[k]) {
        resize(k, expected_ * first * c.item_bytes);
      }
    }
  }

  size_t filled(size_t k) const {
    return columns_[k].kind == 'O' ? columns_[k].strings.size() : fill_[k] / columns_[k].item_bytes;
  }

  /// Back to `elements` elements in column k.
  void unfill(size_t k, size_t elements) {
    if (columns_[k].kind == 'O') {
      columns_[k].strings.resize(elements);
    } else {
      fill_[k] = elements * columns_[k].item_bytes;
    }
  }

  void see(uint32_t k) {
    if (seen_[k] == 0) {
      seen_[k] = 1;
      order_.push_back(k);
    }
  }

  /// Room for `bytes` more in column k.
  void grow(uint32_t k, size_t bytes) { resize(k, std::max(fill_[k] + bytes, 2 * capacity_[k] + 64)); }

  /// Column k's buffer made `bytes` long (uninitialized past what it held: written before it is read).
  void resize(uint32_t k, size_t bytes) {
    Bytes& data = columns_[k].data;
    data.resize(bytes);
    base_[k] = data.data();
    capacity_[k] = data.size();
  }

  /// op.count times the variable dimensions' lengths; false for a negative length (a message cut short).
  bool total_of(const DecodePlan::Op& op, int64_t& total) const {
    total = op.count;
    for (uint32_t d = op.dims_begin; d < op.dims_end; ++d) {
      const int64_t n = slots_[static_cast<size_t>(plan_->dim_slots[d])];
      if (n < 0) return false;
      if (__builtin_mul_overflow(total, n, &total)) return false;
    }
    return true;
  }

  /// Decodes one message into the columns as lcmtypes::walk visits it. False when it is shorter than it claims.
  bool decode(std::span<const uint8_t> data) {
    if (data.size() < 8) return false;
    const uint8_t* p = data.data() + 8;
    const uint8_t* const end = data.data() + data.size();
    const DecodePlan::Op* const ops = plan_->ops.data();
    const size_t n_ops = plan_->ops.size();
    size_t depth = 0;
    for (size_t i = 0; i < n_ops;) {
      const DecodePlan::Op& op = ops[i];
      switch (op.kind) {
        case DecodePlan::Kind::kNumbers: {
          int64_t total = 1;
          if (op.dims_begin != op.dims_end || op.count != 1) {
            if (!total_of(op, total)) return false;
          }
          const size_t size = op.size;
          if (static_cast<uint64_t>(total) > static_cast<size_t>(end - p) / size) return false;
          const size_t bytes = static_cast<size_t>(total) * size;
          const uint32_t k = op.column;
          see(k);
          if (fill_[k] + bytes > capacity_[k]) grow(k, bytes);
          copy_swapped(base_[k] + fill_[k], p, bytes, size);
          fill_[k] += bytes;
          if (op.slot >= 0) slots_[static_cast<size_t>(op.slot)] = integer_at(p, size, op.is_byte);
          p += bytes;
          ++i;
          break;
        }
        case DecodePlan::Kind::kString: {
          if (end - p < 4) return false;
          const auto n = static_cast<uint32_t>(integer_at(p, 4, true));  // with its NUL
          p += 4;
          if (n == 0 || static_cast<size_t>(end - p) < n) return false;
          see(op.column);
          columns_[op.column].strings.push_back({reinterpret_cast<const char*>(p), n - 1});
          p += n;
          ++i;
          break;
        }
        case DecodePlan::Kind::kLoop: {
          int64_t total = 0;
          if (!total_of(op, total)) return false;
          if (total == 0) {
            i = op.end + 1;
            break;
          }
          loops_[depth++] = {i, total};
          ++i;
          break;
        }
        case DecodePlan::Kind::kEnd: {
          Loop& loop = loops_[depth - 1];
          if (--loop.left > 0) {
            i = loop.begin + 1;
          } else {
            --depth;
            ++i;
          }
          break;
        }
      }
    }
    return true;
  }

  struct Loop {
    size_t begin = 0;  ///< the kLoop op
    int64_t left = 0;  ///< iterations left, this one included
  };

  std::string path_;
  std::string channel_;
  size_t expected_;
  PlanCache* plans_;
  const DecodePlan* plan_ = nullptr;
  int64_t fingerprint_ = 0;
  Channel out_;
  size_t rows_ = 0;                 // messages decoded
  std::vector<Column> columns_;     // the plan's, filled
  std::vector<uint8_t*> base_;      // columns_[k].data.data()
  std::vector<size_t> fill_;        // bytes written to each numbers column
  std::vector<size_t> capacity_;    // columns_[k].data.size()
  std::vector<uint32_t> variable_;  // columns whose messages hold varying counts
  std::vector<size_t> before_;      // elements of those columns before the message being read
  std::vector<uint8_t> seen_;       // whether a message held column k yet
  std::vector<uint32_t> order_;     // columns in the order messages first held them
  std::vector<int64_t> slots_;      // lengths read in the message being read
  std::vector<Loop> loops_;         // the loops the decoder is in
};

}  // namespace

namespace {
constexpr size_t kHugePage = size_t{2} << 20;
}  // namespace

void* allocate_column(size_t bytes) {
  // From 1 MiB: a page fault per 4 KiB costs more than the rest of the last huge page, unused (the columns of a
  // channel of 200,000 messages are 1.6 MB each).
  if (bytes < kHugePage / 2) {
    void* p = std::malloc(std::max<size_t>(bytes, 1));
    if (p == nullptr) throw std::bad_alloc();
    return p;
  }
  void* p = std::aligned_alloc(kHugePage, (bytes + kHugePage - 1) / kHugePage * kHugePage);
  if (p == nullptr) throw std::bad_alloc();
  madvise(p, (bytes + kHugePage - 1) / kHugePage * kHugePage,
          MADV_HUGEPAGE);  // advice only: without it (or huge pages), small pages
  return p;
}

void free_column(void* p, size_t /*bytes*/) noexcept { std::free(p); }

Result<std::shared_ptr<const EventTable>> EventTable::build(const std::string& path) {
  auto mapped = MappedFile::open(path);
  if (!mapped) return mapped.error();
  const std::span<const uint8_t> bytes = mapped->bytes();
#ifdef MADV_POPULATE_READ
  // Every page mapped in one call rather than a page fault per 4 KiB (advice: without it, faults).
  if (!bytes.empty()) madvise(const_cast<uint8_t*>(bytes.data()), bytes.size(), MADV_POPULATE_READ);
#endif
  auto table = std::make_shared<EventTable>(path, std::move(*mapped));
  auto reader = LogReader::from_memory(bytes);
  if (!reader) return reader.error();
  Event e;
  std::vector<uint64_t>* last = nullptr;  // events come in runs of a channel often enough to skip the hash
  std::string_view last_channel;
  while (reader->next(e)) {
    if (last == nullptr || e.channel != last_channel) {
      last = &table->offsets_[std::string(e.channel)];
      last_channel = e.channel;
    }
    last->push_back(e.offset);
  }
  return std::shared_ptr<const EventTable>(std::move(table));
}

const std::vector<uint64_t>* EventTable::offsets(const std::string& channel) const {
  auto it = offsets_.find(channel);
  return it == offsets_.end() ? nullptr : &it->second;
}

void EventTable::prefetch(uint64_t offset) const {
  const uint8_t* p = mapped_.bytes().data() + offset;
  const uint8_t* end = mapped_.bytes().data() + mapped_.bytes().size();
  for (int line = 0; line < 8 && p < end; ++line, p += 64) __builtin_prefetch(p);
}

Event EventTable::event_at(uint64_t offset) const {
  const uint8_t* p = mapped_.bytes().data() + offset;  // an intact event (build() found it)
  Event e;
  e.event_number = static_cast<int64_t>(logfmt::load_be64(p + 4));
  e.utime = static_cast<int64_t>(logfmt::load_be64(p + 12));
  const auto channel_len = static_cast<size_t>(logfmt::load_be32(p + 20));
  const auto data_len = static_cast<size_t>(logfmt::load_be32(p + 24));
  e.channel = {reinterpret_cast<const char*>(p + logfmt::kEventHeaderSize), channel_len};
  e.data = {p + logfmt::kEventHeaderSize + channel_len, data_len};
  e.offset = offset;
  return e;
}

Result<std::vector<Channel>> read_channels(const EventTable& log,
                                           const std::vector<std::pair<std::string, int64_t>>& channels) {
  PlanCache plans;
  std::vector<PlanReader> readers;
  readers.reserve(channels.size());
  for (const auto& [name, expected] : channels) readers.emplace_back(log.path(), name, expected, &plans);
  return read_with(log, channels, readers);
}

namespace {

/// A file read forward through one buffer with pread(2): a pass over a log copies each byte once into a buffer
/// that stays mapped, where a mapping of the file costs a page fault per 4 KiB at its first touch in the process
/// (on this machine's virtual machine, more than the copy: 0.33 s against 0.13 s for 721 MB).
class ForwardFile {
 public:
  explicit ForwardFile(const std::string& path) : fd_(::open(path.c_str(), O_RDONLY | O_CLOEXEC)) {
    struct stat st {};
    if (fd_ >= 0 && ::fstat(fd_, &st) == 0 && S_ISREG(st.st_mode)) size_ = static_cast<uint64_t>(st.st_size);
  }
  ForwardFile(const ForwardFile&) = delete;
  ForwardFile& operator=(const ForwardFile&) = delete;
  ~ForwardFile() {
    if (fd_ >= 0) ::close(fd_);
  }

  uint64_t size() const { return size_; }

  /// The bytes [pos, pos + n) of the file (pos at or after the last call's; pos + n <= size()); nullptr when they
  /// cannot be read. What lies before pos may be dropped.
  const uint8_t* get(uint64_t pos, uint64_t n) {
    if (pos >= start_ && pos + n <= end_) return buffer_.data() + (pos - start_);
    const uint64_t keep = pos >= start_ && pos < end_ ? end_ - pos : 0;
    if (keep > 0) std::memmove(buffer_.data(), buffer_.data() + (pos - start_), keep);
    if (buffer_.size() < n) buffer_.resize(std::max<uint64_t>(n, 2 * buffer_.size()));
    start_ = pos;
    end_ = pos + keep;
    const uint64_t until = std::min(size_, start_ + buffer_.size());
    while (end_ < until) {
      const ssize_t got = ::pread(fd_, buffer_.data() + (end_ - start_), until - end_, static_cast<off_t>(end_));
      if (got > 0) {
        end_ += static_cast<uint64_t>(got);
      } else if (got == 0 || errno != EINTR) {
        break;
      }
    }
    return pos + n <= end_ ? buffer_.data() : nullptr;
  }

 private:
  /// [bytes]: a few hundred events of a few hundred bytes, in the core's cache when they are decoded.
  static constexpr size_t kBuffer = size_t{1} << 20;
  int fd_ = -1;
  uint64_t size_ = 0;
  std::vector<uint8_t> buffer_ = std::vector<uint8_t>(kBuffer);
  uint64_t start_ = 0;  // the file offset of buffer_[0]
  uint64_t end_ = 0;    // where the bytes buffer_ holds end
};

/// Calls on_event with each event of the log at path, in file order, while the log is intact: each event starts
/// with the sync word where the one before it ended (the first at 0), has a sane header, and ends where the next
/// starts or at the end of the file. Those are the events LogReader finds, none with a problem. False (after
/// calling on_event for the events before) at the first place where the log is not so, or cannot be read.
template <typename OnEvent>
bool for_each_intact_event(const std::string& path, OnEvent&& on_event) {
  ForwardFile file(path);
  const uint64_t size = file.size();
  if (size == 0) return false;
  Event e;
  for (uint64_t pos = 0; pos < size;) {
    if (size - pos < logfmt::kEventHeaderSize) return false;
    const uint8_t* p = file.get(pos, logfmt::kEventHeaderSize);
    if (p == nullptr || logfmt::load_be32(p) != logfmt::kSyncWord) return false;
    const auto channel_len = static_cast<int32_t>(logfmt::load_be32(p + 20));
    const auto data_len = static_cast<int32_t>(logfmt::load_be32(p + 24));
    if (channel_len <= 0 || channel_len > logfmt::kMaxChannelLength || data_len < 0) return false;
    const uint64_t length =
        logfmt::kEventHeaderSize + static_cast<uint64_t>(channel_len) + static_cast<uint64_t>(data_len);
    if (length > size - pos) return false;
    const uint64_t end = pos + length;
    if (end != size && size - end < 4) return false;
    p = file.get(pos, end == size ? length : length + 4);  // with the next event's sync word
    if (p == nullptr || (end != size && logfmt::load_be32(p + length) != logfmt::kSyncWord)) return false;
    e.event_number = static_cast<int64_t>(logfmt::load_be64(p + 4));
    e.utime = static_cast<int64_t>(logfmt::load_be64(p + 12));
    e.channel = {reinterpret_cast<const char*>(p + logfmt::kEventHeaderSize), static_cast<size_t>(channel_len)};
    e.data = {p + logfmt::kEventHeaderSize + channel_len, static_cast<size_t>(data_len)};
    e.offset = pos;
    on_event(e);
    pos = end;
  }
  return true;
}

/// The channels shared between `threads` passes, by their bytes: each channel in turn, the biggest first, to the
/// pass with the fewest bytes so far.
std::vector<std::vector<size_t>> share(const std::vector<uint64_t>& bytes, size_t threads) {
  std::vector<size_t> order(bytes.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return bytes[a] > bytes[b]; });
  std::vector<std::vector<size_t>> shares(threads);
  std::vector<uint64_t> load(threads, 0);
  for (size_t k : order) {
    const size_t t = static_cast<size_t>(std::min_element(load.begin(), load.end()) - load.begin());
    shares[t].push_back(k);
    load[t] += bytes[k];
  }
  for (auto& s : shares) std::sort(s.begin(), s.end());
  return shares;
}

}  // namespace

Result<std::optional<std::vector<Channel>>> read_intact_log(
    const std::string& path, const std::vector<std::pair<std::string, int64_t>>& channels,
    const std::vector<uint64_t>& bytes, size_t threads) {
  const size_t n = channels.size();
  threads = std::max<size_t>(1, std::min(threads, n));
  const std::vector<std::vector<size_t>> shares = share(bytes, threads);
  std::vector<PlanCache> plans(threads);  // a cache per thread
  std::vector<PlanReader> readers;
  readers.reserve(n);
  std::vector<size_t> thread_of(n, 0);
  for (size_t t = 0; t < threads; ++t) {
    for (size_t k : shares[t]) thread_of[k] = t;
  }
  for (size_t k = 0; k < n; ++k)
    readers.emplace_back(path, channels[k].first, channels[k].second, &plans[thread_of[k]]);
  std::vector<std::optional<Error>> failed(n);
  std::vector<uint8_t> intact(threads, 0);
  const auto pass = [&](size_t t) {
    // The channels met so far, each with its reader (SIZE_MAX: another pass's, or none): a log holds a few dozen
    // at most, the one met last looked at first.
    std::vector<std::pair<std::string, size_t>> met;
    size_t last = 0;
    intact[t] = for_each_intact_event(path, [&](const Event& e) {
      if (last >= met.size() || met[last].first != e.channel) {
        last = 0;
        while (last < met.size() && met[last].first != e.channel) ++last;
        if (last == met.size()) {
          size_t reader = SIZE_MAX;
          for (size_t k : shares[t]) {
            if (channels[k].first == e.channel) reader = k;
          }
          met.emplace_back(std::string(e.channel), reader);
        }
      }
      const size_t reader = met[last].second;
      if (reader == SIZE_MAX || failed[reader]) return;
      if (auto r = readers[reader].add(e); !r) failed[reader] = r.error();
    });
  };
  // What a pass threw (std::bad_alloc for a column a damaged count would make too large), thrown again here once
  // every pass is done.
  std::vector<std::exception_ptr> thrown(threads);
  const auto guarded = [&](size_t t) {
    try {
      pass(t);
    } catch (...) {
      thrown[t] = std::current_exception();
    }
  };
  std::vector<std::thread> others;
  std::vector<size_t> here = {0};  // the passes made on this thread: the first, and any no thread could be made for
  for (size_t t = 1; t < threads; ++t) {
    try {
      others.emplace_back(guarded, t);
    } catch (const std::system_error&) {
      here.push_back(t);
    }
  }
  for (size_t t : here) guarded(t);
  for (auto& t : others) t.join();
  for (const auto& e : thrown) {
    if (e) std::rethrow_exception(e);
  }
  if (std::find(intact.begin(), intact.end(), 0) != intact.end()) return std::optional<std::vector<Channel>>();
  for (auto& f : failed) {  // the first of the channels (in their order) whose messages are of no driftlab type
    if (f) return *f;
  }
  std::vector<Channel> out;
  out.reserve(n);
  for (auto& r : readers) out.push_back(r.take());
  return std::optional<std::vector<Channel>>(std::move(out));
}

Result<std::vector<Channel>> read_channels_reference(const std::string& path,
                                                     const std::vector<std::pair<std::string, int64_t>>& channels) {
  // A pass over the log with LogReader, as every reader did before the plans: independent of EventTable.
  auto reader = LogReader::open(path);
  if (!reader) return reader.error();
  std::vector<WalkReader> readers;
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

}  // namespace driftlab::python
