#include "formats/import.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <optional>
#include <set>

#include <filesystem>
#include <memory>

#include "core/log_writer.h"
#include "core/number_text.h"
#include "core/text_file.h"
#include "driftlab/channel_source_t.hpp"
#include "driftlab/dropout_t.hpp"
#include "driftlab/foreign_message_t.hpp"
#include "driftlab/foreign_schema_t.hpp"
#include "driftlab/log_text_t.hpp"
#include "driftlab/parameter_t.hpp"
#include "driftlab/stamped_foreign_message_t.hpp"
#include "driftlab/timesync_status_t.hpp"
#include "formats/carmen.h"
#include "formats/compression.h"
#include "formats/mcap.h"
#include "formats/ros1_bag.h"
#include "formats/ros2_bag.h"
#include "formats/ros_definition.h"
#include "formats/ros_messages.h"
#include "formats/ulog.h"
#include "formats/ulog_messages.h"
#include "lcmtypes/encode.h"
#include "lcmtypes/seq_origin.h"

namespace driftlab::formats {
namespace {

using lcmtypes::encode;

constexpr char kSchemaChannel[] = "FOREIGN_SCHEMAS";

/// A string as an LCM message holds it: up to its first NUL (LCM encodes strings so).
std::string lcm_text(std::string_view v) { return std::string(v.substr(0, v.find('\0'))); }

/// Up to n bytes from the start of path (fewer for a short file; empty when it cannot be read).
std::string head_of(const std::string& path, size_t n) {
  std::string s(n, '\0');
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return {};
  const ssize_t got = ::read(fd, s.data(), n);
  ::close(fd);
  s.resize(got > 0 ? static_cast<size_t>(got) : 0);
  return s;
}

/// MRPT's serialization starts every object with 0x80 + the length of its class name, then the name: MRPT 1's
/// "CSensoryFrame", MRPT 2's with its namespace, "mrpt::obs::CObservationOdometry" (what carmen2rawlog writes).
bool looks_like_mrpt(std::string_view h) {
  if (h.size() < 2) return false;
  const auto first = static_cast<unsigned char>(h[0]);
  const size_t len = first & 0x7f;
  if (!(first & 0x80) || len < 2 || len > 100 || h.size() < 1 + len) return false;
  const std::string_view name = h.substr(1, len);
  if (name[0] != 'C' && !name.starts_with("mrpt::")) return false;
  return std::all_of(name.begin(), name.end(),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == ':'; });
}

std::string describe(std::string_view h) {
  if (h.empty()) return "an empty file";
  const bool text = std::all_of(h.begin(), h.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u >= 0x20 || c == '\n' || c == '\r' || c == '\t' || u >= 0x80;
  });
  if (text) {
    std::string first(h.substr(0, std::min<size_t>(h.find('\n'), 40)));
    return "text starting \"" + first + "\"";
  }
  static constexpr char kHex[] = "0123456789abcdef";
  std::string bytes;
  for (size_t i = 0; i < std::min<size_t>(h.size(), 8); ++i) {
    const auto u = static_cast<unsigned char>(h[i]);
    bytes += std::string{kHex[u >> 4], kHex[u & 15]} + (i + 1 < std::min<size_t>(h.size(), 8) ? " " : "");
  }
  return "binary data starting " + bytes;
}

/// Where a message was met, for problem lines.
struct Where {
  enum Kind { kByte, kChunk, kRow } kind = kByte;
  uint64_t offset = 0;   ///< file offset (kByte, kChunk), or the row id (kRow)
  int64_t in_chunk = 0;  ///< kChunk: the record's offset in the chunk's records
  std::string text() const {
    switch (kind) {
      case kByte: return "at byte " + std::to_string(offset);
      case kChunk:
        return "at byte " + std::to_string(offset) + " (in the chunk there, byte " + std::to_string(in_chunk) +
               " of its records)";
      case kRow: return "at row " + std::to_string(offset);
    }
    return {};
  }
};

/// A message of a ROS bag or MCAP file, as every reader hands it on.
struct Incoming {
  std::string_view topic;
  std::string_view type;                 ///< as the file names it ("sensor_msgs/msg/LaserScan")
  std::string_view encoding;             ///< "ros1", "cdr", or another MCAP message encoding
  std::string_view definition;           ///< its schema text ("" when the file has none)
  std::string_view definition_encoding;  ///< "ros1msg", "ros2msg", "ros2idl", "jsonschema", ...
  int64_t arrival_us = 0;
  bool has_sequence = false;  ///< MCAP: a sequence number travels with it
  uint32_t sequence = 0;
  /// What an earlier import said of the channel (driftlab export keeps it in an MCAP channel's metadata): its type
  /// in the first recording, and where its seq came from.
  std::string_view source_type;
  std::optional<lcmtypes::SeqOrigin> seq_origin;
  std::span<const uint8_t> payload;
  Where where;
};

class Importer {
 public:
  Importer(LogWriter writer, std::function<void(const std::string&)> on_problem)
      : writer_(std::move(writer)), on_problem_(std::move(on_problem)) {}

  ImportSummary summary;
  std::string file;  ///< the file being read, for problem lines

  LogWriter& writer() { return writer_; }
  const Status& status() const { return status_; }

  /// A temporary file read in place of the user's (a zstd-compressed bag decompressed) and what problems call it.
  std::string temporary, temporary_named;

  void problem(const std::string& line) {
    ++summary.problems;
    on_problem_(named(line));
  }

  /// line with the temporary file, at its start, named as the user knows it: the temporary is gone when it is read.
  std::string named(const std::string& line) const {
    if (temporary.empty() || !line.starts_with(temporary)) return line;
    return temporary_named + line.substr(temporary.size());
  }

