#include "formats/internal/importer.h"

#include "driftlab/channel_source_t.hpp"
#include "driftlab/foreign_message_t.hpp"
#include "driftlab/foreign_schema_t.hpp"
#include "driftlab/stamped_foreign_message_t.hpp"
#include "formats/carmen.h"
#include "formats/mcap.h"
#include "formats/ros1_bag.h"
#include "formats/ros2_bag.h"
#include "formats/ros_messages.h"
#include "lcmtypes/encode.h"

namespace driftlab::formats::internal {

using lcmtypes::encode;

std::string lcm_text(std::string_view v) { return std::string(v.substr(0, v.find('\0'))); }

bool Importer::describe(int64_t utime, std::string_view channel, std::string_view source_type,
                        lcmtypes::SeqOrigin origin) {
  if (!sources_.emplace(channel).second) return status_.ok();
  channel_source_t s{};
  s.channel = lcm_text(channel);
  s.source_type = lcm_text(source_type);
  s.seq_origin = static_cast<int8_t>(origin);
  return write(utime, lcmtypes::kChannelSources, encode(s));
}

void Importer::message(const Incoming& m) {
  if (!status_) return;
  // A channel name an LCM log can hold: 1 to 255 bytes, no NUL.
  if (m.topic.empty() || m.topic.size() > 255 || m.topic.find('\0') != std::string_view::npos) {
    if (bad_topics_++ == 0) {
      problem(file + ": " + m.where.text() +
              ": a topic name an LCM log cannot hold (empty, over 255 bytes or "
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
        problem(file + ": " + std::string(m.topic) + " " + m.where.text() + ": the schema of " + std::string(m.type) +
                " does not parse (" + d.error().message + "); its messages are carried unchecked");
      }
    }
  }
  TopicCount& t =
      topic(m.topic, m.type, st.stamped ? "driftlab.stamped_foreign_message_t" : "driftlab.foreign_message_t");
  if (st.definition) {
    if (std::string why = st.definition->check(payload); !why.empty()) {
      ++t.malformed;
      problem(file + ": " + std::string(m.topic) + " " + m.where.text() + ": not a " + std::string(m.type) + ": " +
              why);
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
  if (!describe(m.arrival_us, m.topic, m.source_type.empty() ? m.type : m.source_type, m.seq_origin.value_or(origin))) {
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
        const std::string_view source =
            m.channel.ends_with("_POSE") ? m.channel.substr(0, m.channel.size() - 5) : m.channel;
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

}  // namespace driftlab::formats::internal
