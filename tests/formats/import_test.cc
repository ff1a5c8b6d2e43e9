// driftlab import (formats/import): ROS 1 bags checked against an independent reader on real bags, CARMEN logs
// against their own lines, and broken files of both: every intact message converted, the rest reported.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "driftlab/channel_source_t.hpp"
#include "driftlab/foreign_message_t.hpp"
#include "driftlab/foreign_schema_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "formats/carmen.h"
#include "formats/import.h"
#include "formats/ros1_bag.h"
#include "lcmtypes/seq_origin.h"
#include "lcmtypes/validate.h"
#include "tests/formats/import_in_process.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using test::OwnedEvent;

const std::string kOracle = std::string(DRIFTLAB_SOURCE_DIR) + "/tests/formats/ros1_bag_oracle.py";

test::Imported import(const std::string& in, const std::string& out) { return test::import_in_process({in}, out); }

std::map<std::string, std::vector<OwnedEvent>> by_channel(const std::string& log) {
  std::map<std::string, std::vector<OwnedEvent>> m;
  for (auto& e : test::read_all(log)) m[e.channel].push_back(std::move(e));
  return m;
}

/// What the oracle says of one message, against the converted message.
void expect_same(const nlohmann::json& want, const std::string& type, const OwnedEvent& got) {
  SCOPED_TRACE(got.channel + " " + want.dump());
  EXPECT_EQ(got.utime, want["record_us"].get<int64_t>());
  if (type == "tf2_msgs/TFMessage") {
    const auto tf = test::decode<tf_t>(got);
    ASSERT_EQ(tf.ntransforms, want["transforms"].get<int>());
    const auto& t = tf.transforms[0];
    EXPECT_EQ(t.header.utime, want["first"]["stamp_us"].get<int64_t>());
    EXPECT_EQ(t.header.frame_id, want["first"]["frame_id"]);
    EXPECT_EQ(t.child_frame_id, want["first"]["child"]);
    EXPECT_EQ(t.translation.x, want["first"]["xyz"][0].get<double>());
    EXPECT_EQ(t.translation.z, want["first"]["xyz"][2].get<double>());
    return;
  }
  if (type == "sensor_msgs/LaserScan") {
    const auto s = test::decode<laser_scan_t>(got);
    EXPECT_EQ(s.header.seq, want["seq"].get<int64_t>());
    EXPECT_EQ(s.header.utime, want["stamp_us"].get<int64_t>());
    EXPECT_EQ(s.header.frame_id, want["frame_id"]);
    ASSERT_EQ(s.nranges, want["nranges"].get<int>());
    EXPECT_FLOAT_EQ(s.angle_min, want["angle_min"].get<float>());
    EXPECT_FLOAT_EQ(s.angle_increment, want["angle_increment"].get<float>());
    EXPECT_FLOAT_EQ(s.range_max, want["range_max"].get<float>());
    for (size_t i = 0; i < want["ranges"].size(); ++i) EXPECT_FLOAT_EQ(s.ranges[i], want["ranges"][i].get<float>());
    return;
  }
  if (type == "nav_msgs/Odometry") {
    const auto o = test::decode<odometry_t>(got);
    EXPECT_EQ(o.header.seq, want["seq"].get<int64_t>());
    EXPECT_EQ(o.header.utime, want["stamp_us"].get<int64_t>());
    EXPECT_EQ(o.header.frame_id, want["frame_id"]);
    EXPECT_EQ(o.child_frame_id, want["child"]);
    EXPECT_EQ(o.position.x, want["xyz"][0].get<double>());
    EXPECT_EQ(o.position.y, want["xyz"][1].get<double>());
    EXPECT_EQ(o.orientation.z, want["q_xyzw"][2].get<double>());
    EXPECT_EQ(o.orientation.w, want["q_xyzw"][3].get<double>());
    return;
  }
  ADD_FAILURE() << "the test has no check for " << type;
}

// Every message of real bags (bz2 chunks from carmen_to_rosbag, lz4 chunks from evo's test data) accounted for,
// first and last of each topic equal to what an independent reader finds in the file.
TEST(Import, Ros1BagsAgreeWithAnIndependentReader) {
  for (const char* name : {"carmen/intel.orig.bag", "carmen/aces.orig.bag", "bags/tf_example.bag"}) {
    SCOPED_TRACE(name);
    const std::string bag = test::shared_data(name);
    if (bag.empty()) return;
    test::TempDir dir;
    const auto r = import(bag, dir.file("out.lcm"));
    ASSERT_EQ(r.said(), "");
    EXPECT_NE(r.text.find("(ROS 1 bag)"), std::string::npos) << r.text;

    std::string oracle_out;
    ASSERT_EQ(test::run(std::string(DRIFTLAB_PYTHON) + " " + kOracle + " '" + bag + "'", &oracle_out), 0);
    const auto oracle = nlohmann::json::parse(oracle_out);
    auto log = by_channel(dir.file("out.lcm"));
    // Each topic's type and where its seq comes from, said once before its first message: a stamped message's
    // header.seq is the publisher's; a TFMessage carries none (its transforms' own are not the message's).
    std::map<std::string, channel_source_t> sources;
    for (const auto& e : log["CHANNEL_SOURCES"]) {
      const auto src = test::decode<channel_source_t>(e);
      EXPECT_EQ(sources.count(src.channel), 0u) << src.channel;
      sources[src.channel] = src;
    }
    log.erase("CHANNEL_SOURCES");
    EXPECT_EQ(log.size(), oracle.size());
    EXPECT_EQ(sources.size(), oracle.size());
    for (const auto& [topic, want] : oracle.items()) {
      SCOPED_TRACE(topic);
      ASSERT_TRUE(sources.count(topic));
      EXPECT_EQ(sources.at(topic).source_type, want["type"].get<std::string>());
      const bool tf = want["type"] == "tf/tfMessage" || want["type"] == "tf2_msgs/TFMessage";
      EXPECT_EQ(sources.at(topic).seq_origin,
                static_cast<int8_t>(tf ? lcmtypes::SeqOrigin::kCounted : lcmtypes::SeqOrigin::kSource));
    }
    for (const auto& [topic, want] : oracle.items()) {
      SCOPED_TRACE(topic);
      ASSERT_TRUE(log.count(topic));
      const auto& events = log.at(topic);
      ASSERT_EQ(static_cast<int64_t>(events.size()), want["count"].get<int64_t>());
      expect_same(want["first"], want["type"], events.front());
      expect_same(want["last"], want["type"], events.back());
    }
  }
}