  TopicCount& topic(std::string_view channel, std::string_view source_type, const char* driftlab_type) {
    auto it = topic_index_.find(channel);
    if (it == topic_index_.end()) {
      it = topic_index_.emplace(std::string(channel), summary.topics.size()).first;
      summary.topics.push_back({std::string(channel), std::string(source_type), driftlab_type, 0, 0});
    }
    return summary.topics[it->second];
  }
  bool write(int64_t utime, std::string_view channel, std::span<const uint8_t> bytes) {
    if (!status_) return false;
    status_ = writer_.write(utime, channel, bytes);
    if (!status_) return false;
    ++summary.messages;
    return true;
  }
  /// Says what the recording knew of a channel that its messages do not (channel_source_t), once, before the
  /// channel's first message: from that message (an MCAP channel whose first sequence is 0 is taken as counted, as
  /// rosbag2 writes 0 for every message; one whose sequence starts later at 0 and then counts is taken so too).
  bool describe(int64_t utime, std::string_view channel, std::string_view source_type, lcmtypes::SeqOrigin origin) {
    if (!sources_.emplace(channel).second) return status_.ok();
    channel_source_t s{};
    s.channel = lcm_text(channel);
    s.source_type = lcm_text(source_type);
    s.seq_origin = static_cast<int8_t>(origin);
    return write(utime, lcmtypes::kChannelSources, encode(s));
  }

  /// Converts one ROS message: a mapped type onto its driftlab type, any other carried as foreign_message_t after
  /// a check against its schema.
  void message(const Incoming& m) {
    if (!status_) return;
    // A channel name an LCM log can hold: 1 to 255 bytes, no NUL.
    if (m.topic.empty() || m.topic.size() > 255 || m.topic.find('\0') != std::string_view::npos) {
      if (bad_topics_++ == 0) {
        problem(file + ": " + m.where.text() + ": a topic name an LCM log cannot hold (empty, over 255 bytes or "
                "with a NUL); its messages are left out");
      }
      return;
    }
    auto sit = state_.find(m.topic);
    if (sit == state_.end()) sit = state_.emplace(std::string(m.topic), State{}).first;
    State& st = sit->second;
    std::span<const uint8_t> payload = m.payload;
    if (m.encoding == "cdr" && looks_like_zstd(payload)) {
      // rosbag2's message compression: each payload a zstd frame (a CDR payload starts with a zero byte).
      if (std::string e = decompressor_.run(Codec::kZstd, payload, 0, unpacked_); !e.empty()) {
        ++topic(m.topic, m.type, "driftlab.foreign_message_t").malformed;
        problem(file + ": " + std::string(m.topic) + " " + m.where.text() + ": a compressed message: " + e);
        return;
      }
      payload = unpacked_;
    }
    // header.seq where the message carries none: MCAP's sequence once the channel shows one, else the count.
    if (m.has_sequence && (m.sequence != 0 || st.sequences)) {
      if (st.sequences && m.sequence < st.last_sequence && st.last_sequence - m.sequence > (1u << 31)) {
        st.sequence_high += int64_t{1} << 32;  // wrapped
      }
      st.sequences = true;
      st.last_sequence = m.sequence;
    }
    const int64_t fallback_seq = st.sequences ? st.sequence_high + m.sequence : st.count;
    const Serialization ser = m.encoding == "ros1" ? Serialization::kRos1 : Serialization::kCdr;
    const bool ros = m.encoding == "ros1" || m.encoding == "cdr";
    const char* mapped = ros ? driftlab_type_for(m.type) : nullptr;
    if (mapped) {
      TopicCount& t = topic(m.topic, m.type, mapped);
      auto converted = convert_ros_message(m.type, ser, payload, m.arrival_us, fallback_seq, &error_, &reuse_);
      if (!converted) {
        ++t.malformed;
        problem(file + ": " + std::string(m.topic) + " " + m.where.text() + ": " + error_);
        return;
      }
      using lcmtypes::SeqOrigin;
      const SeqOrigin origin = converted->has_seq ? SeqOrigin::kSource
                               : st.sequences     ? SeqOrigin::kTransport
                                                  : SeqOrigin::kCounted;
      if (describe(m.arrival_us, m.topic, m.source_type.empty() ? m.type : m.source_type,
                   m.seq_origin.value_or(origin)) &&
          write(m.arrival_us, m.topic, converted->lcm)) {
        ++t.messages;
        ++st.count;
      }
      // A large message's buffer is kept for the next one (a point cloud's took it; a small one's is let go).
      if (converted->lcm.capacity() > reuse_.capacity()) reuse_ = std::move(converted->lcm);
      return;
    }
    if (ros && !st.definition_checked) {
      st.definition_checked = true;
      st.clock = is_ros_clock_type(m.type);
      st.stamped = st.clock;
      const bool msg_text = m.definition_encoding == "ros1msg" || m.definition_encoding == "ros2msg";
      if (msg_text && !m.definition.empty()) {
        auto d = RosDefinition::parse(m.type, m.definition, ser);
        if (d) {
          st.definition = std::make_unique<RosDefinition>(std::move(*d));
          // A type that starts with a std_msgs/Header is carried with its header read out (any stamped message).
          const auto& types = st.definition->types();
          const auto& fields = types[0].fields;
          st.stamped =
              st.clock || (!fields.empty() && fields[0].complex >= 0 && fields[0].array == RosField::Array::kNone &&
                           types[static_cast<size_t>(fields[0].complex)].name == "std_msgs/Header");
        } else {
          problem(file + ": " + std::string(m.topic) + " " + m.where.text() + ": the schema of " +
                  std::string(m.type) + " does not parse (" + d.error().message +
                  "); its messages are carried unchecked");
        }
      }
    }
    TopicCount& t =
        topic(m.topic, m.type, st.stamped ? "driftlab.stamped_foreign_message_t" : "driftlab.foreign_message_t");
    if (st.definition) {
      if (std::string why = st.definition->check(payload); !why.empty()) {
        ++t.malformed;
        problem(file + ": " + std::string(m.topic) + " " + m.where.text() + ": not a " + std::string(m.type) +
                ": " + why);
        return;
      }
    }
    header_t header{};
    bool has_seq = false;
    // A checked message holds its header; read_leading_header cannot fail on one.
    if (st.clock) {
      if (!read_clock(ser, payload, fallback_seq, &header)) {
        ++t.malformed;
        problem(file + ": " + std::string(m.topic) + " " + m.where.text() + ": not a " + std::string(m.type) +
                ": shorter than a time");
        return;
      }
    } else if (st.stamped) {
      read_leading_header(ser, payload, fallback_seq, &header, &has_seq);
    }
    using lcmtypes::SeqOrigin;
    const SeqOrigin origin = has_seq ? SeqOrigin::kSource : st.sequences ? SeqOrigin::kTransport : SeqOrigin::kCounted;
    if (!describe(m.arrival_us, m.topic, m.source_type.empty() ? m.type : m.source_type,
                  m.seq_origin.value_or(origin))) {
      return;
    }
    if (!st.schema_written) {
      foreign_schema_t s{};
      s.channel = std::string(m.topic);
      s.type = lcm_text(m.type);
      s.encoding = lcm_text(m.encoding);
      s.definition = lcm_text(m.definition);
      if (!write(m.arrival_us, kSchemaChannel, encode(s))) return;
      st.schema_written = true;
    }
    bool written = false;
    if (st.stamped) {
      stamped_foreign_message_t f{};
      f.header = std::move(header);
      f.type = lcm_text(m.type);
      f.encoding = lcm_text(m.encoding);
      f.data.assign(payload.begin(), payload.end());
      f.size = static_cast<int32_t>(f.data.size());
      written = write(m.arrival_us, m.topic, encode(f));
    } else {
      foreign_message_t f{};
      f.type = lcm_text(m.type);
      f.encoding = lcm_text(m.encoding);
      f.data.assign(payload.begin(), payload.end());
      f.size = static_cast<int32_t>(f.data.size());
      written = write(m.arrival_us, m.topic, encode(f));
    }
    if (written) {
      ++t.messages;
      ++st.count;
    }
  }

