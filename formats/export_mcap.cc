#include "formats/export_mcap.h"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>

#include "core/log_reader.h"
#include "core/number_text.h"
#include "core/text_file.h"
#include "driftlab/barometer_t.hpp"
#include "driftlab/channel_source_t.hpp"
#include "driftlab/foreign_message_t.hpp"
#include "driftlab/foreign_schema_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/image_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/stamped_foreign_message_t.hpp"
#include "driftlab/tf_t.hpp"
#include "driftlab/velocity_command_t.hpp"
#include "formats/internal/ros2_cdr.h"
#include "formats/ros2_bag.h"
#include "formats/ros2_schema.h"
#include "lcmtypes/schema.h"
#include "lcmtypes/seq_origin.h"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace driftlab::formats {
namespace {

namespace fs = std::filesystem;
using namespace internal;  // NOLINT(google-build-using-namespace): the CDR encoders, one per mapped type

// --- topics, channels and schemas ----------------------------------------------------------------------------------

/// A valid ROS 2 topic name for a channel: the channel itself when it is one, else its characters outside
/// [A-Za-z0-9_/] replaced by '_', a token starting with a digit given a leading '_', empty tokens dropped.
std::string topic_for(const std::string& channel) {
  std::string out;
  bool token_start = true;
  for (size_t i = 0; i < channel.size(); ++i) {
    char c = channel[i];
    if (c == '/') {
      if (!out.empty() && out.back() == '/') continue;
      out += '/';
      token_start = true;
      continue;
    }
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') c = '_';
    if (token_start && std::isdigit(static_cast<unsigned char>(c))) out += '_';
    out += c;
    token_start = false;
  }
  if (out.size() > 1 && out.back() == '/') out.pop_back();
  if (out.empty() || out == "/") out = "/_";
  return out;
}

std::string qos_profile(bool latched) {
  // rosbag2's offered_qos_profiles: keep last 10, reliable, volatile (transient local for latched topics), no
  // deadline, lifespan or liveliness lease (the maximum durations mean "infinite").
  return std::string("- history: 1\n  depth: 10\n  reliability: 1\n  durability: ") + (latched ? "1" : "2") +
         "\n  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n"
         "    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n"
         "    nsec: 4294967295\n  avoid_ros_namespace_conventions: false";
}

class Exporter {
 public:
  Exporter(McapWriter& w, const std::function<void(const std::string&)>& on_problem)
      : w_(w), on_problem_(on_problem) {}

  McapExportSummary summary;

