// A PX4 flight log (ULog) into a driftlab log: its topics, parameters, information, log lines and dropouts
// (docs/formats.md).
#include <cstring>
#include <limits>

#include "driftlab/dropout_t.hpp"
#include "driftlab/foreign_message_t.hpp"
#include "driftlab/foreign_schema_t.hpp"
#include "driftlab/log_text_t.hpp"
#include "driftlab/parameter_t.hpp"
#include "driftlab/timesync_status_t.hpp"
#include "formats/internal/importer.h"
#include "formats/ulog.h"
#include "formats/ulog_messages.h"
#include "lcmtypes/encode.h"

namespace driftlab::formats::internal {

using lcmtypes::encode;

namespace {

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

}  // namespace

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
  // A record of the log besides its topics (a log line, a parameter, a dropout): its seq the count on its channel.
  auto record = [&](const char* channel, int64_t utime, auto& m, const char* source_type, const char* type) {
    Channel& c = records[channel];
    m.header.seq = c.count;
    m.header.utime = utime;
    if (out.write(utime, channel, encode(m))) {
      ++out.topic(channel, source_type, type).messages;
      ++c.count;
    }
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
        ts.round_trip_s = 0;                              // a receiver's time: no exchange
        if (out.write(t, kUlogUtcChannel, encode(ts))) {  // logged with the message it came in
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
    log_text_t m{};
    m.level = l.level >= '0' && l.level <= '9' ? l.level - '0' : l.level;
    m.tag = l.tagged ? l.tag : -1;
    m.text = std::string(l.text.substr(0, l.text.find('\0')));
    record(kUlogLog, ulog_utime(l.timestamp), m, "ULog logged string", "driftlab.log_text_t");
  };
  cb.value = [&](const UlogValue& v) {
    const bool info = v.kind == 'I' || v.kind == 'M';
    parameter_t m{};
    m.name = std::string(v.key.substr(0, v.key.find('\0')));
    m.type = std::string(v.type.substr(0, v.type.find('\0')));
    ulog_value(v.type, v.value, &m.value, &m.text);
    m.default_types = v.default_types;
    record(info ? kUlogInfo : kUlogParams, ulog_utime(v.time), m, info ? "ULog information" : "ULog parameter",
           "driftlab.parameter_t");
  };
  cb.dropout = [&](const UlogDropout& d) {
    dropout_t m{};
    m.duration_us = int64_t{d.duration_ms} * 1000;
    record(kUlogDropouts, ulog_utime(d.timestamp), m, "ULog dropout", "driftlab.dropout_t");
  };
  if (Status s = log->read(cb); !s) return Error(path + ": " + s.message());
  for (const auto& [type, n] : log->unknown_types()) {
    out.summary.skipped.emplace_back(std::string("ULog record type '") + type + "'", n);
  }
  return out.status();
}

}  // namespace driftlab::formats::internal