 private:
  struct State {
    int64_t count = 0;
    bool sequences = false;
    uint32_t last_sequence = 0;
    int64_t sequence_high = 0;
    bool definition_checked = false;
    bool stamped = false;  // its definition starts with a std_msgs/Header: carried as stamped_foreign_message_t
    bool clock = false;    // rosgraph_msgs/Clock: carried stamped with its time
    bool schema_written = false;
    std::unique_ptr<RosDefinition> definition;
  };
  LogWriter writer_;
  std::function<void(const std::string&)> on_problem_;
  std::map<std::string, size_t, std::less<>> topic_index_;
  std::map<std::string, State, std::less<>> state_;
  std::set<std::string, std::less<>> sources_;  // the channels described
  Status status_;
  std::string error_;
  int64_t bad_topics_ = 0;
  Decompressor decompressor_;
  std::vector<uint8_t> unpacked_;
  std::vector<uint8_t> reuse_;  // the last large converted message's memory, for the next (convert_ros_message)
};

Status import_ros1(const std::string& path, Importer& out) {
  auto bag = Ros1BagReader::open(path);
  if (!bag) return bag.error();
  bag->read(
      [&](const BagMessage& m) {
        const RosConnection& c = *m.connection;
        Incoming in;
        in.topic = c.topic;
        in.type = c.type;
        in.encoding = "ros1";
        in.definition = c.definition;
        in.definition_encoding = "ros1msg";
        in.arrival_us = m.record_time_ns / 1000;
        in.payload = m.data;
        in.where = {Where::kByte, m.offset, 0};
        out.message(in);
      },
      [&](const BagProblem& p) { out.problem(path + ": at byte " + std::to_string(p.offset) + ": " + p.what); });
  return out.status();
}

Status import_mcap(const std::string& path, Importer& out) {
  auto mcap = McapReader::open(path);
  if (!mcap) return mcap.error();
  const int64_t problems_before = out.summary.problems;
  const int64_t read = mcap->read(
      [&](const McapMessage& m) {
        const McapChannel& c = *m.channel;
        Incoming in;
        in.topic = c.topic;
        // A channel whose name is not a ROS name went out under one, with the original beside (driftlab export).
        // And what the import before the export said of it (channel_source_t).
        for (const auto& [k, v] : c.metadata) {
          if (k == "driftlab_channel" && !v.empty()) in.topic = v;
          if (k == "driftlab_source_type") in.source_type = v;
          if (k == "driftlab_seq_origin" && v.size() == 1 && v[0] >= '0' && v[0] <= '2') {
            in.seq_origin = static_cast<lcmtypes::SeqOrigin>(v[0] - '0');
          }
        }
        in.type = c.schema ? std::string_view(c.schema->name) : std::string_view();
        in.encoding = c.message_encoding;
        in.definition = c.schema ? std::string_view(c.schema->data) : std::string_view();
        in.definition_encoding = c.schema ? std::string_view(c.schema->encoding) : std::string_view();
        in.arrival_us = static_cast<int64_t>(m.log_time / 1000);
        in.has_sequence = true;
        in.sequence = m.sequence;
        in.payload = m.data;
        in.where = m.offset_in_chunk >= 0 ? Where{Where::kChunk, m.offset, m.offset_in_chunk}
                                          : Where{Where::kByte, m.offset, 0};
        out.message(in);
      },
      [&](const McapProblem& p) { out.problem(path + ": at byte " + std::to_string(p.offset) + ": " + p.what); });
  // Every message accounted for: the summary's count against what was read (when nothing else was reported).
  if (const McapStatistics* st = mcap->statistics();
      st && out.summary.problems == problems_before && st->message_count != static_cast<uint64_t>(read)) {
    out.problem(path + ": the summary counts " + std::to_string(st->message_count) + " messages; " +
                std::to_string(read) + " were read");
  }
  return out.status();
}