  Status event(const Event& e) {
    if (e.channel == "FOREIGN_SCHEMAS") {
      foreign_schema_t s{};
      if (lcmtypes::decode(e.data, s)) foreign_[s.channel] = {s.type, s.encoding, s.definition};
      return {};
    }
    if (e.channel == lcmtypes::kChannelSources) {  // an import's word on a channel: kept in its MCAP channel's metadata
      channel_source_t s{};
      if (lcmtypes::decode(e.data, s)) sources_[s.channel] = std::move(s);
      return {};
    }
    if (e.data.size() < 8) return skip(e.channel);
    int64_t fp = 0;
    for (int i = 0; i < 8; ++i) fp = static_cast<int64_t>((static_cast<uint64_t>(fp) << 8) | e.data[i]);
    const char* type = lcmtypes::type_name(fp);
    if (!type) return skip(e.channel);
    const std::string_view t = type;
    const uint64_t log_ns = static_cast<uint64_t>(std::max<int64_t>(0, e.utime)) * 1000;
    cdr_.reset();
    std::string ros_type, encoding = "cdr", schema_encoding = "ros2msg", schema;
    int64_t seq = -1;
    bool ok = true;
    auto decode = [&](auto& m) {
      ok = lcmtypes::decode(e.data, m);
      if (ok) seq = m.header.seq;
      return ok;
    };
    // Carried as recorded: written back as they came, with their schema.
    auto carried = [&](const auto& f) {
      auto it = foreign_.find(std::string(e.channel));
      const std::string definition = it != foreign_.end() ? it->second.definition : "";
      const std::string schema_kind = f.encoding == "cdr" ? "ros2msg" : f.encoding == "ros1" ? "ros1msg" : "";
      return write(e, f.type, f.encoding, schema_kind, definition, {f.data.data(), f.data.size()}, log_ns, -1, type);
    };
    if (t == "driftlab.foreign_message_t") {
      foreign_message_t f{};
      if (!lcmtypes::decode(e.data, f)) return malformed(e);
      return carried(f);
    }
    if (t == "driftlab.stamped_foreign_message_t") {
      stamped_foreign_message_t f{};
      if (!lcmtypes::decode(e.data, f)) return malformed(e);
      return carried(f);
    }
    if (t == "driftlab.laser_scan_t") {
      laser_scan_t m{};
      if (decode(m)) laser_scan(cdr_, m);
    } else if (t == "driftlab.imu_t") {
      imu_t m{};
      if (decode(m)) imu(cdr_, m);
    } else if (t == "driftlab.odometry_t") {
      odometry_t m{};
      if (decode(m)) odometry(cdr_, m);
    } else if (t == "driftlab.pose_t") {
      pose_t m{};
      if (decode(m)) pose(cdr_, m);
    } else if (t == "driftlab.tf_t") {
      tf_t m{};
      if (decode(m)) tf(cdr_, m);
    } else if (t == "driftlab.velocity_command_t") {
      velocity_command_t m{};
      if (decode(m)) twist(cdr_, m);
    } else if (t == "driftlab.joint_state_t") {
      joint_state_t m{};
      if (decode(m)) joint_state(cdr_, m);
    } else if (t == "driftlab.gnss_t") {
      gnss_t m{};
      if (decode(m)) nav_sat_fix(cdr_, m);
    } else if (t == "driftlab.magnetometer_t") {
      magnetometer_t m{};
      if (decode(m)) magnetic_field(cdr_, m);
    } else if (t == "driftlab.barometer_t") {
      barometer_t m{};
      if (decode(m)) fluid_pressure(cdr_, m);
    } else if (t == "driftlab.point_cloud_t") {
      return point_cloud_direct(e, log_ns, type);
    } else if (t == "driftlab.image_t") {
      image_t m{};
      if (decode(m)) {
        if (compressed(m)) {
          compressed_image(cdr_, m);
          ros_type = "sensor_msgs/msg/CompressedImage";
        } else {
          image(cdr_, m);
          ros_type = "sensor_msgs/msg/Image";
        }
      }
    } else {
      const lcmtypes::StructDef* s = lcmtypes::find_struct(t);
      if (!s || !lcmtypes::well_formed(e.data, fp)) return malformed(e);
      ok = internal::lcm_to_cdr(e.data, *s, cdr_);
      if (auto h = lcmtypes::read_header(e.data, e.utime)) seq = h->seq;
    }
    if (!ok) return malformed(e);
    if (ros_type.empty()) ros_type = ros2_type_for(t);
    return write(e, ros_type, encoding, schema_encoding, "", cdr_.bytes(), log_ns, seq, type);
  }

 private:
  struct Foreign {
    std::string type, encoding, definition;
  };
  struct Channel {
    uint16_t id;
    size_t topic;  // index into summary.topics
    int64_t count = 0;
  };

  Status skip(std::string_view channel) {
    for (auto& [c, n] : summary.skipped) {
      if (c == channel) {
        ++n;
        return {};
      }
    }
    summary.skipped.emplace_back(std::string(channel), 1);
    return {};
  }
  Status malformed(const Event& e) {
    on_problem_(std::string(e.channel) + " at byte " + std::to_string(e.offset) +
                ": a message that does not decode as its type; left out");
    return {};
  }

