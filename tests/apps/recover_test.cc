// driftlab recover: every intact event of a damaged log into a clean one that LCM's own reader (lcm/eventlog.h,
// which stops at the first bad byte) reads to the end; what was left out listed; intact logs copied unchanged.
#include <gtest/gtest.h>
#include <lcm/eventlog.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/log_writer.h"
#include "driftlab/laser_scan_t.hpp"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

namespace fs = std::filesystem;
const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kData = DRIFTLAB_TEST_DATA;

test::CmdResult driftlab(const std::string& args) { return test::run_capture("timeout 60 " + kDriftlab + " " + args); }

/// Events as LCM's C reader sees them: it stops at the first damage.
std::vector<test::OwnedEvent> read_with_lcm(const std::string& path) {
  std::vector<test::OwnedEvent> out;
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "r");
  if (log == nullptr) return out;
  while (lcm_eventlog_event_t* ev = lcm_eventlog_read_next_event(log)) {
    const auto* data = static_cast<const uint8_t*>(ev->data);
    out.push_back({ev->eventnum, ev->timestamp, std::string(ev->channel, ev->channellen),
                   std::vector<uint8_t>(data, data + ev->datalen), 0});
    lcm_eventlog_free_event(ev);
  }
  lcm_eventlog_destroy(log);
  return out;
}

/// The events with their numbers from 0 and no offsets, as recover writes them.
std::vector<test::OwnedEvent> renumbered(std::vector<test::OwnedEvent> events) {
  for (size_t i = 0; i < events.size(); ++i) events[i].event_number = static_cast<int64_t>(i), events[i].offset = 0;
  return events;
}

TEST(Recover, WritesEveryIntactEventOfADamagedLogIntoOneLcmReadsToTheEnd) {
  test::TempDir dir;
  for (const char* name : {"truncated", "garbage", "bad_lengths"}) {
    const std::string log = kData + "/" + name + ".lcm", out = dir.file(std::string(name) + ".lcm");
    std::vector<Problem> problems;
    const auto intact = test::read_all(log, &problems);
    ASSERT_FALSE(problems.empty()) << name;
    const auto r = driftlab("recover " + log + " -o " + out);
    ASSERT_EQ(r.code, 0) << name << "\n" << r.err;
    // LCM's reader gets every intact event.
    EXPECT_EQ(read_with_lcm(out), renumbered(intact)) << name;
    std::vector<Problem> none;
    EXPECT_EQ(test::read_all(out, &none).size(), intact.size());
    EXPECT_TRUE(none.empty()) << name;
    // What was left out, where, as `driftlab info` names it.
    for (const auto& p : problems) {
      EXPECT_NE(r.out.find("at byte " + std::to_string(p.offset) + ": " + to_string(p.kind)), std::string::npos)
          << name << "\n"
          << r.out;
    }
  }
}

TEST(Recover, LeavesOutMessagesThatLieAboutTheirLengthsUnlessAsked) {
  test::TempDir dir;
  const std::string log = dir.file("lies.lcm");
  driftlab::laser_scan_t scan{};
  scan.header = {0, 1000, "laser"};
  scan.nranges = 3;
  scan.ranges = {1, 2, 3};
  auto lie = test::encode(scan);
  test::put_be32(lie, lcmtypes::kHeaderFrameOffset + 4 + 6 + 7 * 4, -5);  // nranges -5
  {
    auto w = LogWriter::create(log);
    ASSERT_TRUE(w.ok());
    for (int i = 0; i < 10; ++i) ASSERT_TRUE(w->write(1000 + i, "SCAN", i % 3 == 1 ? lie : test::encode(scan)).ok());
    ASSERT_TRUE(w->close().ok());
  }
  auto r = driftlab("recover " + log + " -o " + dir.file("clean.lcm") + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["events"], 7);
  EXPECT_EQ(j["problems_total"], 0);
  EXPECT_EQ(j["malformed"]["SCAN"]["count"], 3);
  const size_t second = 28 + 4 + test::encode(scan).size();  // the first lie is the second event
  EXPECT_EQ(j["malformed"]["SCAN"]["first"], "event at byte " + std::to_string(second) + ": ranges: length -5");
  for (const auto& e : test::read_all(dir.file("clean.lcm"))) EXPECT_EQ(lcmtypes::layout_problem(e.data), std::nullopt);
  r = driftlab("recover " + log + " -o " + dir.file("all.lcm") + " --keep-malformed --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["events"], 10);
}

TEST(Recover, AnIntactLogComesOutByteForByte) {
  test::TempDir dir;
  const auto r = driftlab("recover " + kData + "/sample.lcm -o " + dir.file("copy.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("nothing left out"), std::string::npos) << r.out;
  EXPECT_EQ(test::read_file(dir.file("copy.lcm")), test::read_file(kData + "/sample.lcm"));
}

TEST(Recover, WhatIsNoLogOrCannotBeWrittenLeavesNothing) {
  test::TempDir dir;
  auto r = driftlab("recover " + kData + "/not_a_log.txt -o " + dir.file("x.lcm"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("not_a_log.txt: not an LCM event log"), std::string::npos) << r.err;
  r = driftlab("recover " + kData + "/sample.lcm -o " + dir.file("missing/x.lcm"));
  EXPECT_EQ(r.code, 1);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

}  // namespace
}  // namespace driftlab
