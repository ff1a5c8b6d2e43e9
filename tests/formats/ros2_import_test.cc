// driftlab import of ROS 2 bags and MCAP files end to end, through the command: split recordings, big-endian CDR,
// rosbag2's file and message compression, bad input named in one line with the rest converted, and every command
// reading these files directly through a cached conversion.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/stat.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <filesystem>
#include <map>

#include "driftlab/foreign_message_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/velocity_command_t.hpp"
#include "formats/compression.h"
#include "formats/mcap.h"
#include "formats/ros2_bag.h"
#include "formats/ros_messages.h"
#include "lcmtypes/encode.h"
#include "lcmtypes/validate.h"
#include "tests/formats/import_in_process.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

namespace fs = std::filesystem;
using test::CmdResult;
using test::run_capture;

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";

CmdResult driftlab(const std::string& args) { return run_capture(kDriftlab + " " + args); }
test::Imported import(const std::vector<std::string>& in, const std::string& out) {
  return test::import_in_process(in, out);
}

std::map<std::string, std::vector<test::OwnedEvent>> by_channel(const std::string& log) {
  std::map<std::string, std::vector<test::OwnedEvent>> m;
  for (auto& e : test::read_all(log)) m[e.channel].push_back(std::move(e));
  return m;
}

/// CDR (XCDR1) written by hand, in either byte order, to feed the importer what rosbag2 stores.
class Cdr {
 public:
  explicit Cdr(bool big) : big_(big) { b_ = {0x00, static_cast<uint8_t>(big ? 0x00 : 0x01), 0x00, 0x00}; }
  template <typename T>
  Cdr& put(T v) {
    while ((b_.size() - 4) % sizeof(T)) b_.push_back(0);
    uint8_t raw[sizeof(T)];
    std::memcpy(raw, &v, sizeof(T));
    if (big_) std::reverse(raw, raw + sizeof(T));
    b_.insert(b_.end(), raw, raw + sizeof(T));
    return *this;
  }
  Cdr& str(const std::string& s) {
    put(static_cast<uint32_t>(s.size() + 1));
    b_.insert(b_.end(), s.begin(), s.end());
    b_.push_back(0);
    return *this;
  }
  std::vector<uint8_t> bytes() const { return b_; }

 private:
  bool big_;
  std::vector<uint8_t> b_;
};

/// A sensor_msgs/LaserScan: stamp sec.nanosec, frame "laser", 3 ranges.
std::vector<uint8_t> scan(bool big, int32_t sec, uint32_t nanosec, float first_range) {
  Cdr c(big);
  c.put(sec).put(nanosec).str("laser");
  for (float v : {-1.0F, 1.0F, 1.0F, 0.0F, 0.1F, 0.1F, 30.0F}) c.put(v);
  c.put<uint32_t>(3).put(first_range).put(2.5F).put(3.5F);
  c.put<uint32_t>(0);
  return c.bytes();
}

constexpr char kScanDefinition[] = "# (not needed: a mapped type)\n";

/// An MCAP file of n scans on /scan, stamps from first_sec on, received 10 ms after; zstd chunks of chunk_bytes.
void write_scans(const std::string& path, int first, int n, bool big = false, size_t chunk_bytes = 4 << 20) {
  auto w = formats::McapWriter::create(path, {.chunk_bytes = chunk_bytes});
  ASSERT_TRUE(w.ok());
  const uint16_t s = w->add_schema("sensor_msgs/msg/LaserScan", "ros2msg", kScanDefinition);
  const uint16_t c = w->add_channel(s, "/scan", "cdr");
  for (int i = first; i < first + n; ++i) {
    const uint64_t t = 1'700'000'000'000'000'000ull + static_cast<uint64_t>(i) * 100'000'000ull;
    ASSERT_TRUE(w->write(c, 0, t + 10'000'000, t + 10'000'000,
                         scan(big, static_cast<int32_t>(t / 1'000'000'000), static_cast<uint32_t>(t % 1'000'000'000),
                              static_cast<float>(i)))
                    .ok());
  }
  ASSERT_TRUE(w->close().ok());
}

void write_text(const std::string& path, const std::string& text) { test::write_file(path, {text.begin(), text.end()}); }