Status import_sqlite(const std::string& path, Importer& out) {
  auto db = SqliteBagReader::open(path);
  if (!db) return db.error();
  db->read(
      [&](const Ros2DbMessage& m) {
        const Ros2TopicInfo& t = *m.topic;
        Incoming in;
        in.topic = t.name;
        in.type = t.type;
        in.encoding = t.serialization_format;
        if (auto d = db->definitions().find(t.type); d != db->definitions().end()) {
          in.definition_encoding = d->second.first;
          in.definition = d->second.second;
        }
        in.arrival_us = m.timestamp_ns / 1000;
        in.payload = m.data;
        in.where = {Where::kRow, static_cast<uint64_t>(m.row), 0};
        out.message(in);
      },
      [&](const Ros2DbProblem& p) {
        out.problem(path + ": " + (p.row ? "at row " + std::to_string(p.row) + ": " : std::string()) + p.what);
      });
  return out.status();
}

Status import_carmen(const std::string& path, Importer& out) {
  auto log = CarmenReader::open(path);
  if (!log) return log.error();
  log->read(
      [&](const CarmenMessage& m) {
        const std::string_view source = m.channel.ends_with("_POSE") ? m.channel.substr(0, m.channel.size() - 5)
                                                                      : m.channel;
        const std::string_view source_type = m.channel == "TF_STATIC" ? "PARAM" : source;
        if (out.describe(m.log_utime, m.channel, source_type, lcmtypes::SeqOrigin::kCounted) &&
            out.write(m.log_utime, m.channel, m.lcm)) {
          ++out.topic(m.channel, source_type, m.type).messages;
        }
      },
      [&](size_t line, const std::string& what) { out.problem(path + ":" + std::to_string(line) + ": " + what); });
  out.summary.skipped = log->skipped();
  return out.status();
}

/// A ULog value (an information field, a parameter) as a number (NaN when it is not one number) and as text: a
/// string as it came (to its first NUL), a number in decimal, anything else in hex.
void ulog_value(std::string_view type, std::span<const uint8_t> v, double* number, std::string* text) {
  *number = std::numeric_limits<double>::quiet_NaN();
  text->clear();
  if (type.starts_with("char[")) {
    const std::string_view s(reinterpret_cast<const char*>(v.data()), v.size());
    *text = std::string(s.substr(0, s.find('\0')));
    return;
  }
  const std::map<std::string, std::string, std::less<>> one{{"v", "v:" + std::string(type) + " x;"}};
  if (auto l = resolve_ulog_format(one, "v");
      l && l->fields.size() == 1 && l->fields[0].count == 0 && l->size == v.size()) {
    *number = l->number(v, "x");
    char buf[40];
    const UlogType t = l->fields[0].type;
    if (t == UlogType::kFloat) {
      std::snprintf(buf, sizeof buf, "%.9g", *number);
    } else if (t == UlogType::kDouble) {
      std::snprintf(buf, sizeof buf, "%.17g", *number);
    } else if (t == UlogType::kUint64) {
      uint64_t u = 0;
      for (size_t i = 8; i-- > 0;) u = (u << 8) | v[i];
      std::snprintf(buf, sizeof buf, "%llu", static_cast<unsigned long long>(u));
    } else if (t == UlogType::kInt64) {
      uint64_t u = 0;
      for (size_t i = 8; i-- > 0;) u = (u << 8) | v[i];
      std::snprintf(buf, sizeof buf, "%lld", static_cast<long long>(static_cast<int64_t>(u)));
    } else {
      std::snprintf(buf, sizeof buf, "%.0f", *number);
    }
    *text = buf;
    return;
  }
  static constexpr char kHex[] = "0123456789abcdef";
  for (const uint8_t b : v) *text += std::string{kHex[b >> 4], kHex[b & 15]};
}

/// Channels of a ULog's records besides its topics.
constexpr char kUlogLog[] = "ULOG_LOG";
constexpr char kUlogParams[] = "ULOG_PARAMS";
constexpr char kUlogInfo[] = "ULOG_INFO";
constexpr char kUlogDropouts[] = "ULOG_DROPOUTS";