  /// point_cloud_t as sensor_msgs/PointCloud2 (float32 x, y, z, then intensity and time when every point has
  /// them; is_dense when no x is NaN) straight from the log's bytes into the chunk: one pass over the points turns
  /// LCM's arrays of big-endian floats into CDR's interleaved little-endian points. Decoding the message first
  /// (lcm-gen's byte swaps into five arrays), then encoding it and copying it into the chunk were two thirds of an
  /// export's work on the calling thread.
  Status point_cloud_direct(const Event& e, uint64_t log_ns, const char* driftlab_type) {
    if (!lcmtypes::well_formed(e.data, point_cloud_t::getHash())) return malformed(e);
    // The layout is checked: every length below is inside the message.
    const auto header = lcmtypes::read_header(e.data, e.utime);  // the type has one: the registry says so
    if (!header) return malformed(e);
    const header_t h{header->seq, header->utime, std::string(header->frame_id)};
    const uint8_t* d = e.data.data();
    size_t p = lcmtypes::kHeaderFrameOffset + 4 + header->frame_id.size() + 1;  // past the frame's NUL
    auto be32 = [&] {
      uint32_t v;
      std::memcpy(&v, d + p, 4);
      p += 4;
      return __builtin_bswap32(v);
    };
    const uint32_t height = be32(), width = be32(), npoints = be32();
    const uint8_t* x = d + p;
    const uint8_t* y = x + 4 * size_t{npoints};
    const uint8_t* z = y + 4 * size_t{npoints};
    p += 12 * size_t{npoints};
    const uint32_t nintensities = be32();
    const uint8_t* in = d + p;
    p += 4 * size_t{nintensities};
    const uint32_t ntimes = be32();
    const uint8_t* tt = d + p;
    const bool intensity = nintensities == npoints && npoints > 0;
    const bool time = ntimes == npoints && npoints > 0;
    cdr_.reset();
    cdr_.header(h);
    cdr_.put(height);
    cdr_.put(width);
    const char* names[5] = {"x", "y", "z", nullptr, nullptr};
    size_t fields = 3;
    if (intensity) names[fields++] = "intensity";
    if (time) names[fields++] = "time";
    cdr_.put(static_cast<uint32_t>(fields));
    for (size_t i = 0; i < fields; ++i) {
      cdr_.str(names[i]);
      cdr_.put(static_cast<uint32_t>(4 * i));  // offset
      cdr_.put<uint8_t>(7);                    // FLOAT32
      cdr_.put<uint32_t>(1);                   // count
    }
    const auto point_step = static_cast<uint32_t>(4 * fields);
    cdr_.put<uint8_t>(0);  // is_bigendian
    cdr_.put(point_step);
    cdr_.put(point_step * width);
    const size_t n = npoints;
    cdr_.put(static_cast<uint32_t>(n * point_step));
    const std::vector<uint8_t>& prefix = cdr_.bytes();
    auto fill = [&](uint8_t* out) {
      std::memcpy(out, prefix.data(), prefix.size());
      uint8_t* o = out + prefix.size();
      uint32_t nan = 0;  // a NaN x: not dense
      auto put = [](uint8_t* to, const uint8_t* from) {
        uint32_t v;
        std::memcpy(&v, from, 4);
        v = __builtin_bswap32(v);
        std::memcpy(to, &v, 4);
        return v;
      };
      for (size_t i = 0; i < n; ++i, o += point_step) {
        const uint32_t vx = put(o, x + 4 * i);
        nan |= static_cast<uint32_t>((vx & 0x7fffffffU) > 0x7f800000U);
        put(o + 4, y + 4 * i);
        put(o + 8, z + 4 * i);
        size_t k = 12;
        if (intensity) {
          put(o + k, in + 4 * i);
          k += 4;
        }
        if (time) put(o + k, tt + 4 * i);
      }
      *o = nan ? 0 : 1;  // is_dense
    };
    return write(e, "sensor_msgs/msg/PointCloud2", "cdr", "ros2msg", "", {}, log_ns, h.seq, driftlab_type,
                 prefix.size() + n * point_step + 1, fill);
  }