// A recording split in two files (named as rosbag2 names its splits, b_2 before b_10) is one recording, given as
// its folder or as its files in any order; every command reads it.
TEST(Ros2Import, SplitRecordingIsOneRecording) {
  test::TempDir dir;
  const std::string bag = dir.file("bag");
  fs::create_directories(bag);
  write_scans(bag + "/b_2.mcap", 0, 5);
  write_scans(bag + "/b_10.mcap", 5, 5);
  formats::Ros2TopicInfo topic{"/scan", "sensor_msgs/msg/LaserScan", "cdr", "", "", 10};
  write_text(bag + "/metadata.yaml",
             formats::ros2_metadata_yaml("mcap", {topic}, {{"b_2.mcap", 0, 0, 5}, {"b_10.mcap", 0, 0, 5}}));

  auto r = import({bag}, dir.file("folder.lcm"));
  ASSERT_EQ(r.said(), "");
  EXPECT_NE(r.text.find("(ROS 2 bag (mcap), 2 files)"), std::string::npos) << r.text;
  r = import({bag + "/b_10.mcap", bag + "/b_2.mcap"}, dir.file("files.lcm"));
  ASSERT_EQ(r.said(), "");
  EXPECT_EQ(test::read_file(dir.file("folder.lcm")), test::read_file(dir.file("files.lcm")));

  const auto log = by_channel(dir.file("folder.lcm"));
  ASSERT_EQ(log.at("/scan").size(), 10u);
  for (int i = 0; i < 10; ++i) {
    laser_scan_t s;
    ASSERT_TRUE(lcmtypes::decode(log.at("/scan")[static_cast<size_t>(i)].data, s));
    EXPECT_EQ(s.ranges[0], static_cast<float>(i));
    EXPECT_EQ(s.header.seq, i);  // no MCAP sequence: the count on the topic, across the files
    EXPECT_EQ(s.header.utime, 1'700'000'000'000'000 + int64_t{i} * 100'000);
    EXPECT_EQ(log.at("/scan")[static_cast<size_t>(i)].utime, s.header.utime + 10'000);
  }
  // The ten scans and what the import says of their channel (CHANNEL_SOURCES).
  EXPECT_EQ(r.summary.messages, 11);
}

// A NUL inside a ROS string (found by the fuzzer): the driftlab message keeps the string up to it, as LCM encodes
// strings, and stays well formed.
TEST(Ros2Import, StringsEndAtTheirFirstNul) {
  std::string frame("base", 4);
  frame += '\0';
  frame += "link";
  Cdr c(false);
  c.put<int32_t>(1).put<uint32_t>(2).str(frame);
  for (int i = 0; i < 6; ++i) c.put(0.5 * i);
  std::string error;
  const auto bytes = c.bytes();
  auto m = formats::convert_ros_message("geometry_msgs/msg/TwistStamped", formats::Serialization::kCdr, bytes, 0, 0,
                                        &error);
  ASSERT_TRUE(m.has_value()) << error;
  EXPECT_FALSE(lcmtypes::layout_problem(m->lcm).has_value());
  velocity_command_t v;
  ASSERT_TRUE(lcmtypes::decode(m->lcm, v));
  EXPECT_EQ(v.header.frame_id, "base");
  EXPECT_EQ(v.angular.z, 2.5);
}

// A bag folder without its metadata.yaml: said in one line, exit 2, and its files still read in name order.
TEST(Ros2Import, MissingMetadataIsNamedAndTheFilesRead) {
  test::TempDir dir;
  const std::string bag = dir.file("bag");
  fs::create_directories(bag);
  write_scans(bag + "/b_0.mcap", 0, 3);
  write_scans(bag + "/b_1.mcap", 3, 3);
  const auto r = import({bag}, dir.file("out.lcm"));
  EXPECT_EQ(r.said(), bag + "/metadata.yaml: cannot be read; reading the bag files in the folder in name order\n");
  EXPECT_EQ(by_channel(dir.file("out.lcm")).at("/scan").size(), 6u);
}

// A metadata.yaml missing a key the import reads, or holding it as the wrong kind of node (yaml-cpp throws on
// subscripting those, which aborted the program), is one line naming the file, the line and the dotted key; exit 2,
// and the bag's files are still read in name order.
TEST(Ros2Import, MissingMetadataKeysAreNamedInOneLine) {
  test::TempDir dir;
  const std::string bag = dir.file("bag");
  fs::create_directories(bag);
  write_scans(bag + "/b_0.mcap", 0, 4);
  formats::Ros2TopicInfo topic{"/scan", "sensor_msgs/msg/LaserScan", "cdr", "", "", 4};
  const std::string good = formats::ros2_metadata_yaml("mcap", {topic}, {{"b_0.mcap", 0, 0, 4}});
  auto without = [&](const std::string& cut, const std::string& put = "") {
    std::string y = good;
    const size_t at = y.find(cut);
    EXPECT_NE(at, std::string::npos) << cut;
    return at == std::string::npos ? y : y.replace(at, cut.size(), put);
  };
  auto entry = [&](const std::string& put) {  // the topic's whole entry replaced
    const size_t from = good.find("    - topic_metadata:"), to = good.find("  compression_format:");
    return good.substr(0, from) + put + good.substr(to);
  };
  const std::string ns = "  starting_time:\n    nanoseconds_since_epoch: 0\n";
  const std::string md = "    - topic_metadata:\n        name: \"/scan\"\n        type: sensor_msgs/msg/LaserScan\n";
  const std::string top = "rosbag2_bagfile_information.";
  const std::string twmc = top + "topics_with_message_count[0]";
  for (const auto& [yaml, key] : std::vector<std::pair<std::string, std::string>>{
           {without(ns), top + "starting_time: missing"},
           {without(ns, "  starting_time:\n    nanoseconds: 0\n"),
            top + "starting_time.nanoseconds_since_epoch: missing"},
           {without(ns, "  starting_time: 5\n"), top + "starting_time: not a map"},
           {without(ns, "  starting_time:\n    nanoseconds_since_epoch: [1, 2]\n"),
            top + "starting_time.nanoseconds_since_epoch: not an integer"},
           {without("  duration:\n    nanoseconds: 0\n"), top + "duration: missing"},
           {without("  message_count: 4\n"), top + "message_count: missing"},
           {entry("    - message_count: 4\n"), twmc + ".topic_metadata: missing"},
           {entry("    - topic_metadata: 7\n      message_count: 4\n"), twmc + ".topic_metadata: not a map"},
           {without(md, "    - topic_metadata:\n        type: sensor_msgs/msg/LaserScan\n"),
            twmc + ".topic_metadata.name: missing"},
           {good.substr(0, good.find("  topics_with_message_count:")) + good.substr(good.find("  compression_format:")),
            top + "topics_with_message_count: missing"},
       }) {
    write_text(bag + "/metadata.yaml", yaml);
    fs::remove(dir.file("out.lcm"));
    const auto r = import({bag}, dir.file("out.lcm"));
    EXPECT_EQ(r.error, "") << key;
    ASSERT_EQ(r.problems.size(), 1u) << key << "\n" << r.said();
    EXPECT_EQ(r.problems[0].rfind(bag + "/metadata.yaml:", 0), 0u) << r.said();
    EXPECT_NE(r.problems[0].find(key + "; reading the bag files in the folder in name order"), std::string::npos)
        << key << "\n"
        << r.said();
    ASSERT_TRUE(fs::exists(dir.file("out.lcm"))) << key << "\n" << r.said();
    EXPECT_EQ(by_channel(dir.file("out.lcm")).at("/scan").size(), 4u) << key;  // nothing intact lost
    // Every command reading the bag through its conversion says the same, and none aborts.
    const CmdResult info = driftlab("info '" + bag + "'");
    EXPECT_NE(info.err.find(key), std::string::npos) << key << "\n" << info.err;
    EXPECT_EQ(info.err.find("terminate"), std::string::npos) << info.err;
  }
  // The keys rosbag2 added later (or that only describe) may be absent.
  write_text(bag + "/metadata.yaml", without("  compression_format: \"\"\n  compression_mode: \"\"\n"));
  EXPECT_EQ(import({bag}, dir.file("out.lcm")).said(), "");
}

// The same scans in big-endian CDR (encapsulation 00 00) give the same driftlab messages.
TEST(Ros2Import, BigEndianCdr) {
  test::TempDir dir;
  write_scans(dir.file("le.mcap"), 0, 4, false);
  write_scans(dir.file("be.mcap"), 0, 4, true);
  ASSERT_EQ(import({dir.file("le.mcap")}, dir.file("le.lcm")).said(), "");
  ASSERT_EQ(import({dir.file("be.mcap")}, dir.file("be.lcm")).said(), "");
  EXPECT_EQ(test::read_file(dir.file("le.lcm")), test::read_file(dir.file("be.lcm")));
}

/// An MCAP file written record by record, to hold what no writer would write.
class RawMcap {
 public:
  RawMcap() {
    b_ = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
    std::vector<uint8_t> h;
    str(h, "ros2");
    str(h, "test");
    record(0x01, h);
  }
  void schema(uint16_t id, const std::string& name, const std::string& text) {
    std::vector<uint8_t> c;
    put(c, id);
    str(c, name);
    str(c, "ros2msg");
    str(c, text);
    record(0x03, c);
  }
  void channel(uint16_t id, uint16_t schema, const std::string& topic) {
    std::vector<uint8_t> c;
    put(c, id);
    put(c, schema);
    str(c, topic);
    str(c, "cdr");
    put<uint32_t>(c, 0);
    record(0x04, c);
  }
  size_t message(uint16_t channel, uint64_t t, const std::vector<uint8_t>& data) {
    std::vector<uint8_t> c;
    put(c, channel);
    put<uint32_t>(c, 0);
    put(c, t);
    put(c, t);
    c.insert(c.end(), data.begin(), data.end());
    return record(0x05, c);
  }
  size_t chunk(const std::string& compression, const std::vector<uint8_t>& records) {
    std::vector<uint8_t> c;
    put<uint64_t>(c, 0);
    put<uint64_t>(c, 0);
    put<uint64_t>(c, records.size());
    put<uint32_t>(c, 0);
    str(c, compression);
    put<uint64_t>(c, records.size());
    c.insert(c.end(), records.begin(), records.end());
    return record(0x06, c);
  }
  const std::vector<uint8_t>& bytes() const { return b_; }

 private:
  template <typename T>
  static void put(std::vector<uint8_t>& b, T v) {
    b.insert(b.end(), reinterpret_cast<const uint8_t*>(&v), reinterpret_cast<const uint8_t*>(&v) + sizeof(T));
  }
  static void str(std::vector<uint8_t>& b, const std::string& s) {
    put(b, static_cast<uint32_t>(s.size()));
    b.insert(b.end(), s.begin(), s.end());
  }
  size_t record(uint8_t op, const std::vector<uint8_t>& c) {
    const size_t at = b_.size();
    b_.push_back(op);
    put<uint64_t>(b_, c.size());
    b_.insert(b_.end(), c.begin(), c.end());
    return at;
  }
  std::vector<uint8_t> b_;
};

// Bad input, each named in one line with the file, the topic and the offset, exit 2, and everything intact still
// converted: a message shorter than its schema, a schema that does not parse, a chunk of an unknown compression.
TEST(Ros2Import, BadInputIsNamedAndTheRestConverted) {
  test::TempDir dir;
  RawMcap m;
  m.schema(1, "sensor_msgs/msg/LaserScan", "");
  m.schema(2, "demo_msgs/msg/Pair", "int32 a\nfloat64 b\n");
  m.schema(3, "demo_msgs/msg/Broken", "int32 a\nNoSuchType b\n");
  m.channel(1, 1, "/scan");
  m.channel(2, 2, "/pair");
  m.channel(3, 3, "/broken");
  m.message(1, 1'000'000'000, scan(false, 1, 0, 1.0F));
  const std::vector<uint8_t> pair = Cdr(false).put<int32_t>(7).put(2.5).bytes();
  m.message(2, 1'000'000'000, pair);
  const size_t short_at = m.message(2, 1'100'000'000, {pair.begin(), pair.begin() + 9});  // ends inside b
  const size_t broken_at = m.message(3, 1'200'000'000, Cdr(false).put<int32_t>(1).bytes());
  const size_t chunk_at = m.chunk("brotli", {1, 2, 3});
  const auto cut_scan = scan(false, 2, 0, 2.0F);
  const size_t scan_short_at = m.message(1, 2'000'000'000, {cut_scan.begin(), cut_scan.begin() + 20});
  m.message(1, 3'000'000'000, scan(false, 3, 0, 3.0F));
  test::write_file(dir.file("bad.mcap"), m.bytes());

  const auto r = import({dir.file("bad.mcap")}, dir.file("out.lcm"));
  EXPECT_EQ(r.error, "");
  const std::string f = dir.file("bad.mcap");
  EXPECT_NE(r.said().find(f + ": /pair at byte " + std::to_string(short_at) +
                          ": not a demo_msgs/msg/Pair: ends inside the message (9 bytes)\n"),
            std::string::npos)
      << r.said();
  EXPECT_NE(r.said().find(f + ": /broken at byte " + std::to_string(broken_at) +
                          ": the schema of demo_msgs/msg/Broken does not parse (line 2: type NoSuchType is not defined "
                          "in the schema); its messages are carried unchecked\n"),
            std::string::npos)
      << r.said();
  EXPECT_NE(r.said().find(f + ": at byte " + std::to_string(chunk_at) +
                          ": a chunk compressed with \"brotli\", which is not known"),
            std::string::npos)
      << r.said();
  EXPECT_NE(r.said().find(f + ": /scan at byte " + std::to_string(scan_short_at) + ": not a sensor_msgs/LaserScan: "),
            std::string::npos)
      << r.said();
  const auto log = by_channel(dir.file("out.lcm"));
  EXPECT_EQ(log.at("/scan").size(), 2u);
  EXPECT_EQ(log.at("/pair").size(), 1u);
  EXPECT_EQ(log.at("/broken").size(), 1u);
  EXPECT_NE(r.text.find("(1 malformed, left out)"), std::string::npos) << r.text;
}

// A zstd chunk in the middle of a file that does not decompress (its frame's first bytes overwritten), while
// the chunks around it are decompressed on the reader's second thread: reported once, naming the file and the
// chunk's offset (then the data section's CRC, which the damage breaks too), exit 2, and every scan before and
// after it converted, in order; the same lines and the same log as the reader on one thread gives.
TEST(Ros2Import, CorruptChunkInTheMiddleIsReportedOnceAndTheRestConverted) {
  test::TempDir dir;
  const std::string f = dir.file("scans.mcap");
  write_scans(f, 0, 300, false, 1024);  // about 8 scans a chunk
  auto bytes = test::read_file(f);
  std::vector<uint64_t> chunks;  // each scan's chunk
  {
    auto r = formats::McapReader::from_memory(bytes);
    ASSERT_TRUE(r.ok());
    r->read([&](const formats::McapMessage& m) { chunks.push_back(m.offset); },
            [](const formats::McapProblem& p) { ADD_FAILURE() << p.what; });
  }
  ASSERT_EQ(chunks.size(), 300u);
  const uint64_t victim = chunks[150];
  const size_t frame = victim + 9 + 8 + 8 + 8 + 4 + 4 + 4 + 8;  // the chunk's fields, then its zstd frame
  ASSERT_EQ(bytes[frame], 0x28);
  std::fill_n(bytes.begin() + static_cast<ptrdiff_t>(frame), 4, 0);
  test::write_file(f, bytes);

  const auto r = import({f}, dir.file("out.lcm"));
  EXPECT_EQ(r.error, "");
  ASSERT_EQ(r.problems.size(), 2u) << r.said();
  EXPECT_EQ(r.problems[0], f + ": at byte " + std::to_string(victim) + ": chunk: zstd: Unknown frame descriptor");
  EXPECT_EQ(r.problems[1].rfind(f + ": at byte ", 0), 0u) << r.said();
  EXPECT_NE(r.problems[1].find(": the data section fails its CRC ("), std::string::npos) << r.said();

  std::vector<float> want;  // the scans outside the victim, in order
  for (int i = 0; i < 300; ++i)
    if (chunks[static_cast<size_t>(i)] != victim) want.push_back(static_cast<float>(i));
  ASSERT_LT(want.size(), 300u);
  ASSERT_GT(want.size(), 280u);
  const auto log = by_channel(dir.file("out.lcm"));
  ASSERT_EQ(log.at("/scan").size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) {
    laser_scan_t s;
    ASSERT_TRUE(lcmtypes::decode(log.at("/scan")[i].data, s));
    EXPECT_EQ(s.ranges[0], want[i]);
  }

  // The same on the calling thread alone.
  std::string serial_problems;
  int64_t serial_messages = 0;
  auto serial = formats::McapReader::from_memory(bytes);
  ASSERT_TRUE(serial.ok());
  serial->set_pipelined(false);
  serial->read([&](const formats::McapMessage&) { ++serial_messages; },
               [&](const formats::McapProblem& p) {
                 serial_problems += f + ": at byte " + std::to_string(p.offset) + ": " + p.what + "\n";
               });
  EXPECT_EQ(serial_problems, r.said());
  EXPECT_EQ(serial_messages, static_cast<int64_t>(want.size()));
}

// sensor_msgs/PointCloud2 in the layout lidar drivers write (float32 fields in the machine's byte order) is
// written straight as LCM's bytes: they equal lcm-gen's encoding of the same point_cloud_t, with and without
// intensity and time, and so do those of the general path (the same points as big-endian data).
TEST(Ros2Import, PointCloudFastPathEncodesAsLcmGen) {
  for (const bool extra : {true, false}) {
    for (const bool big_data : {false, true}) {
      const uint32_t height = 2, width = 3;
      std::vector<std::string> names = {"x", "y", "z"};
      if (extra) names.insert(names.end(), {"intensity", "time"});
      const auto step = static_cast<uint32_t>(4 * names.size() + 4);  // a float of padding after the fields
      Cdr c(false);
      c.put<int32_t>(12).put<uint32_t>(345'678'000).str("lidar").put(height).put(width);
      c.put(static_cast<uint32_t>(names.size()));
      for (size_t i = 0; i < names.size(); ++i) {
        c.str(names[i]).put(static_cast<uint32_t>(4 * i)).put<uint8_t>(7).put<uint32_t>(1);
      }
      c.put<uint8_t>(big_data ? 1 : 0).put(step).put(step * width).put(step * width * height);
      point_cloud_t want;
      want.header.seq = 7;
      want.header.utime = 12'345'678;
      want.header.frame_id = "lidar";
      want.height = static_cast<int32_t>(height);
      want.width = static_cast<int32_t>(width);
      want.npoints = static_cast<int32_t>(height * width);
      std::vector<float>* arrays[] = {&want.x, &want.y, &want.z, &want.intensities, &want.time_offsets};
      for (uint32_t k = 0; k < height * width; ++k) {
        for (size_t f = 0; f <= names.size(); ++f) {
          const float v = f < names.size() ? static_cast<float>(k) * 10.0F + static_cast<float>(f) + 0.25F : -1.0F;
          if (f < names.size()) arrays[f]->push_back(v);
          uint8_t raw[4];
          std::memcpy(raw, &v, 4);
          if (big_data) std::reverse(raw, raw + 4);
          for (uint8_t b : raw) c.put(b);
        }
      }
      c.put<uint8_t>(1);  // is_dense
      want.nintensities = static_cast<int32_t>(want.intensities.size());
      want.ntimes = static_cast<int32_t>(want.time_offsets.size());
      std::string error;
      auto got = formats::convert_ros_message("sensor_msgs/msg/PointCloud2", formats::Serialization::kCdr, c.bytes(), 0,
                                              7, &error);
      ASSERT_TRUE(got) << error;
      EXPECT_EQ(got->lcm, lcmtypes::encode(want)) << "extra " << extra << ", big-endian data " << big_data;
    }
  }
}

// An empty cloud may declare any number of empty rows; found by import_fuzz: 170 bytes declaring 2^32 - 1 rows of
// no columns took 5 s under ASan, walking the rows one by one, and came out with a negative height (point_cloud_t
// counts in int32_t). Rows or columns past int32_t are refused with one line; an empty cloud of two billion rows
// converts as such, with and without x, y and z fields (the fast path and the general one).
TEST(Ros2Import, AnEmptyCloudOfBillionsOfRows) {
  auto cloud = [](uint32_t height, uint32_t width, bool xyz) {
    Cdr c(false);
    c.put<int32_t>(12).put<uint32_t>(0).str("lidar").put(height).put(width);
    const std::vector<std::string> names = xyz ? std::vector<std::string>{"x", "y", "z"} : std::vector<std::string>{};
    c.put(static_cast<uint32_t>(names.size()));
    for (size_t i = 0; i < names.size(); ++i)
      c.str(names[i]).put(static_cast<uint32_t>(4 * i)).put<uint8_t>(7).put<uint32_t>(1);
    c.put<uint8_t>(0).put<uint32_t>(12).put<uint32_t>(0).put<uint32_t>(0).put<uint8_t>(1);
    std::string error;
    auto got = formats::convert_ros_message("sensor_msgs/msg/PointCloud2", formats::Serialization::kCdr, c.bytes(), 0,
                                            0, &error);
    return std::make_pair(std::move(got), error);
  };
  for (const bool xyz : {true, false}) {
    SCOPED_TRACE(xyz ? "x, y and z" : "no fields");
    const auto [too_many, why] = cloud(4294967295U, 0, xyz);
    EXPECT_FALSE(too_many);
    EXPECT_NE(why.find("a point cloud of 4294967295 x 0 points: more rows or columns than point_cloud_t's int32"),
              std::string::npos)
        << why;
    const auto [empty, error] = cloud(2000000000U, 0, xyz);
    ASSERT_TRUE(empty) << error;
    const auto m = test::decode<point_cloud_t>({0, 0, "POINTS", empty->lcm, 0});
    EXPECT_EQ(m.height, 2000000000);
    EXPECT_EQ(m.width, 0);
    EXPECT_EQ(m.npoints, 0);
  }
}

// rosbag2's compression: a file compressed whole (compression_mode FILE) and every message compressed
// (MESSAGE) give the same log as the uncompressed bag.
TEST(Ros2Import, FileAndMessageCompression) {
  const std::string mcap = test::shared_data("bags/nav2_turtlebot.mcap");
  const std::string db3 = test::shared_data("bags/tf_example.db3");
  if (mcap.empty() || db3.empty()) return;
  test::TempDir dir;
  formats::Compressor zstd(formats::Codec::kZstd, 3);
  std::vector<uint8_t> packed;
  ASSERT_EQ(zstd.run(test::read_file(mcap), packed), "");
  test::write_file(dir.file("nav2.mcap.zstd"), packed);
  ASSERT_EQ(import({mcap}, dir.file("plain.lcm")).said(), "");
  auto r = import({dir.file("nav2.mcap.zstd")}, dir.file("packed.lcm"));
  ASSERT_EQ(r.said(), "");
  EXPECT_NE(r.text.find("compressed whole with zstd"), std::string::npos) << r.text;
  EXPECT_EQ(test::read_file(dir.file("plain.lcm")), test::read_file(dir.file("packed.lcm")));
  EXPECT_FALSE(fs::exists(dir.file("packed.lcm.unzstd")));

  fs::copy_file(db3, dir.file("m.db3"));
  fs::permissions(dir.file("m.db3"), fs::perms::owner_write, fs::perm_options::add);
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(dir.file("m.db3").c_str(), &db), SQLITE_OK);
  std::vector<std::pair<int64_t, std::vector<uint8_t>>> rows;
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(db, "SELECT id, data FROM messages", -1, &st, nullptr);
  while (sqlite3_step(st) == SQLITE_ROW) {
    const auto* p = static_cast<const uint8_t*>(sqlite3_column_blob(st, 1));
    std::vector<uint8_t> z;
    ASSERT_EQ(zstd.run({p, static_cast<size_t>(sqlite3_column_bytes(st, 1))}, z), "");
    rows.emplace_back(sqlite3_column_int64(st, 0), std::move(z));
  }
  sqlite3_finalize(st);
  sqlite3_prepare_v2(db, "UPDATE messages SET data = ? WHERE id = ?", -1, &st, nullptr);
  for (const auto& [id, z] : rows) {
    sqlite3_bind_blob(st, 1, z.data(), static_cast<int>(z.size()), SQLITE_STATIC);
    sqlite3_bind_int64(st, 2, id);
    ASSERT_EQ(sqlite3_step(st), SQLITE_DONE);
    sqlite3_reset(st);
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  ASSERT_EQ(import({db3}, dir.file("db_plain.lcm")).said(), "");
  r = import({dir.file("m.db3")}, dir.file("db_packed.lcm"));
  ASSERT_EQ(r.said(), "");
  EXPECT_EQ(test::read_file(dir.file("db_plain.lcm")), test::read_file(dir.file("db_packed.lcm")));
}

// Reading a bag leaves its folder as it was: a sqlite3 bag in WAL mode (ros2 bag record's) opened read-only left an
// empty -wal and a 32 KiB -shm file beside it. And a bag whose recorder is still writing (its rows in the write-ahead
// log, not yet in the file) is read with those rows.
TEST(Ros2Import, ASqliteBagIsReadWithoutWritingBesideItAndWithItsWriteAheadLog) {
  test::TempDir dir;
  const std::string bag = dir.file("rec") + "/rec_0.db3";
  fs::create_directories(dir.file("rec"));
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(bag.c_str(), &db), SQLITE_OK);
  auto exec = [&](const std::string& sql) {
    EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  };
  exec(
      "PRAGMA journal_mode=WAL; PRAGMA wal_autocheckpoint=0;"
      "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT, "
      "offered_qos_profiles TEXT); INSERT INTO topics VALUES(1, '/x', 'std_msgs/msg/Empty', 'cdr', '');"
      "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, data BLOB);");
  exec("PRAGMA wal_checkpoint(TRUNCATE);");  // the tables in the file; the rows below only in the log
  for (int i = 1; i <= 5; ++i) {
    exec("INSERT INTO messages VALUES(" + std::to_string(i) + ", 1, " + std::to_string(1000 * i) + ", x'00010000');");
  }
  ASSERT_GT(fs::file_size(bag + "-wal"), 0u);
  auto r = import({bag}, dir.file("live.lcm"));
  EXPECT_EQ(r.said(), "");
  EXPECT_EQ(by_channel(dir.file("live.lcm")).at("/x").size(), 5u);  // the recorder's rows, from its log
  sqlite3_close(db);  // the recorder stops: its log checkpointed into the file, -wal and -shm removed

  ASSERT_FALSE(fs::exists(bag + "-wal"));
  const auto before = fs::last_write_time(bag);
  r = import({bag}, dir.file("done.lcm"));
  EXPECT_EQ(r.said(), "");
  EXPECT_EQ(by_channel(dir.file("done.lcm")).at("/x").size(), 5u);
  std::vector<std::string> beside;
  for (const auto& f : fs::directory_iterator(dir.file("rec"))) beside.push_back(f.path().filename().string());
  EXPECT_EQ(beside, std::vector<std::string>{"rec_0.db3"});
  EXPECT_EQ(fs::last_write_time(bag), before);
}

// A sqlite3 bag cut short: the rows before the damage are read, the damage is named, exit 2.
TEST(Ros2Import, CutSqliteBag) {
  const std::string db3 = test::shared_data("bags/tf_example.db3");
  if (db3.empty()) return;
  test::TempDir dir;
  auto bytes = test::read_file(db3);
  bytes.resize(bytes.size() * 2 / 3);
  test::write_file(dir.file("cut.db3"), bytes);
  const auto r = import({dir.file("cut.db3")}, dir.file("cut.lcm"));
  EXPECT_EQ(r.error, "");
  EXPECT_NE(r.said().find(dir.file("cut.db3") + ": the file is cut short"), std::string::npos) << r.said();
  EXPECT_NE(r.said().find("cannot be read (database disk image is malformed)"), std::string::npos) << r.said();
  // The rows on the pages before the cut: more than a third of the 517 transforms, fewer than all.
  const auto log = by_channel(dir.file("cut.lcm"));
  EXPECT_GT(log.at("/tf").size(), 517u / 3);
  EXPECT_LT(log.at("/tf").size(), 517u);
  EXPECT_EQ(log.at("/tf_static").size(), 1u);
}

// A messages table whose ids are not rosbag2's integer keys (here reals, two of them read as the integer 1): reading
// stops where the ids stop increasing, says so, and keeps what came before. Before, a damaged page after such ids
// had reading go round the same rows for ever (found by the ros2 fuzzer). And a table of many small rows is read
// whole: the work limit a hostile schema meets is far above what rows cost.
TEST(Ros2Import, MessageIdsThatDoNotIncreaseStopReading) {
  test::TempDir dir;
  const auto make = [&](const std::string& name, const std::string& id_type, const std::vector<std::string>& ids) {
    sqlite3* db = nullptr;
    EXPECT_EQ(sqlite3_open(dir.file(name).c_str(), &db), SQLITE_OK);
    std::string sql = "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT, "
                      "offered_qos_profiles TEXT); INSERT INTO topics VALUES(1, '/x', 'std_msgs/msg/Empty', 'cdr', '');"
                      "CREATE TABLE messages(id " + id_type + ", topic_id INTEGER, timestamp INTEGER, data BLOB);"
                      "BEGIN;";
    for (size_t i = 0; i < ids.size(); ++i) {
      sql += "INSERT INTO messages VALUES(" + ids[i] + ", 1, " + std::to_string(1000 + i) + ", x'00010000');";
    }
    sql += "COMMIT;";
    EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
    sqlite3_close(db);
    auto r = formats::SqliteBagReader::open(dir.file(name));
    EXPECT_TRUE(r.ok()) << r.error().message;
    std::vector<int64_t> rows;
    std::vector<std::string> problems;
    r->read([&](const formats::Ros2DbMessage& m) { rows.push_back(m.row); },
            [&](const formats::Ros2DbProblem& p) { problems.push_back(p.what); });
    return std::make_pair(rows, problems);
  };
  const auto [rows, problems] = make("real_ids.db3", "REAL", {"0.5", "1.2", "1.7", "3"});
  EXPECT_EQ(rows, (std::vector<int64_t>{0, 1}));
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("message ids after 1 repeat or are not integers"), std::string::npos) << problems[0];

  std::vector<std::string> many;
  for (int i = 1; i <= 200000; ++i) many.push_back(std::to_string(i));
  const auto [all, none] = make("many.db3", "INTEGER PRIMARY KEY", many);
  EXPECT_EQ(all.size(), many.size());
  EXPECT_TRUE(none.empty()) << none.front();
}

// Every command takes these files directly: the conversion is made once beside the file and said on stderr,
// reused while the file is unchanged, made again when it changes, and kept under XDG_CACHE_HOME when the folder
// cannot be written.
TEST(Ros2Import, CommandsReadBagsThroughACache) {
  const std::string src = test::shared_data("bags/nav2_turtlebot.mcap");
  if (src.empty()) return;
  test::TempDir dir;
  const std::string bag = dir.file("run.mcap");
  fs::copy_file(src, bag);
  CmdResult r = driftlab("info '" + bag + "'");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "driftlab: " + bag + ": converting it to " + bag + ".dlimport.lcm (kept for later runs)\n" +
                       "driftlab: " + bag + " (ROS 2 bag (MCAP)): 8,201 messages converted\n");
  EXPECT_NE(r.out.find("/amcl_pose"), std::string::npos);
  r = driftlab("diagnose '" + bag + "' --json-out '" + dir.file("d.json") + "'");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "driftlab: " + bag + ": reading its conversion " + bag + ".dlimport.lcm\n");
  r = driftlab("eval --gt '" + bag + ":/odom' --est '" + bag + ":/amcl_pose' --max-dt 0.05");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("matched"), std::string::npos) << r.out;
  r = driftlab("export tum '" + bag + ":/odom' -o '" + dir.file("odom.tum") + "'");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("2,639 poses"), std::string::npos) << r.out;

  // Changed (a new modification time): converted again.
  ASSERT_EQ(test::run("touch -d '2001-01-01' '" + bag + "'"), 0);
  r = driftlab("info '" + bag + "'");
  EXPECT_NE(r.err.find("converting it to"), std::string::npos) << r.err;

  // A folder that cannot be written: the cache goes to XDG_CACHE_HOME.
  const std::string ro = dir.file("ro");
  fs::create_directories(ro);
  fs::copy_file(src, ro + "/run.mcap");
  fs::permissions(ro, fs::perms::owner_read | fs::perms::owner_exec);
  r = run_capture("XDG_CACHE_HOME='" + dir.file("cache") + "' " + kDriftlab + " info '" + ro + "/run.mcap'");
  fs::permissions(ro, fs::perms::owner_all);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("converting it to " + dir.file("cache") + "/driftlab/run.mcap-"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(ro + "/run.mcap.dlimport.lcm"));
}

// One file is read once, however often it is named: listed twice in metadata.yaml (also as "./b_0.mcap"), or given
// twice on the command line (also through a link), it was imported twice, every message doubled, exit 0. Now each
// repetition is one line and the messages are there once.
TEST(Ros2Import, AFileListedOrGivenTwiceIsReadOnce) {
  test::TempDir dir;
  const std::string bag = dir.file("bag");
  fs::create_directories(bag);
  write_scans(bag + "/b_0.mcap", 0, 4);
  formats::Ros2TopicInfo topic{"/scan", "sensor_msgs/msg/LaserScan", "cdr", "", "", 4};
  write_text(bag + "/metadata.yaml",
             formats::ros2_metadata_yaml("mcap", {topic}, {{"b_0.mcap", 0, 0, 4}, {"./b_0.mcap", 0, 0, 4}}));
  auto r = import({bag}, dir.file("out.lcm"));
  EXPECT_EQ(r.said(),
            bag + "/./b_0.mcap (the same file as " + bag + "/b_0.mcap): listed twice in metadata.yaml; read once\n");
  EXPECT_EQ(by_channel(dir.file("out.lcm")).at("/scan").size(), 4u);

  fs::create_symlink(bag + "/b_0.mcap", dir.file("link.mcap"));
  r = import({bag + "/b_0.mcap", dir.file("link.mcap")}, dir.file("two.lcm"));
  EXPECT_EQ(r.said(), dir.file("link.mcap") + " (the same file as " + bag + "/b_0.mcap): given twice; read once\n");
  EXPECT_EQ(by_channel(dir.file("two.lcm")).at("/scan").size(), 4u);
}

// A problem inside a bag compressed whole with zstd names that file (offsets into what it decompresses to): it named
// the temporary file the bag was decompressed into ("OUT.partial.PID.N.unzstd: at byte 58: ..."), gone by then.
TEST(Ros2Import, AProblemInACompressedBagNamesItNotTheTemporaryFile) {
  test::TempDir dir;
  write_scans(dir.file("cut.mcap"), 0, 20);
  auto bytes = test::read_file(dir.file("cut.mcap"));
  bytes.resize(bytes.size() / 2);  // cut inside its chunk
  formats::Compressor zstd(formats::Codec::kZstd, 3);
  std::vector<uint8_t> packed;
  ASSERT_EQ(zstd.run(bytes, packed), "");
  test::write_file(dir.file("cut.mcap.zstd"), packed);
  const auto r = import({dir.file("cut.mcap.zstd")}, dir.file("out.lcm"));
  EXPECT_EQ(r.error, "");
  EXPECT_EQ(r.said().rfind(dir.file("cut.mcap.zstd") + " (decompressed): at byte ", 0), 0u) << r.said();
  EXPECT_EQ(r.said().find("unzstd"), std::string::npos) << r.said();
  EXPECT_EQ(r.said().find(".partial"), std::string::npos) << r.said();
}

}  // namespace
}  // namespace driftlab