Status import_ulog(const std::string& path, Importer& out) {
  auto log = UlogReader::open(path);
  if (!log) return log.error();
  // First pass: which instances of each topic carry data. A topic logged in one instance, 0, is a channel of its
  // name; one logged in several, or in another, a channel per instance, "name/multi_id" (as pyulog names them).
  std::map<std::string, std::set<uint8_t>, std::less<>> instances;
  {
    UlogReader::Callbacks scan;
    std::vector<bool> counted(65536, false);  // by msg_id: its current subscription's instance is in instances
    scan.subscription = [&](const UlogSubscription& s) { counted[s.msg_id] = false; };
    scan.data = [&](const UlogData& d) {
      if (counted[d.subscription->msg_id]) return;
      counted[d.subscription->msg_id] = true;
      instances[d.subscription->name].insert(d.subscription->multi_id);
    };
    if (Status s = log->read(scan); !s) return Error(path + ": " + s.message());
  }
  auto channel_of = [&](const UlogSubscription& s) {
    const auto it = instances.find(s.name);
    const bool plain = it != instances.end() && it->second.size() == 1 && *it->second.begin() == 0 && s.multi_id == 0;
    return plain ? s.name : s.name + "/" + std::to_string(s.multi_id);
  };
  struct Channel {
    std::string name;
    int64_t count = 0;
    bool described = false;  // its channel_source_t written
    bool schema_written = false;
    size_t topic = SIZE_MAX;  // its entry in out.summary.topics, once it has one
    // Of its current subscription: its topic's mapping (none when the format does not resolve or has no mapping),
    // and the bytes that start each of its messages as foreign_message_t (all but its size and data).
    std::optional<UlogConverter> converter;
    std::vector<uint8_t> foreign_head;
  };
  std::map<std::string, Channel, std::less<>> channels;
  std::map<std::string, Channel, std::less<>> records;  // ULOG_LOG, ULOG_PARAMS, ...: counted apart from the topics
  // The channel of each msg_id's current subscription (found once per subscription, not per message); null for a
  // name an LCM log cannot hold.
  std::vector<Channel*> by_id(65536, nullptr);
  std::set<std::string> long_names;
  auto where = [&](uint64_t offset) { return path + ": at byte " + std::to_string(offset); };
  auto topic = [&](Channel& c, const UlogSubscription& s, const char* type) -> TopicCount& {
    if (c.topic == SIZE_MAX)
      c.topic = static_cast<size_t>(&out.topic(c.name, s.name, type) - out.summary.topics.data());
    return out.summary.topics[c.topic];
  };
  foreign_message_t f;  // the start of each topic's foreign messages (foreign_head)
  f.encoding = "ulog";
  std::vector<uint8_t> encoded;  // each message encoded, its memory kept from one to the next

  UlogReader::Callbacks cb;
  cb.problem = [&](uint64_t offset, const std::string& what) { out.problem(where(offset) + ": " + what); };
  cb.subscription = [&](const UlogSubscription& s) {
    const std::string name = channel_of(s);
    if (name.size() > 255) {
      by_id[s.msg_id] = nullptr;
      return;
    }
    Channel& c = channels[name];
    c.name = name;
    c.converter.reset();
    if (s.layout && driftlab_type_for_ulog(s.name) != nullptr) c.converter.emplace(s.layout);
    f.type = s.name;
    f.data.clear();
    f.size = 0;
    lcmtypes::encode_into(f, &c.foreign_head);
    c.foreign_head.resize(c.foreign_head.size() - 4);  // its size, 0, written per message
    by_id[s.msg_id] = &c;
  };
  cb.data = [&](const UlogData& d) {
    const UlogSubscription& s = *d.subscription;
    Channel* cp = by_id[s.msg_id];
    if (!cp) {
      // A channel name an LCM log cannot hold (a hostile file's; PX4's topic names are short).
      if (long_names.insert(s.name).second) {
        out.problem(where(d.offset) + ": topic " + s.name.substr(0, 40) +
                    "... has a name over 255 bytes, which an LCM log cannot hold; its messages are left out");
      }
      return;
    }
    Channel& c = *cp;
    const int64_t t = ulog_utime(d.timestamp);
    if (!s.layout) {
      // Reported once, with its subscription; counted here.
      ++topic(c, s, "driftlab.foreign_message_t").malformed;
      return;
    }
    // ULog has no sequence number: seq is the count on the channel (CHANNEL_SOURCES says so).
    if (!c.described && !out.describe(t, c.name, s.name, lcmtypes::SeqOrigin::kCounted)) return;
    c.described = true;
    if (const char* type = c.converter ? c.converter->convert(d.payload, d.timestamp, c.count, &encoded) : nullptr) {
      TopicCount& tc = topic(c, s, type);
      if (out.write(t, c.name, encoded)) {
        ++tc.messages;
        ++c.count;
      }
      if (const auto tie = c.converter->gnss_utc(d.payload, d.timestamp)) {
        Channel& u = records[kUlogUtcChannel];
        timesync_status_t ts{};
        ts.header.seq = u.count;
        ts.header.utime = tie->boot_us;
        ts.header.frame_id = c.name;
        ts.remote_utime = tie->utc_us;
        ts.observed_offset_s = ts.estimated_offset_s = static_cast<double>(tie->utc_us - tie->boot_us) * 1e-6;
        ts.round_trip_s = 0;  // a receiver's time: no exchange
        if (out.write(t, kUlogUtcChannel, encode(ts))) {
          ++out.topic(kUlogUtcChannel, "ULog GNSS UTC", "driftlab.timesync_status_t").messages;
          ++u.count;
        }
      }
      return;
    }
    TopicCount& tc = topic(c, s, "driftlab.foreign_message_t");
    if (!c.schema_written) {
      foreign_schema_t fs{};
      fs.channel = c.name;
      fs.type = s.name;
      fs.encoding = "ulog";
      fs.definition = s.layout->definition;
      if (!out.write(t, kSchemaChannel, encode(fs))) return;
      c.schema_written = true;
    }
    // foreign_message_t's encoding: its head, its size (big-endian, as LCM writes an int32_t), its data.
    const auto size = static_cast<uint32_t>(d.payload.size());
    const uint8_t size_be[4] = {static_cast<uint8_t>(size >> 24), static_cast<uint8_t>(size >> 16),
                                static_cast<uint8_t>(size >> 8), static_cast<uint8_t>(size)};
    encoded.assign(c.foreign_head.begin(), c.foreign_head.end());
    encoded.insert(encoded.end(), size_be, size_be + 4);
    encoded.insert(encoded.end(), d.payload.begin(), d.payload.end());
    if (out.write(t, c.name, encoded)) {
      ++tc.messages;
      ++c.count;
    }
  };
  cb.logged = [&](const UlogLogged& l) {
    Channel& c = records[kUlogLog];
    log_text_t m{};
    m.header.seq = c.count;
    m.header.utime = ulog_utime(l.timestamp);
    m.level = l.level >= '0' && l.level <= '9' ? l.level - '0' : l.level;
    m.tag = l.tagged ? l.tag : -1;
    m.text = std::string(l.text.substr(0, l.text.find('\0')));
    if (out.write(m.header.utime, kUlogLog, encode(m))) {
      ++out.topic(kUlogLog, "ULog logged string", "driftlab.log_text_t").messages;
      ++c.count;
    }
  };
  cb.value = [&](const UlogValue& v) {
    const char* channel = v.kind == 'I' || v.kind == 'M' ? kUlogInfo : kUlogParams;
    Channel& c = records[channel];
    parameter_t m{};
    m.header.seq = c.count;
    m.header.utime = ulog_utime(v.time);
    m.name = std::string(v.key.substr(0, v.key.find('\0')));
    m.type = std::string(v.type.substr(0, v.type.find('\0')));
    ulog_value(v.type, v.value, &m.value, &m.text);
    m.default_types = v.default_types;
    if (out.write(m.header.utime, channel, encode(m))) {
      ++out.topic(channel, v.kind == 'I' || v.kind == 'M' ? "ULog information" : "ULog parameter",
                  "driftlab.parameter_t")
            .messages;
      ++c.count;
    }
  };
  cb.dropout = [&](const UlogDropout& d) {
    Channel& c = records[kUlogDropouts];
    dropout_t m{};
    m.header.seq = c.count;
    m.header.utime = ulog_utime(d.timestamp);
    m.duration_us = int64_t{d.duration_ms} * 1000;
    if (out.write(m.header.utime, kUlogDropouts, encode(m))) {
      ++out.topic(kUlogDropouts, "ULog dropout", "driftlab.dropout_t").messages;
      ++c.count;
    }
  };
  if (Status s = log->read(cb); !s) return Error(path + ": " + s.message());
  for (const auto& [type, n] : log->unknown_types()) {
    out.summary.skipped.emplace_back(std::string("ULog record type '") + type + "'", n);
  }
  return out.status();
}

