// driftlab import against the readers Foxglove runs (tests/formats/oracle.h): every message of every shared bag
// (ROS 2 MCAP with zstd chunks, sqlite3, ROS 1 bags with bz2 and lz4 chunks, rosbag2's CDR test bags with every
// primitive type) is accounted for, and each converted message equals the oracle's decoding of it, field by field.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "driftlab/foreign_schema_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"
#include "tests/formats/oracle.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using nlohmann::json;
using test::OwnedEvent;

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";

/// Compares a driftlab log with the oracle's reading of the file it came from, topic by topic.
void expect_log_matches(const std::string& log, const std::vector<json>& oracle) {
  std::map<std::string, std::vector<OwnedEvent>> events;
  std::map<std::string, std::string> schemas;
  for (auto& e : test::read_all(log)) {
    if (e.channel == "FOREIGN_SCHEMAS") {
      foreign_schema_t s;
      ASSERT_TRUE(lcmtypes::decode(e.data, s));
      schemas[s.channel] = s.definition;
      continue;
    }
    events[e.channel].push_back(std::move(e));
  }
  std::map<std::string, std::vector<json>> want;
  for (const auto& m : oracle) want[m.at("topic").get<std::string>()].push_back(m);
  ASSERT_EQ(events.size(), want.size());
  for (auto& [topic, msgs] : want) {
    SCOPED_TRACE(topic);
    ASSERT_TRUE(events.count(topic));
    auto& got = events.at(topic);
    ASSERT_EQ(got.size(), msgs.size());
    // header.seq where the source has none: the count on the topic in file order (or MCAP's sequence).
    std::vector<std::pair<OwnedEvent, int64_t>> numbered;
    bool sequences = false;
    for (size_t i = 0; i < got.size(); ++i) numbered.emplace_back(std::move(got[i]), static_cast<int64_t>(i));
    // A ROS 1 bag's oracle goes in time order, the import in file order: both sorted by receive time, then by
    // header stamp and ROS 1's header.seq for messages received at the same instant (stable otherwise).
    auto key_of = [](const OwnedEvent& e) {
      auto h = lcmtypes::read_header(e.data, e.utime);
      tf_t tf;
      if (lcmtypes::decode(e.data, tf)) {  // a batch: its first transform's ROS 1 seq (its own is the count)
        return std::tuple(e.utime, tf.header.utime, tf.ntransforms ? tf.transforms[0].header.seq : 0);
      }
      return std::tuple(e.utime, h ? h->utime : 0, h ? h->seq : 0);
    };
    std::stable_sort(numbered.begin(), numbered.end(),
                     [&](const auto& a, const auto& b) { return key_of(a.first) < key_of(b.first); });
    auto ros_key = [](const json& m) {
      const json& msg = m.at("msg");
      int64_t stamp = 0, seq = 0;
      if (msg.is_object() && msg.contains("header")) {
        stamp = msg["header"]["stamp"]["sec"].get<int64_t>() * 1'000'000 +
                (msg["header"]["stamp"].contains("nsec") ? msg["header"]["stamp"]["nsec"] : msg["header"]["stamp"]["nanosec"])
                        .get<int64_t>() / 1000;
        if (msg["header"].contains("seq")) seq = msg["header"]["seq"].get<int64_t>();
      } else if (msg.is_object() && msg.contains("transforms")) {
        if (!msg["transforms"].empty() && msg["transforms"][0]["header"].contains("seq")) {
          seq = msg["transforms"][0]["header"]["seq"].get<int64_t>();
        }
        for (const auto& t : msg["transforms"]) {
          const json& st = t["header"]["stamp"];
          stamp = std::max(stamp, st["sec"].get<int64_t>() * 1'000'000 +
                                      (st.contains("nsec") ? st["nsec"] : st["nanosec"]).get<int64_t>() / 1000);
        }
      }
      return std::tuple(m.at("time_ns").get<int64_t>() / 1000, stamp, seq);
    };
    std::stable_sort(msgs.begin(), msgs.end(), [&](const json& a, const json& b) { return ros_key(a) < ros_key(b); });
    for (size_t i = 0; i < msgs.size(); ++i) {
      const json& seq = msgs[i].at("sequence");
      sequences |= seq.is_number() && seq.get<int64_t>() != 0;
      const int64_t expected_seq = sequences ? seq.get<int64_t>() : numbered[i].second;
      test::expect_same_message(msgs[i], numbered[i].first, expected_seq, schemas[topic]);
      if (::testing::Test::HasFailure()) return;  // one broken message says enough
    }
  }
}

class SharedBags : public ::testing::TestWithParam<const char*> {};

TEST_P(SharedBags, EveryMessageEqualsFoxglovesReading) {
  const std::string bag = test::shared_data(GetParam());
  if (bag.empty()) return;
  auto oracle = test::oracle_messages(bag);
  if (!oracle) return;
  ASSERT_FALSE(oracle->empty());
  test::TempDir dir;
  const auto r = test::run_capture(kDriftlab + " import '" + bag + "' -o '" + dir.file("out.lcm") + "'");
  // rosbag2's talker test bag stores placeholder definitions ("uint8 level" for rcl_interfaces/Log): its /rosout
  // messages hold more than their schema, which CDR readers accept (Foxglove's too), so it imports cleanly.
  ASSERT_EQ(r.code, 0) << r.err;
  expect_log_matches(dir.file("out.lcm"), *oracle);
}

INSTANTIATE_TEST_SUITE_P(Import, SharedBags,
                         ::testing::Values("bags/nav2_turtlebot.mcap", "bags/mcap_cdr_test_cdr_test_0.mcap",
                                           "bags/mcap_talker_talker.mcap", "bags/sqlite3_cdr_test_cdr_test_0.db3",
                                           "bags/sqlite3_talker_talker.db3", "bags/tf_example.db3",
                                           "bags/tf_example.bag", "carmen/aces.orig.bag", "carmen/intel.orig.bag"),
                         [](const auto& info) {
                           std::string n = info.param;
                           for (char& c : n)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return n;
                         });

}  // namespace
}  // namespace driftlab