// The README of the data counts 13,631 scans and 26,915 odometry poses in the Intel bag: the import says so too.
TEST(Import, SummaryCountsEveryTopic) {
  const std::string bag = test::shared_data("carmen/intel.orig.bag");
  if (bag.empty()) return;
  test::TempDir dir;
  const auto r = import(bag, dir.file("intel.lcm"));
  ASSERT_EQ(r.said(), "");
  EXPECT_NE(r.text.find("/scan"), std::string::npos);
  EXPECT_NE(r.text.find("sensor_msgs/LaserScan"), std::string::npos);
  EXPECT_NE(r.text.find("13,631"), std::string::npos) << r.text;
  EXPECT_NE(r.text.find("26,915"), std::string::npos) << r.text;
}

// --- A ROS 1 bag written here, record by record, to break it in known ways. ---------------------------------

void put32(std::string& b, uint32_t v) { b.append(reinterpret_cast<const char*>(&v), 4); }
std::string field(const std::string& name, const std::string& value) {
  std::string f;
  put32(f, static_cast<uint32_t>(name.size() + 1 + value.size()));
  return f + name + "=" + value;
}
std::string u32(uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }
std::string record(const std::string& header, const std::string& data) {
  std::string r;
  put32(r, static_cast<uint32_t>(header.size()));
  r += header;
  put32(r, static_cast<uint32_t>(data.size()));
  return r + data;
}
std::string connection(uint32_t id, const std::string& topic, const std::string& type) {
  return record(field("op", "\x07") + field("conn", u32(id)) + field("topic", topic),
                field("topic", topic) + field("type", type) + field("md5sum", "*") +
                    field("message_definition", "# the definition of " + type + "\n"));
}
std::string message(uint32_t conn, uint32_t sec, uint32_t nsec, const std::string& payload) {
  return record(field("op", std::string(1, '\x02')) + field("conn", u32(conn)) + field("time", u32(sec) + u32(nsec)),
                payload);
}
/// A sensor_msgs/LaserScan in ROS 1 serialization: 3 beams.
std::string scan_payload(uint32_t seq, uint32_t sec) {
  std::string p = u32(seq) + u32(sec) + u32(0);
  put32(p, 5);
  p += "laser";
  const float head[7] = {-1.0F, 1.0F, 1.0F, 0.0F, 0.1F, 0.1F, 30.0F};
  p.append(reinterpret_cast<const char*>(head), sizeof(head));
  put32(p, 3);
  const float ranges[3] = {1.5F, 2.5F, 3.5F};
  p.append(reinterpret_cast<const char*>(ranges), sizeof(ranges));
  put32(p, 0);
  return p;
}
/// An unindexed bag (as a recording cut off before rosbag closed it): header, then records, no chunks.
std::string bag_of(const std::string& records) {
  std::string header = record(field("op", "\x03") + field("index_pos", std::string(8, '\0')) +
                                  field("conn_count", u32(0)) + field("chunk_count", u32(0)),
                              std::string(64, ' '));
  return "#ROSBAG V2.0\n" + header + records;
}
std::string write_bag(const test::TempDir& dir, const std::string& bytes) {
  const std::string path = dir.file("in.bag");
  test::write_file(path, {bytes.begin(), bytes.end()});
  return path;
}