/// "b_10.mcap" after "b_2.mcap": runs of digits compare as numbers.
bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  auto digit = [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; };
  while (i < a.size() && j < b.size()) {
    if (digit(a[i]) && digit(b[j])) {
      size_t ie = i, je = j;
      while (ie < a.size() && digit(a[ie])) ++ie;
      while (je < b.size() && digit(b[je])) ++je;
      std::string_view da = std::string_view(a).substr(i, ie - i), db = std::string_view(b).substr(j, je - j);
      da.remove_prefix(std::min(da.find_first_not_of('0'), da.size()));
      db.remove_prefix(std::min(db.find_first_not_of('0'), db.size()));
      if (da.size() != db.size()) return da.size() < db.size();
      if (da != db) return da < db;
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

bool is_dir(const std::string& p) {
  std::error_code ec;
  return std::filesystem::is_directory(p, ec);
}
bool exists(const std::string& p) {
  std::error_code ec;
  return std::filesystem::exists(p, ec);
}

/// A bag folder's storage files: from metadata.yaml, else every .mcap and .db3 (compressed or not) in it.
std::vector<std::string> folder_files(const std::string& folder, const Ros2BagMetadata* metadata) {
  std::vector<std::string> files;
  if (metadata) {
    for (const auto& f : metadata->relative_file_paths) {
      // Older rosbag2 versions list the path with the folder's own name in front.
      std::string p = folder + "/" + f;
      const std::string base = folder + "/" + std::filesystem::path(f).filename().string();
      if (!exists(p) && exists(base)) p = base;
      files.push_back(p);
    }
    return files;
  }
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(folder, ec)) {
    const std::string name = e.path().filename().string();
    for (const char* ext : {".mcap", ".db3", ".mcap.zstd", ".db3.zstd"}) {
      if (name.ends_with(ext)) {
        files.push_back(e.path().string());
        break;
      }
    }
  }
  std::sort(files.begin(), files.end(), natural_less);
  return files;
}

/// The MCAP header's profile ("ros2"), from the first bytes.
std::string mcap_profile(std::string_view h) {
  if (h.size() < 8 + 9 + 4 || static_cast<uint8_t>(h[8]) != 0x01) return {};
  uint32_t n;
  std::memcpy(&n, h.data() + 17, 4);
  if (n > h.size() - 21) return {};
  return std::string(h.substr(21, n));
}

Detected detect_head(std::string_view h, bool inner = false);

}  // namespace

