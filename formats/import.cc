#include "formats/import.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <map>

#include "core/log_writer.h"
#include "lcmtypes/encode.h"
#include "driftlab/foreign_message_t.hpp"
#include "driftlab/foreign_schema_t.hpp"
#include "formats/carmen.h"
#include "formats/internal/decompress.h"
#include "formats/ros1_bag.h"
#include "formats/ros_messages.h"

namespace driftlab::formats {
namespace {

using lcmtypes::encode;

constexpr char kSchemaChannel[] = "FOREIGN_SCHEMAS";

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

/// MRPT's serialization starts every object with 0x80 + the length of its class name, then the name ("CSensoryFrame").
bool looks_like_mrpt(std::string_view h) {
  if (h.size() < 2) return false;
  const auto first = static_cast<unsigned char>(h[0]);
  const size_t len = first & 0x7f;
  if (!(first & 0x80) || len < 2 || len > 60 || h.size() < 1 + len || h[1] != 'C') return false;
  return std::all_of(h.begin() + 1, h.begin() + 1 + static_cast<ptrdiff_t>(len),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
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

struct Output {
  LogWriter writer;
  ImportSummary summary;
  std::map<std::string, size_t, std::less<>> topic_index;

  TopicCount& topic(std::string_view channel, std::string_view source_type, const char* driftlab_type) {
    auto it = topic_index.find(channel);
    if (it == topic_index.end()) {
      it = topic_index.emplace(std::string(channel), summary.topics.size()).first;
      summary.topics.push_back({std::string(channel), std::string(source_type), driftlab_type, 0, 0});
    }
    return summary.topics[it->second];
  }
  Status write(int64_t utime, std::string_view channel, std::span<const uint8_t> bytes) {
    if (Status s = writer.write(utime, channel, bytes); !s) return s;
    ++summary.messages;
    return {};
  }
};

Status import_ros1(const std::string& path, Output& out, const std::function<void(const std::string&)>& problem) {
  auto bag = Ros1BagReader::open(path);
  if (!bag) return bag.error();
  std::map<std::string, int64_t, std::less<>> next_seq;  // for messages that carry no sequence number
  Status status;
  std::string error;
  bag->read(
      [&](const BagMessage& m) {
        if (!status) return;
        const RosConnection& c = *m.connection;
        const int64_t arrival = m.record_time_ns / 1000;
        const char* mapped = driftlab_type_for(c.type);
        TopicCount& t = out.topic(c.topic, c.type, mapped ? mapped : "driftlab.foreign_message_t");
        if (!mapped) {
          if (t.messages == 0) {
            foreign_schema_t s;
            s.channel = c.topic;
            s.type = c.type;
            s.encoding = "ros1";
            s.definition = c.definition;
            status = out.write(arrival, kSchemaChannel, encode(s));
          }
          foreign_message_t f;
          f.type = c.type;
          f.encoding = "ros1";
          f.data.assign(m.data.begin(), m.data.end());
          f.size = static_cast<int32_t>(f.data.size());
          if (status) status = out.write(arrival, c.topic, encode(f));
          ++t.messages;
          return;
        }
        int64_t& seq = next_seq[c.topic];
        auto converted = convert_ros_message(c.type, Serialization::kRos1, m.data, arrival, seq, &error);
        if (!converted) {
          ++t.malformed;
          ++out.summary.problems;
          problem(path + ": " + c.topic + " at byte " + std::to_string(m.offset) + ": " + error);
          return;
        }
        if (!converted->has_seq) ++seq;  // header.seq: the source's, else the count on this topic
        status = out.write(arrival, c.topic, converted->lcm);
        ++t.messages;
      },
      [&](const BagProblem& p) {
        ++out.summary.problems;
        problem(path + ": at byte " + std::to_string(p.offset) + ": " + p.what);
      });
  return status;
}

Status import_carmen(const std::string& path, Output& out, const std::function<void(const std::string&)>& problem) {
  auto log = CarmenReader::open(path);
  if (!log) return log.error();
  Status status;
  log->read(
      [&](const CarmenMessage& m) {
        if (!status) return;
        const std::string_view source = m.channel.ends_with("_POSE") ? m.channel.substr(0, m.channel.size() - 5)
                                                                      : m.channel;
        ++out.topic(m.channel, m.channel == "TF_STATIC" ? "PARAM" : source, m.type).messages;
        status = out.write(m.log_utime, m.channel, m.lcm);
      },
      [&](size_t line, const std::string& what) {
        ++out.summary.problems;
        problem(path + ":" + std::to_string(line) + ": " + what);
      });
  out.summary.skipped = log->skipped();
  return status;
}

}  // namespace

Detected detect_format(const std::string& path) {
  const std::string h = head_of(path, 4096);
  if (Ros1BagReader::looks_like({reinterpret_cast<const uint8_t*>(h.data()), h.size()})) {
    return {Format::kRos1Bag, "ROS 1 bag", {}};
  }
  if (h.size() >= 4 && static_cast<unsigned char>(h[0]) == 0xED && static_cast<unsigned char>(h[1]) == 0xA2 &&
      static_cast<unsigned char>(h[2]) == 0xDA && static_cast<unsigned char>(h[3]) == 0xEA) {
    return {Format::kLcmLog, "LCM log", {}};
  }
  std::string text = h;
  if (h.size() >= 2 && static_cast<unsigned char>(h[0]) == 0x1f && static_cast<unsigned char>(h[1]) == 0x8b) {
    // gzip: look at what it holds (a partial inflate of the first block is enough).
    std::vector<uint8_t> inflated;
    (void)internal::decompress(internal::Codec::kGzip, {reinterpret_cast<const uint8_t*>(h.data()), h.size()}, 0,
                               inflated);
    text.assign(inflated.begin(), inflated.begin() + static_cast<ptrdiff_t>(std::min<size_t>(inflated.size(), 4096)));
    if (text.empty()) return {Format::kUnknown, "", "gzip data that does not inflate"};
  }
  if (CarmenReader::looks_like(text)) return {Format::kCarmen, "CARMEN log", {}};
  if (looks_like_mrpt(text)) return {Format::kMrptRawlog, "MRPT rawlog", {}};
  return {Format::kUnknown, "", (text.size() == h.size() ? "" : "gzip holding ") + describe(text)};
}

Result<ImportSummary> import_log(const std::string& in, const std::string& out_path,
                                 const std::function<void(const std::string&)>& on_problem) {
  const Detected d = detect_format(in);
  if (d.format == Format::kUnknown) {
    return Error(in + ": not a format driftlab imports (ROS 1 bag, CARMEN log, MRPT rawlog): " + d.description);
  }
  if (d.format == Format::kLcmLog) return Error(in + ": already an LCM log; nothing to import");
  if (d.format == Format::kMrptRawlog) return Error(in + ": an MRPT rawlog: use `driftlab import rawlog`");
  auto writer = LogWriter::create(out_path, {.atomic = true});
  if (!writer) return writer.error();
  Output out{std::move(*writer), {}, {}};
  out.summary.format = d.name;
  Status s = d.format == Format::kRos1Bag ? import_ros1(in, out, on_problem) : import_carmen(in, out, on_problem);
  if (!s) {
    out.writer.discard();
    return Error(s.message());
  }
  if (Status c = out.writer.close(); !c) return Error(c.message());
  return out.summary;
}

}  // namespace driftlab::formats