// An unindexed bag: every message read; a type without a mapping carried with its definition; a short
// LaserScan and a message on an undefined connection reported with topic and byte offset; exit 2.
TEST(Import, UnindexedBagWithUnmappedAndMalformedMessages) {
  test::TempDir dir;
  std::string recs = connection(0, "/scan", "sensor_msgs/LaserScan") + connection(1, "/chatter", "std_msgs/String");
  recs += message(0, 100, 0, scan_payload(0, 99));
  recs += message(1, 100, 500, u32(5) + "hello");
  const size_t short_at = bag_of(recs).size();
  recs += message(0, 101, 0, scan_payload(1, 100).substr(0, 30));  // cut inside the header's frame
  recs += message(7, 101, 10, "x");                               // connection 7 never defined
  recs += message(0, 102, 0, scan_payload(2, 101));
  const auto r = import(write_bag(dir, bag_of(recs)), dir.file("out.lcm"));
  EXPECT_EQ(r.error, "");
  EXPECT_EQ(r.problems.size(), 2u) << r.said();
  EXPECT_NE(r.said().find("in.bag: /scan at byte " + std::to_string(short_at) + ": not a sensor_msgs/LaserScan"),
            std::string::npos)
      << r.said();
  EXPECT_NE(r.said().find("connection 7"), std::string::npos) << r.said();

  const auto log = by_channel(dir.file("out.lcm"));
  ASSERT_EQ(log.at("/scan").size(), 2u);
  const auto s = test::decode<laser_scan_t>(log.at("/scan")[1]);
  EXPECT_EQ(s.header.seq, 2);
  EXPECT_EQ(s.header.utime, 101'000'000);
  EXPECT_EQ(log.at("/scan")[1].utime, 102'000'000);
  ASSERT_EQ(s.nranges, 3);
  EXPECT_FLOAT_EQ(s.ranges[2], 3.5F);

  ASSERT_EQ(log.at("/chatter").size(), 1u);
  const auto f = test::decode<foreign_message_t>(log.at("/chatter")[0]);
  EXPECT_EQ(f.type, "std_msgs/String");
  EXPECT_EQ(f.encoding, "ros1");
  EXPECT_EQ(std::string(f.data.begin(), f.data.end()), u32(5) + "hello");
  ASSERT_EQ(log.at("FOREIGN_SCHEMAS").size(), 1u);
  const auto schema = test::decode<foreign_schema_t>(log.at("FOREIGN_SCHEMAS")[0]);
  EXPECT_EQ(schema.channel, "/chatter");
  EXPECT_EQ(schema.definition, "# the definition of std_msgs/String\n");
}

// Garbage in the middle of a bag: reported with its offset, and reading goes on at the next record.
TEST(Import, CorruptBytesAreSkippedToTheNextRecord) {
  test::TempDir dir;
  std::string recs = connection(0, "/scan", "sensor_msgs/LaserScan") + message(0, 1, 0, scan_payload(0, 1));
  const size_t garbage_at = bag_of(recs).size();
  recs += std::string(300, '\xff');
  for (uint32_t i = 1; i < 4; ++i) recs += message(0, 1 + i, 0, scan_payload(i, 1 + i));
  const auto r = import(write_bag(dir, bag_of(recs)), dir.file("out.lcm"));
  EXPECT_EQ(r.error, "");
  EXPECT_EQ(r.problems.size(), 1u) << r.said();
  EXPECT_NE(r.said().find("at byte " + std::to_string(garbage_at) + ": a record header length"), std::string::npos)
      << r.said();
  EXPECT_NE(r.said().find("300 bytes skipped"), std::string::npos) << r.said();
  EXPECT_EQ(by_channel(dir.file("out.lcm")).at("/scan").size(), 4u);
}

// A real bag cut short (bz2 chunks): everything before the cut converted, the cut reported.
TEST(Import, TruncatedBagKeepsEveryWholeMessage) {
  const std::string bag = test::shared_data("carmen/aces.orig.bag");
  if (bag.empty()) return;
  test::TempDir dir;
  auto bytes = test::read_file(bag);
  bytes.resize(bytes.size() / 2);
  test::write_file(dir.file("half.bag"), bytes);
  const auto r = import(dir.file("half.bag"), dir.file("half.lcm"));
  EXPECT_EQ(r.error, "");
  EXPECT_NE(r.said().find("half.bag: at byte "), std::string::npos) << r.said();
  EXPECT_NE(r.said().find("the file ends inside this record"), std::string::npos) << r.said();
  const auto log = by_channel(dir.file("half.lcm"));
  // About half of the 7,374 scans: whole chunks only, and the cut chunk's messages decoded before the cut.
  ASSERT_TRUE(log.count("/scan"));
  EXPECT_GT(log.at("/scan").size(), 7374u * 4 / 10);
  EXPECT_LT(log.at("/scan").size(), 7374u * 6 / 10);
}

/// A chunk record holding records, stored as they are but labelled with `compression`.
std::string chunk(const std::string& compression, const std::string& records) {
  return record(field("op", "\x05") + field("compression", compression) +
                    field("size", u32(static_cast<uint32_t>(records.size()))),
                records);
}
/// A closed bag: header (index_pos pointing after the chunks), chunks, then the connections again, as rosbag writes
/// them (the chunk infos are left out: a front-to-back reader does not need them).
std::string indexed_bag_of(const std::string& chunks, const std::string& index) {
  auto header = [](uint64_t index_pos) {
    return record(field("op", "\x03") + field("index_pos", std::string(reinterpret_cast<const char*>(&index_pos), 8)) +
                      field("conn_count", u32(1)) + field("chunk_count", u32(3)),
                  std::string(4096, ' '));
  };
  const std::string magic = "#ROSBAG V2.0\n";
  return magic + header(magic.size() + header(0).size() + chunks.size()) + chunks + index;
}