  Status write(const Event& e, const std::string& ros_type, const std::string& encoding,
               const std::string& schema_encoding, std::string schema, std::span<const uint8_t> payload,
               uint64_t log_ns, int64_t seq, const char* driftlab_type, size_t fill_size = 0,
               const std::function<void(uint8_t*)>& fill = {}) {
    const std::string key = std::string(e.channel) + '\0' + ros_type + '\0' + encoding;
    auto it = channels_.find(key);
    if (it == channels_.end()) {
      if (schema_encoding == "ros2msg" && schema.empty()) schema = ros2_schema(ros_type);
      const std::string skey = ros_type + '\0' + schema_encoding + '\0' + schema;
      auto sit = schemas_.find(skey);
      if (sit == schemas_.end()) {
        sit = schemas_.emplace(skey, schema_encoding.empty() && schema.empty()
                                         ? uint16_t{0}
                                         : w_.add_schema(ros_type, schema_encoding, schema)).first;
      }
      const std::string channel(e.channel);
      const std::string topic = topic_for(channel);
      std::vector<std::pair<std::string, std::string>> metadata = {
          {"offered_qos_profiles", qos_profile(channel.ends_with("tf_static") || channel == "TF_STATIC")}};
      // Read back by driftlab import.
      if (topic != channel) metadata.emplace_back("driftlab_channel", channel);
      if (const auto src = sources_.find(channel); src != sources_.end()) {
        metadata.emplace_back("driftlab_source_type", src->second.source_type);
        metadata.emplace_back("driftlab_seq_origin", std::to_string(src->second.seq_origin));
      }
      const uint16_t id = w_.add_channel(sit->second, topic, encoding, metadata);
      summary.topics.push_back({channel, topic, driftlab_type, ros_type, encoding, 0});
      it = channels_.emplace(key, Channel{id, summary.topics.size() - 1}).first;
    }
    Channel& c = it->second;
    // The MCAP sequence: header.seq where the message has one, else the count on the channel.
    const auto sequence = static_cast<uint32_t>(seq >= 0 ? seq : c.count);
    if (Status s = fill ? w_.write(c.id, sequence, log_ns, log_ns, fill_size, fill)
                        : w_.write(c.id, sequence, log_ns, log_ns, payload);
        !s) {
      return s;
    }
    ++c.count;
    ++summary.topics[c.topic].messages;
    if (summary.messages++ == 0) summary.start_ns = static_cast<int64_t>(log_ns);
    summary.start_ns = std::min(summary.start_ns, static_cast<int64_t>(log_ns));
    summary.end_ns = std::max(summary.end_ns, static_cast<int64_t>(log_ns));
    return {};
  }

  McapWriter& w_;
  const std::function<void(const std::string&)>& on_problem_;
  Cdr cdr_;
  std::map<std::string, Foreign> foreign_;
  std::map<std::string, channel_source_t> sources_;
  std::map<std::string, Channel> channels_;
  std::map<std::string, uint16_t> schemas_;
};

}  // namespace

Result<McapExportSummary> export_mcap(const std::string& log, const std::string& out, const McapExportOptions& options,
                                      const std::function<void(const std::string&)>& on_problem) {
  // Damaged spots of the log travel with the file too, as its driftlab.log_problems metadata.
  McapMetadata problems{"driftlab.log_problems", {}};
  const std::function<void(const std::string&)> note = [&](const std::string& line) {
    if (problems.entries.size() < 1000) problems.entries.emplace_back(std::to_string(problems.entries.size() + 1), line);
    on_problem(line);
  };
  auto reader = LogReader::open(
      log,
      {.channels = options.channels,
       .also = {"FOREIGN_SCHEMAS", std::string(lcmtypes::kChannelSources)},  // how to write the others
       .on_problem = [&](const Problem& p) { note(log + ": at byte " + std::to_string(p.offset) + ": " + p.detail); }});
  if (!reader) return reader.error();
  auto writer = McapWriter::create(out, {.profile = "ros2",
                                         .library = "driftlab",
                                         .compression = options.compression,
                                         .level = options.level,
                                         .chunk_bytes = options.chunk_bytes});
  if (!writer) return writer.error();
  Exporter ex(*writer, note);
  Status status;
  for (Event e; status && reader->next(e);) status = ex.event(e);
  for (const auto& m : options.metadata) {
    if (status) status = writer->add_metadata(m.name, m.entries);
  }
  if (status && !problems.entries.empty()) status = writer->add_metadata(problems.name, problems.entries);
  if (!status) {
    writer->discard();
    return status.error();
  }
  if (Status s = writer->close(); !s) return s.error();
  ex.summary.bytes = writer->bytes();
  return ex.summary;
}