namespace {

Detected detect_head(std::string_view h, bool inner) {
  const auto* u = reinterpret_cast<const uint8_t*>(h.data());
  if (Ros1BagReader::looks_like({u, h.size()})) return {Format::kRos1Bag, "ROS 1 bag", {}};
  if (McapReader::looks_like({u, h.size()})) {
    const std::string profile = mcap_profile(h);
    return {Format::kMcap, profile == "ros2" ? "ROS 2 bag (MCAP)" : profile == "ros1" ? "ROS 1 MCAP" : "MCAP file", {}};
  }
  if (SqliteBagReader::looks_like({u, h.size()})) return {Format::kRos2Sqlite, "ROS 2 bag (sqlite3)", {}};
  if (UlogReader::looks_like({u, h.size()})) return {Format::kUlog, "PX4 ULog", {}};
  if (h.size() >= 4 && static_cast<unsigned char>(h[0]) == 0xED && static_cast<unsigned char>(h[1]) == 0xA2 &&
      static_cast<unsigned char>(h[2]) == 0xDA && static_cast<unsigned char>(h[3]) == 0xEA) {
    return {Format::kLcmLog, "LCM log", {}};
  }
  if (!inner && looks_like_zstd({u, h.size()})) {
    // rosbag2's file compression: look at what the frame holds (its first block is enough).
    std::vector<uint8_t> head;
    (void)decompress(Codec::kZstd, {u, h.size()}, 0, head);
    const std::string text(head.begin(), head.begin() + static_cast<ptrdiff_t>(std::min<size_t>(head.size(), 4096)));
    Detected d = detect_head(text, true);
    if (d.format == Format::kMcap || d.format == Format::kRos2Sqlite || d.format == Format::kRos1Bag) {
      return {Format::kZstd, d.name + ", compressed whole with zstd", {}};
    }
    return {Format::kUnknown, "", "zstd data holding " + (text.empty() ? std::string("nothing readable") : describe(text))};
  }
  std::string text(h);
  if (!inner && h.size() >= 2 && static_cast<unsigned char>(h[0]) == 0x1f && static_cast<unsigned char>(h[1]) == 0x8b) {
    // gzip: look at what it holds (a partial inflate of the first block is enough).
    std::vector<uint8_t> inflated;
    (void)decompress(Codec::kGzip, {u, h.size()}, 0, inflated);
    text.assign(inflated.begin(), inflated.begin() + static_cast<ptrdiff_t>(std::min<size_t>(inflated.size(), 4096)));
    if (text.empty()) return {Format::kUnknown, "", "gzip data that does not inflate"};
  }
  if (CarmenReader::looks_like(text)) return {Format::kCarmen, "CARMEN log", {}};
  if (looks_like_mrpt(text)) return {Format::kMrptRawlog, "MRPT rawlog", {}};
  return {Format::kUnknown, "", (text.size() == h.size() ? "" : "gzip holding ") + describe(text)};
}

/// files without the second and later spellings of one file (by device and inode, so "./a.mcap", links and
/// "a.mcap" are one; by path when it cannot be looked at): a file listed twice in metadata.yaml, or given twice on
/// the command line, is read once (it was imported twice, every message doubled). Each left out goes in *twice as
/// "LATER (the same file as FIRST)".
std::vector<std::string> once_each(const std::vector<std::string>& files, std::vector<std::string>* twice) {
  std::vector<std::string> out;
  std::map<std::string, std::string> first_of;  // by device:inode or path, the first spelling
  for (const auto& f : files) {
    struct stat st {};
    std::string id;
    if (::stat(f.c_str(), &st) == 0) {
      id = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
    } else {
      id = "path " + std::filesystem::absolute(f).lexically_normal().string();
    }
    auto [it, fresh] = first_of.emplace(id, f);
    if (fresh) {
      out.push_back(f);
    } else if (twice) {
      twice->push_back(f + (f == it->second ? std::string() : " (the same file as " + it->second + ")"));
    }
  }
  return out;
}

constexpr char kKnownFormats[] =
    "ROS 1 bag, ROS 2 bag (MCAP, sqlite3, or its folder), MCAP file, CARMEN log, PX4 ULog, MRPT rawlog";

/// Imports one file (not a folder) into out.
Status import_file(const std::string& path, const std::string& out_path, Importer& out) {
  const Detected d = detect_format(path);
  out.file = path;
  switch (d.format) {
    case Format::kRos1Bag: return import_ros1(path, out);
    case Format::kMcap: return import_mcap(path, out);
    case Format::kRos2Sqlite: return import_sqlite(path, out);
    case Format::kCarmen: return import_carmen(path, out);
    case Format::kUlog: return import_ulog(path, out);
    case Format::kZstd: {
      // Decompressed beside the output (a bag may not fit in memory, nor in a RAM-backed /tmp), then read.
      const std::string plain = out_path + ".unzstd";
      Status s = decompress_zstd_file(path, plain);
      if (!s && !exists(plain)) return s;
      if (!s) out.problem(s.message());
      const Detected inner = detect_format(plain);
      // Problems name the user's file, with offsets into what it decompresses to (they named the temporary file).
      out.temporary = plain;
      out.temporary_named = path + " (decompressed)";
      Status r = inner.format == Format::kMcap        ? import_mcap(plain, out)
                 : inner.format == Format::kRos2Sqlite ? import_sqlite(plain, out)
                 : inner.format == Format::kRos1Bag    ? import_ros1(plain, out)
                                                       : Status(Error(path + ": decompressed, not a bag"));
      std::remove(plain.c_str());
      if (!r) r = Error(out.named(r.message()));
      out.temporary.clear();
      return r;
    }
    case Format::kLcmLog: return Error(path + ": already an LCM log; nothing to import");
    case Format::kMrptRawlog: return Error(path + ": an MRPT rawlog: use `driftlab import rawlog`");
    case Format::kRos2Folder: return Error(path + ": a bag folder among files: give the folder alone");
    case Format::kUnknown: break;
  }
  return Error(path + ": not a format driftlab imports (" + kKnownFormats + "): " + d.description);
}

}  // namespace

Detected detect_format(const std::string& path) {
  if (is_dir(path)) {
    if (exists(path + "/metadata.yaml") || !folder_files(path, nullptr).empty()) {
      return {Format::kRos2Folder, "ROS 2 bag", {}};
    }
    return {Format::kUnknown, "", "a folder without metadata.yaml or bag files"};
  }
  return detect_head(head_of(path, 4096));
}

bool is_importable(Format f) {
  return f != Format::kUnknown && f != Format::kLcmLog && f != Format::kMrptRawlog;
}

std::vector<std::string> recording_files(const std::vector<std::string>& inputs) {
  if (inputs.size() == 1 && is_dir(inputs[0])) {
    auto metadata = read_ros2_metadata(inputs[0]);
    return once_each(folder_files(inputs[0], metadata ? &*metadata : nullptr), nullptr);
  }
  std::vector<std::string> files = once_each(inputs, nullptr);
  std::sort(files.begin(), files.end(), natural_less);
  return files;
}

namespace {
/// A partial output removed unless it was renamed into place (path cleared).
struct RemovedUnlessKept {
  std::string path;
  explicit RemovedUnlessKept(std::string p) : path(std::move(p)) {}
  RemovedUnlessKept(const RemovedUnlessKept&) = delete;
  RemovedUnlessKept& operator=(const RemovedUnlessKept&) = delete;
  ~RemovedUnlessKept() {
    if (!path.empty()) std::remove(path.c_str());
  }
};
}  // namespace