// A chunk of a compression rosbag does not know, between two good ones, holding the topic's connection record: one
// line naming the file and the chunk's offset, exit 2, and the messages of the other chunks converted (the
// connection found again where a closed bag repeats it, after the chunks).
TEST(Import, UnknownChunkCompressionLeavesOutThatChunkOnly) {
  test::TempDir dir;
  std::string first, second, third;
  for (uint32_t i = 0; i < 3; ++i) first += message(0, 10 + i, 0, scan_payload(i, 10 + i));
  second = connection(0, "/scan", "sensor_msgs/LaserScan");
  for (uint32_t i = 3; i < 6; ++i) second += message(0, 10 + i, 0, scan_payload(i, 10 + i));
  for (uint32_t i = 6; i < 9; ++i) third += message(0, 10 + i, 0, scan_payload(i, 10 + i));
  // The first chunk's messages come before any connection record: only the index names their connection.
  const std::string bag = indexed_bag_of(chunk("none", first) + chunk("zip", second) + chunk("none", third),
                                         connection(0, "/scan", "sensor_msgs/LaserScan"));
  const size_t zip_at = bag.find(chunk("zip", second));
  const auto r = import(write_bag(dir, bag), dir.file("out.lcm"));
  EXPECT_EQ(r.said(), dir.file("in.bag") + ": at byte " + std::to_string(zip_at) +
                          ": a chunk compressed with \"zip\", which is not known (rosbag's are none, bz2 and lz4); its "
                          "messages are left out\n");
  const auto log = by_channel(dir.file("out.lcm"));
  ASSERT_EQ(log.at("/scan").size(), 6u);
  const std::vector<int64_t> want = {0, 1, 2, 6, 7, 8};
  for (size_t i = 0; i < want.size(); ++i) {
    const auto s = test::decode<laser_scan_t>(log.at("/scan")[i]);
    EXPECT_EQ(s.header.seq, want[i]);
    EXPECT_EQ(log.at("/scan")[i].utime, (10 + want[i]) * 1'000'000);
  }
}

/// Every call a ROS 1 bag reader makes, as text: messages (topic, record time, offset, bytes) and problems.
std::string trace(formats::Ros1BagReader& r) {
  std::string out;
  r.read(
      [&](const formats::BagMessage& m) {
        out += "message " + m.connection->topic + " " + std::to_string(m.record_time_ns) + " " +
               std::to_string(m.offset) + " " + std::string(m.data.begin(), m.data.end()) + "\n";
      },
      [&](const formats::BagProblem& p) { out += "problem " + std::to_string(p.offset) + " " + p.what + "\n"; });
  return out;
}

/// The offsets of a bag's chunk records.
std::vector<size_t> chunk_offsets(const std::vector<uint8_t>& b) {
  std::vector<size_t> out;
  auto le32 = [&](size_t p) {
    uint32_t v;
    std::memcpy(&v, b.data() + p, 4);
    return v;
  };
  for (size_t p = 13; p + 8 <= b.size();) {
    const uint32_t header_len = le32(p);
    const std::string header(b.begin() + static_cast<ptrdiff_t>(p + 4),
                             b.begin() + static_cast<ptrdiff_t>(p + 4 + header_len));
    if (header.find(std::string("op=\x05", 4)) != std::string::npos) out.push_back(p);
    p += 8 + header_len + le32(p + 4 + header_len);
  }
  return out;
}

// The reader decompresses the chunks ahead on threads of its own: what it delivers, and every problem, in order, is
// the same as decompressing each chunk when it comes to it, on a whole bag (ACES: 17 bz2 chunks) and broken ones.
TEST(Ros1Bag, PipelinedReadMakesTheSameCalls) {
  for (const char* name : {"carmen/aces.orig.bag"}) {
    SCOPED_TRACE(name);
    const std::string bag = test::shared_data(name);
    if (bag.empty()) return;
    const auto whole = test::read_file(bag);
    const auto chunks = chunk_offsets(whole);
    ASSERT_GE(chunks.size(), 3u);
    const size_t middle = chunks[chunks.size() / 2];
    std::vector<std::vector<uint8_t>> variants = {whole};
    auto damaged = whole;  // bytes flipped inside three chunks' compressed data
    for (size_t k : {size_t{0}, chunks.size() / 2, chunks.size() - 1}) damaged[chunks[k] + 300] ^= 0x5a;
    variants.push_back(damaged);
    auto garbage = whole;  // garbage before the middle chunk
    garbage.insert(garbage.begin() + static_cast<ptrdiff_t>(middle), 77, 0xAB);
    variants.push_back(garbage);
    auto length = whole;  // the middle chunk's data length runs past the end of the file
    uint32_t header_len;
    std::memcpy(&header_len, whole.data() + middle, 4);
    std::fill_n(length.begin() + static_cast<ptrdiff_t>(middle + 4 + header_len), 4, 0x7f);
    variants.push_back(length);
    variants.emplace_back(whole.begin(), whole.begin() + static_cast<ptrdiff_t>(middle + 300));  // cut short
    for (size_t v = 0; v < variants.size(); ++v) {
      auto serial = formats::Ros1BagReader::from_memory(variants[v]);
      auto pipelined = formats::Ros1BagReader::from_memory(variants[v]);
      ASSERT_TRUE(serial.ok() && pipelined.ok());
      serial->set_pipelined(false);
      const std::string want = trace(*serial);
      EXPECT_EQ(trace(*pipelined), want) << "variant " << v;
      EXPECT_EQ(want.find("problem ") != std::string::npos, v > 0) << "variant " << v;
    }
  }
}