Result<McapExportSummary> export_rosbag2(const std::string& log, const std::string& folder,
                                         const McapExportOptions& options,
                                         const std::function<void(const std::string&)>& on_problem) {
  std::string dir = folder;
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  std::error_code ec;
  if (fs::exists(dir, ec) && !(fs::is_directory(dir, ec) && fs::is_empty(dir, ec))) {
    return Error(dir + ": exists and is not an empty folder (rosbag2 writes a bag into a new folder)");
  }
  const std::string partial = dir + ".partial";
  fs::remove_all(partial, ec);
  if (!fs::create_directories(partial, ec)) {
    return Error(partial + ": cannot create: " + ec.message(), ErrorCode::kCannotWrite);
  }
  const std::string name = fs::path(dir).filename().string() + "_0.mcap";
  auto summary = export_mcap(log, partial + "/" + name, options, on_problem);
  if (!summary) {
    fs::remove_all(partial, ec);
    return summary.error();
  }
  std::vector<Ros2TopicInfo> topics;
  for (const auto& t : summary->topics) {
    // One topic per ROS topic: a channel that went out on two channels (raw and compressed images) counts once.
    auto it = std::find_if(topics.begin(), topics.end(), [&](const Ros2TopicInfo& x) { return x.name == t.topic; });
    if (it != topics.end()) {
      it->message_count += t.messages;
      continue;
    }
    Ros2TopicInfo ti;
    ti.name = t.topic;
    ti.type = t.ros_type;
    ti.serialization_format = t.encoding;
    ti.offered_qos_profiles = qos_profile(t.channel.ends_with("tf_static") || t.channel == "TF_STATIC");
    ti.message_count = t.messages;
    topics.push_back(std::move(ti));
  }
  const Ros2FileInfo file{name, summary->start_ns, summary->end_ns - summary->start_ns, summary->messages};
  if (Status s = write_file_atomically(partial + "/metadata.yaml", ros2_metadata_yaml("mcap", topics, {file})); !s) {
    fs::remove_all(partial, ec);
    return s.error();
  }
  if (fs::exists(dir, ec)) fs::remove(dir, ec);  // the empty folder given
  fs::rename(partial, dir, ec);
  if (ec) {
    fs::remove_all(partial, ec);
    return Error(dir + ": cannot rename " + partial + " into place", ErrorCode::kCannotWrite);
  }
  return summary;
}

std::string export_text(const McapExportSummary& s, const std::string& log, const std::string& out) {
  std::string text;
  appendf(text, "%s -> %s: %s messages, %s\n", log.c_str(), out.c_str(), thousands(s.messages).c_str(),
          human_bytes(static_cast<double>(s.bytes)).c_str());
  size_t width = 8;
  for (const auto& t : s.topics) width = std::max(width, t.topic.size());
  for (const auto& t : s.topics) {
    appendf(text, "  %-*s %-28s -> %-42s %10s%s\n", static_cast<int>(width), t.topic.c_str(), t.driftlab_type.c_str(),
            (t.ros_type + (t.encoding == "cdr" ? "" : " (" + t.encoding + ")")).c_str(), thousands(t.messages).c_str(),
            t.topic == t.channel ? "" : ("  (channel " + t.channel + ")").c_str());
  }
  for (const auto& [c, n] : s.skipped) {
    appendf(text, "  skipped %s: %s messages of a type driftlab does not know\n", c.c_str(), thousands(n).c_str());
  }
  return text;
}

}  // namespace driftlab::formats