Result<ImportSummary> import_log(const std::string& in, const std::string& out_path,
                                 const std::function<void(const std::string&)>& on_problem) {
  return import_log(std::vector<std::string>{in}, out_path, on_problem);
}

Result<ImportSummary> import_log(const std::vector<std::string>& inputs, const std::string& out_path,
                                 const std::function<void(const std::string&)>& on_problem) {
  if (inputs.empty()) return Error("nothing to import");
  // Everything that can be refused is refused before the output is created.
  const bool folder = inputs.size() == 1 && is_dir(inputs[0]);
  std::optional<Ros2BagMetadata> metadata;
  std::vector<std::string> early_problems;
  std::vector<std::string> files;
  std::string format;
  if (folder) {
    const Detected d = detect_format(inputs[0]);
    if (d.format == Format::kUnknown) return Error(inputs[0] + ": not a ROS 2 bag: " + d.description);
    if (auto m = read_ros2_metadata(inputs[0])) {
      metadata = std::move(*m);
    } else {
      early_problems.push_back(m.error().message + "; reading the bag files in the folder in name order");
    }
    std::vector<std::string> twice;
    files = once_each(folder_files(inputs[0], metadata ? &*metadata : nullptr), &twice);
    for (const auto& f : twice) early_problems.push_back(f + ": listed twice in metadata.yaml; read once");
    if (files.empty()) return Error(inputs[0] + ": metadata.yaml lists no files");
    const std::string storage = metadata ? metadata->storage_identifier : "";
    format = "ROS 2 bag (" + (storage.empty() ? std::string("folder") : storage) + ")";
  } else {
    std::vector<std::string> twice;
    (void)once_each(inputs, &twice);
    for (const auto& f : twice) early_problems.push_back(f + ": given twice; read once");
    files = recording_files(inputs);
    for (const auto& f : files) {
      if (is_dir(f)) return Error(f + ": a bag folder among files: give the folder alone");
      const Detected d = detect_format(f);
      if (!is_importable(d.format) || d.format == Format::kRos2Folder) {
        if (d.format == Format::kLcmLog) return Error(f + ": already an LCM log; nothing to import");
        if (d.format == Format::kMrptRawlog) return Error(f + ": an MRPT rawlog: use `driftlab import rawlog`");
        return Error(f + ": not a format driftlab imports (" + kKnownFormats + "): " + d.description);
      }
      if (format.empty()) format = d.name;
    }
  }
  if (files.size() > 1) format += ", " + std::to_string(files.size()) + " files";

  // Written under a name of its own beside the output, created exclusively, and renamed into place when whole: two
  // processes converting one recording into one cache at once each write their own file (they shared
  // OUT.partial, and one renamed the other's half-written log into place).
  auto own = create_partial_of_its_own(out_path);
  if (!own) return own.error();
  ::close(own->fd);
  RemovedUnlessKept partial{own->path};
  // The kernel's copy into the file on a thread of its own, overlapping the conversion.
  auto writer = LogWriter::create(partial.path, {.background = true});
  if (!writer) return writer.error();
  Importer out(std::move(*writer), on_problem);
  out.summary.format = format;
  for (const auto& p : early_problems) out.problem(p);
  for (const auto& f : files) {
    if (folder && !exists(f)) {
      out.problem(f + ": listed in metadata.yaml, missing");
      continue;
    }
    Status s = import_file(f, partial.path, out);  // its temporary files named after the partial file: its own too
    if (!s && out.status()) {
      // A file that cannot be read at all: fatal alone, a problem among several (the others still convert).
      if (files.size() == 1) {
        out.writer().discard();
        return s.error();
      }
      out.problem(s.message());
    }
    if (!out.status()) {
      out.writer().discard();
      return out.status().error();
    }
  }
  // Every message accounted for: what metadata.yaml counts per topic against what the files held.
  if (metadata) {
    for (const auto& t : metadata->topics) {
      int64_t found = 0;
      for (const auto& c : out.summary.topics)
        if (c.channel == t.name) found = c.messages + c.malformed;
      if (found < t.message_count) {
        out.problem(inputs[0] + "/metadata.yaml: counts " + std::to_string(t.message_count) + " messages on " +
                    t.name + "; the files hold " + std::to_string(found));
      }
    }
  }
  if (Status c = out.writer().close(); !c) return c.error();
  if (std::rename(partial.path.c_str(), out_path.c_str()) != 0) {
    return Error(out_path + ": cannot rename " + partial.path + " into place: " + std::strerror(errno),
                 ErrorCode::kCannotWrite);
  }
  partial.path.clear();  // in place: nothing to remove
  return out.summary;
}

std::string import_text(const ImportSummary& s, const std::string& from, const std::string& to) {
  std::string out;
  appendf(out, "%s (%s) -> %s: %s messages\n", from.c_str(), s.format.c_str(), to.c_str(),
          thousands(s.messages).c_str());
  size_t width = 8;
  for (const auto& t : s.topics) width = std::max(width, t.channel.size());
  for (const auto& t : s.topics) {
    appendf(out, "  %-*s %-34s -> %-28s %10s", static_cast<int>(width), t.channel.c_str(), t.source_type.c_str(),
            t.driftlab_type.c_str(), thousands(t.messages).c_str());
    if (t.malformed) appendf(out, "  (%s malformed, left out)", thousands(t.malformed).c_str());
    if (t.driftlab_type == "driftlab.foreign_message_t") out += "  (no mapping: carried as recorded)";
    if (t.driftlab_type == "driftlab.stamped_foreign_message_t")
      out += "  (no mapping: carried as recorded, its header read)";
    out += "\n";
  }
  for (const auto& [name, n] : s.skipped) {
    appendf(out, "  skipped %-20s %s lines (no driftlab type)\n", name.c_str(), thousands(n).c_str());
  }
  return out;
}

}  // namespace driftlab::formats