// A callback that throws stops the read (the decompressing threads are stopped and joined); the reader reads again.
TEST(Ros1Bag, ThrowingCallbackStopsThePipelinedRead) {
  const std::string bag = test::shared_data("carmen/aces.orig.bag");
  if (bag.empty()) return;
  auto r = formats::Ros1BagReader::open(bag);
  ASSERT_TRUE(r.ok());
  int seen = 0;
  EXPECT_THROW(r->read(
                   [&](const formats::BagMessage&) {
                     if (++seen == 1000) throw std::runtime_error("enough");
                   },
                   [](const formats::BagProblem&) {}),
               std::runtime_error);
  EXPECT_EQ(seen, 1000);
  int64_t again = 0;
  EXPECT_GT(r->read([&](const formats::BagMessage&) { ++again; },
                    [](const formats::BagProblem& p) { ADD_FAILURE() << p.what; }),
            20000);
  EXPECT_GT(again, 20000);
}

TEST(Import, UnknownFormatsAreNamedInOneLine) {
  test::TempDir dir;
  test::write_file(dir.file("notes.txt"), {'h', 'e', 'l', 'l', 'o', '\n'});
  auto r = import(dir.file("notes.txt"), dir.file("out.lcm"));
  EXPECT_EQ(r.said(),
            dir.file("notes.txt") +
                ": not a format driftlab imports (ROS 1 bag, ROS 2 bag (MCAP, sqlite3, or its folder), MCAP file, "
                "CARMEN log, PX4 ULog, MRPT rawlog): text starting "
                "\"hello\"\n");
  test::write_file(dir.file("empty"), {});
  r = import(dir.file("empty"), dir.file("out.lcm"));
  EXPECT_NE(r.error.find("an empty file"), std::string::npos) << r.said();
  EXPECT_FALSE(std::filesystem::exists(dir.file("out.lcm")));
}

// --- CARMEN -------------------------------------------------------------------------------------------------

// GMapping's corrected Intel log: every FLASER and ODOM line converted, NEFF lines counted as skipped; a
// 180-beam FLASER spans -90..+89 degrees, and its longest reading (81.83 m, the SICK's "no return") lies above
// range_max while every other reading is within it.
TEST(Import, CarmenCorrectedLog) {
  const std::string gz = test::shared_data("carmen/intel-corrected.log.gz");
  if (gz.empty()) return;
  test::TempDir dir;
  const auto r = import(gz, dir.file("c.lcm"));
  ASSERT_EQ(r.said(), "");
  EXPECT_NE(r.text.find("(CARMEN log)"), std::string::npos);
  EXPECT_NE(r.text.find("skipped NEFF"), std::string::npos) << r.text;
  const auto log = by_channel(dir.file("c.lcm"));
  ASSERT_EQ(log.at("FLASER").size(), 910u);
  EXPECT_EQ(log.at("FLASER_POSE").size(), 910u);
  EXPECT_EQ(log.at("ODOM").size(), 14541u);
  ASSERT_EQ(log.at("TF_STATIC").size(), 1u);

  // The first FLASER line, read here by the shell, against its message.
  std::string line;
  ASSERT_EQ(test::run("zcat '" + gz + "' | grep -m1 '^FLASER'", &line), 0);
  std::istringstream in(line);
  std::string word;
  int n = 0;
  in >> word >> n;
  ASSERT_EQ(n, 180);
  std::vector<double> ranges(static_cast<size_t>(n));
  for (auto& v : ranges) in >> v;
  double x, y, theta, ox, oy, otheta, ipc, logger;
  std::string host;
  in >> x >> y >> theta >> ox >> oy >> otheta >> ipc >> host >> logger;

  const auto s = test::decode<laser_scan_t>(log.at("FLASER")[0]);
  EXPECT_EQ(s.header.utime, std::llround(ipc * 1e6));
  EXPECT_EQ(log.at("FLASER")[0].utime, std::llround(logger * 1e6));
  EXPECT_EQ(s.header.frame_id, "laser");
  ASSERT_EQ(s.nranges, 180);
  EXPECT_NEAR(s.angle_min, -std::numbers::pi / 2, 1e-6);
  EXPECT_NEAR(s.angle_max, 89 * std::numbers::pi / 180, 1e-6);
  EXPECT_NEAR(s.angle_increment, std::numbers::pi / 180, 1e-7);
  for (int i = 0; i < n; ++i) EXPECT_FLOAT_EQ(s.ranges[static_cast<size_t>(i)], static_cast<float>(ranges[i]));
  const auto p = test::decode<pose_t>(log.at("FLASER_POSE")[0]);
  EXPECT_EQ(p.position.x, x);
  EXPECT_NEAR(2 * std::atan2(p.orientation.z, p.orientation.w), theta, 1e-12);

  float longest = 0;
  int64_t at_longest = 0, beyond = 0;
  for (const auto& e : log.at("FLASER")) {
    const auto scan = test::decode<laser_scan_t>(e);
    for (float v : scan.ranges) {
      if (v > longest) longest = v, at_longest = 0;
      at_longest += v == longest;
      beyond += v > scan.range_max;
    }
  }
  EXPECT_FLOAT_EQ(longest, 81.83F);
  EXPECT_EQ(beyond, at_longest);
}

// Every CARMEN message driftlab reads, on lines written here, with a broken line in the middle.
TEST(Import, CarmenMessagesAndBrokenLines) {
  test::TempDir dir;
  std::string text =
      "# CARMEN log\n"
      "PARAM robot_frontlaser_offset 0.25 nohost 0\n"
      "ODOM 1.0 2.0 0.5 0.3 0.1 0 10.000001 host 10.002\n"
      "TRUEPOS 1.1 2.1 0.6 1.0 2.0 0.5 10.01 host 10.011\n"
      "RAWLASER1 0 -1.5708 3.1416 0.0175 30.0 0.01 0 3 1.0 30.0 2.0 0 10.02 host 10.025\n"
      "FLASER 4 1 2 x 4 0 0 0 0 0 0 10.03 host 10.03\n"
      "ROBOTLASER1 0 -0.5 1.0 0.5 8.0 0.01 0 3 1.0 8.0 2.0 3 10 20 30 0.1 0.2 0.3 1 2 3 0.5 0.1 0 0 0 10.04 host "
      "10.05\n"
      "PARAM robot_rearlaser_offset -0.2 nohost 0\n"
      "PARAM robot_rear_laser_max 8.0 nohost 0\n"
      "RLASER 3 1.5 8.0 2.5 4.0 5.0 3.1 4.0 5.0 3.1 10.06 host 10.07\n"
      "SYNC 1 host 11\n";
  test::write_file(dir.file("in.log"), {text.begin(), text.end()});
  const auto r = import(dir.file("in.log"), dir.file("out.lcm"));
  EXPECT_EQ(r.said(), dir.file("in.log") + ":6: FLASER: \"x\" is not a number\n");
  EXPECT_NE(r.text.find("skipped SYNC"), std::string::npos) << r.text;
  const auto log = by_channel(dir.file("out.lcm"));

  const auto o = test::decode<odometry_t>(log.at("ODOM")[0]);
  EXPECT_EQ(o.header.utime, 10'000'001);
  EXPECT_EQ(log.at("ODOM")[0].utime, 10'002'000);
  EXPECT_EQ(o.position.x, 1.0);
  EXPECT_NEAR(2 * std::atan2(o.orientation.z, o.orientation.w), 0.5, 1e-12);
  EXPECT_EQ(o.linear_velocity.x, 0.3);
  EXPECT_EQ(o.angular_velocity.z, 0.1);
  EXPECT_EQ(test::decode<pose_t>(log.at("TRUEPOS")[0]).position.y, 2.1);

  const auto raw = test::decode<laser_scan_t>(log.at("RAWLASER1")[0]);
  EXPECT_FLOAT_EQ(raw.angle_min, -1.5708F);
  EXPECT_FLOAT_EQ(raw.angle_increment, 0.0175F);
  ASSERT_EQ(raw.nranges, 3);
  EXPECT_GT(raw.ranges[1], raw.range_max);  // 30.0 = maximum_range: no return
  EXPECT_LE(raw.ranges[2], raw.range_max);

  const auto robot = test::decode<laser_scan_t>(log.at("ROBOTLASER1")[0]);
  ASSERT_EQ(robot.nintensities, 3);
  EXPECT_EQ(robot.intensities[2], 30.0F);
  const auto laser_pose = test::decode<pose_t>(log.at("ROBOTLASER1_POSE")[0]);
  EXPECT_EQ(laser_pose.position.x, 0.1);
  EXPECT_EQ(laser_pose.position.y, 0.2);

  // The rear laser: 3 beams over 180 degrees (an odd count includes both ends), its own frame, its maximum (PARAM
  // robot_rear_laser_max) meaning no return; the pose on the line on RLASER_POSE.
  ASSERT_EQ(log.at("RLASER").size(), 1u);
  const auto rear = test::decode<laser_scan_t>(log.at("RLASER")[0]);
  EXPECT_EQ(rear.header.frame_id, "rear_laser");
  EXPECT_EQ(rear.header.utime, 10'060'000);
  EXPECT_EQ(log.at("RLASER")[0].utime, 10'070'000);
  ASSERT_EQ(rear.nranges, 3);
  EXPECT_NEAR(rear.angle_min, -std::numbers::pi / 2, 1e-6);
  EXPECT_NEAR(rear.angle_max, std::numbers::pi / 2, 1e-6);
  EXPECT_NEAR(rear.angle_increment, std::numbers::pi / 2, 1e-6);
  EXPECT_EQ(rear.ranges, (std::vector<float>{1.5F, 8.0F, 2.5F}));
  EXPECT_GT(rear.ranges[1], rear.range_max);  // 8.0: no return
  EXPECT_LE(rear.ranges[2], rear.range_max);
  const auto rear_pose = test::decode<pose_t>(log.at("RLASER_POSE")[0]);
  EXPECT_EQ(rear_pose.child_frame_id, "rear_laser");
  EXPECT_EQ(rear_pose.position.x, 4.0);
  EXPECT_EQ(rear_pose.position.y, 5.0);
  EXPECT_NEAR(2 * std::atan2(rear_pose.orientation.z, rear_pose.orientation.w), 3.1, 1e-12);
  EXPECT_NE(r.text.find("RLASER"), std::string::npos) << r.text;

  const auto tf = test::decode<tf_t>(log.at("TF_STATIC")[0]);
  ASSERT_EQ(tf.ntransforms, 2);
  EXPECT_EQ(tf.transforms[0].child_frame_id, "laser");
  EXPECT_EQ(tf.transforms[0].translation.x, 0.25);  // the PARAM before the lines' poses (next test)
  // The rear laser looks backwards from its offset.
  EXPECT_EQ(tf.transforms[1].child_frame_id, "rear_laser");
  EXPECT_EQ(tf.transforms[1].translation.x, -0.2);
  EXPECT_NEAR(2 * std::atan2(tf.transforms[1].rotation.z, tf.transforms[1].rotation.w), std::numbers::pi, 1e-12);
  // Every field written: the transforms' own headers had an uninitialised seq (MIT CSAIL's .clf imported with
  // 4613442422282062397 there), so two imports of one log could differ.
  for (const auto& x : tf.transforms) {
    EXPECT_EQ(x.header.seq, 0);
    EXPECT_EQ(x.header.utime, tf.header.utime);
  }
}

/// The transforms of the one TF_STATIC a CARMEN log given as text imports to.
std::vector<transform_t> carmen_mounts(const std::string& text) {
  auto log = formats::CarmenReader::from_text(text);
  std::vector<std::string> problems;
  std::optional<tf_t> tf;
  log.read(
      [&](const formats::CarmenMessage& m) {
        if (m.channel != "TF_STATIC") return;
        EXPECT_FALSE(tf) << "one TF_STATIC";
        tf.emplace();
        EXPECT_TRUE(lcmtypes::decode(m.lcm, *tf));
      },
      [&](size_t line, const std::string& what) { problems.push_back(std::to_string(line) + ": " + what); });
  EXPECT_TRUE(problems.empty()) << ::testing::PrintToString(problems);
  return tf ? tf->transforms : std::vector<transform_t>{};
}

// A laser line carries its laser's pose and its robot's (FLASER and RLASER after the readings, ROBOTLASERk after
// the remissions): where no PARAM says where the laser sits and every line says the same, the lines do. The
// Freiburg clinic's log has only ROBOTLASER1 lines, its laser 0.22 m ahead: with the laser put on the robot's
// centre, the SLAM's relation error there was 0.104 m instead of the bag's 0.099 m (SlamOnTheClinicsClf).
TEST(Import, CarmenLaserLinesSayWhereTheirLasersSit) {
  // The robot at (1, 2) facing +y, then at (3, 2) facing +x; the front laser 0.3 m ahead and 0.05 m to its left,
  // the rear one 0.2 m behind and facing backwards.
  const auto robotlaser = carmen_mounts(
      "ODOM 1 2 1.5707963268 0 0 0 10.0 host 10.0\n"
      "ROBOTLASER1 0 -1.5708 3.1416 1.5708 30 0.01 0 3 1 2 3 0 0.95 2.3 1.5707963268 1 2 1.5707963268 0 0 0 0 0 "
      "10.0 host 10.0\n"
      "ROBOTLASER2 0 -1.5708 3.1416 1.5708 30 0.01 0 3 1 2 3 0 1 1.8 4.7123889804 1 2 1.5707963268 0 0 0 0 0 "
      "10.0 host 10.0\n"
      "ROBOTLASER1 0 -1.5708 3.1416 1.5708 30 0.01 0 3 1 2 3 0 3.3 2.05 0 3 2 0 0 0 0 0 0 10.1 host 10.1\n");
  ASSERT_EQ(robotlaser.size(), 2u);
  const auto& front = robotlaser[0];
  EXPECT_EQ(front.child_frame_id, "laser");
  EXPECT_NEAR(front.translation.x, 0.3, 1e-9);
  EXPECT_NEAR(front.translation.y, 0.05, 1e-9);
  EXPECT_NEAR(front.rotation.z, 0, 1e-9);
  const auto& rear = robotlaser[1];
  EXPECT_EQ(rear.child_frame_id, "rear_laser");
  EXPECT_NEAR(rear.translation.x, -0.2, 1e-9);
  EXPECT_NEAR(rear.translation.y, 0, 1e-9);
  EXPECT_NEAR(std::abs(2 * std::atan2(rear.rotation.z, rear.rotation.w)), std::numbers::pi, 1e-9);

  // FLASER lines the same way: the laser 0.3 m ahead on both.
  const std::string first = "FLASER 3 1 2 3 0.3 0 0 0 0 0 10.0 host 10.0\n";
  const auto flaser = carmen_mounts(first + "FLASER 3 1 2 3 1 1.3 1.5707963268 1 1 1.5707963268 10.1 host 10.1\n");
  ASSERT_EQ(flaser.size(), 2u);
  EXPECT_NEAR(flaser[0].translation.x, 0.3, 1e-9);
  EXPECT_NEAR(flaser[0].translation.y, 0, 1e-9);
  // Two poses that do not keep one offset are no mounting (a corrected log: its first pose is the corrected one,
  // its second the odometry's): the laser stays on the robot's centre.
  const auto corrected = carmen_mounts(first + "FLASER 3 1 2 3 1.2 1.3 1.6 1 1 1.5707963268 10.1 host 10.1\n");
  ASSERT_EQ(corrected.size(), 2u);
  EXPECT_EQ(corrected[0].translation.x, 0);
  EXPECT_EQ(corrected[0].translation.y, 0);
}

// Reading counts larger than the numbers on their line are broken lines, named with the count: one beyond
// size_t's range (1.7e47, found by the import fuzzer) was converted to size_t, which is undefined (UBSan stopped
// there; elsewhere the message showed whatever the conversion gave).
TEST(Import, CarmenCountsBeyondTheirLineAreBrokenLines) {
  auto log = formats::CarmenReader::from_text(
      "FLASER 1.7e47 1 2 0 0 0 0 0 0 10.03 host 10.03\n"
      "RLASER 9 1 2 0 0 0 0 0 0 10.03 host 10.03\n"
      "RAWLASER1 0 -1.5708 3.1416 0.0175 30.0 0.01 0 1e300 1.0 0 10.02 host 10.025\n"
      "ROBOTLASER1 0 -0.5 1.0 0.5 8.0 0.01 0 1 1.0 2e19 0 0 0 0 0 0 0 0 0 0 0 10.04 host 10.05\n"
      "FLASER 2 1 2 0 0 0 0 0 0 10.05 host 10.05\n");
  std::vector<std::string> problems;
  std::vector<std::string> channels;
  EXPECT_EQ(
      log.read([&](const formats::CarmenMessage& m) { channels.emplace_back(m.channel); },
               [&](size_t line, const std::string& what) { problems.push_back(std::to_string(line) + ": " + what); }),
      3);
  EXPECT_EQ(problems, (std::vector<std::string>{"1: FLASER: 1.7e+47 readings announced, 9 numbers on the line",
                                                "2: RLASER: 9 readings announced, 9 numbers on the line",
                                                "3: RAWLASER1: 1e+300 readings announced, 10 numbers on the line",
                                                "4: ROBOTLASER1: 2e+19 remissions announced, 21 numbers on the line"}));
  EXPECT_EQ(channels, (std::vector<std::string>{"TF_STATIC", "FLASER", "FLASER_POSE"}));
}

// A time beyond what int64_t microseconds hold is a broken line naming it: 1e300 s became INT64_MIN silently
// (llround of a number out of range), and the message was kept at the start of time.
TEST(Import, CarmenTimesBeyondInt64AreBrokenLines) {
  auto log = formats::CarmenReader::from_text(
      "ODOM 0 0 0 0 0 0 1e300 host 1e300\n"
      "ODOM 0 0 0 0 0 0 10.0 host -1e13\n"
      "ODOM 1 0 0 0 0 0 10.05 host 10.05\n");
  std::vector<std::string> problems;
  std::vector<int64_t> times;
  log.read([&](const formats::CarmenMessage& m) { times.push_back(m.log_utime); },
           [&](size_t line, const std::string& what) { problems.push_back(std::to_string(line) + ": " + what); });
  EXPECT_EQ(problems,
            (std::vector<std::string>{"1: ODOM: time 1e+300 s is beyond what a log time can hold (+/-9.2e12 s)",
                                      "2: ODOM: time -1e+13 s is beyond what a log time can hold (+/-9.2e12 s)"}));
  for (const int64_t t : times) EXPECT_EQ(t, 10050000);
}

// A laser's name is the word and its number. "RAWLASER" and four NULs (found by the import fuzzer) was taken for a
// laser whose frame, "laser" and a NUL, made a laser_scan_t that does not hold its type's layout; such names, and
// any with more than digits after the word, are lines of an unknown message, counted as skipped.
TEST(Import, CarmenLaserNamesAreTheWordAndANumber) {
  using namespace std::string_literals;
  auto log = formats::CarmenReader::from_text(
      "RAWLASER\0\0\0\0 0 0 0 0 0 0 2.04 0 0 85\n"
      "RAWLASER1x 0 0 0 0 0 0 0 0 85\n"
      "RAWLASER3 0 -1 2 1 8 0.01 0 2 1 2 0 85 host 85\n"s);
  std::vector<formats::CarmenMessage> messages;
  std::vector<std::string> problems;
  log.read([&](const formats::CarmenMessage& m) { messages.push_back(m); },
           [&](size_t line, const std::string& what) { problems.push_back(std::to_string(line) + ": " + what); });
  EXPECT_TRUE(problems.empty()) << problems[0];
  ASSERT_EQ(messages.size(), 2u);  // the TF and RAWLASER3's scan
  EXPECT_EQ(messages[1].channel, "RAWLASER3");
  for (const auto& m : messages) EXPECT_FALSE(lcmtypes::layout_problem(m.lcm)) << m.channel;
  EXPECT_EQ(test::decode<laser_scan_t>({0, 0, "RAWLASER3", messages[1].lcm, 0}).header.frame_id, "laser3");
  ASSERT_EQ(log.skipped().size(), 2u);
  EXPECT_EQ(log.skipped()[0].first, "RAWLASER\0\0\0\0"s);
  EXPECT_EQ(log.skipped()[1].first, "RAWLASER1x");
}

}  // namespace
}  // namespace driftlab
