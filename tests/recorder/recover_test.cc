// recorder/recover.h: every intact event of a damaged log into a clean one that LCM's own reader (lcm/eventlog.h,
// which stops at the first bad byte) reads to the end; what was left out listed; intact logs copied unchanged.
#include "recorder/recover.h"

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
const std::string kData = DRIFTLAB_TEST_DATA;

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
    auto r = recorder::recover_log(log, out, {});
    ASSERT_TRUE(r) << name << "\n" << r.error().message;
    const std::string text = recorder::recovery_text(*r, 20);
    // LCM's reader gets every intact event.
    EXPECT_EQ(read_with_lcm(out), renumbered(intact)) << name;
    std::vector<Problem> none;
    EXPECT_EQ(test::read_all(out, &none).size(), intact.size());
    EXPECT_TRUE(none.empty()) << name;
    // What was left out, where, as `driftlab info` names it.
    for (const auto& p : problems) {
      EXPECT_NE(text.find("at byte " + std::to_string(p.offset) + ": " + to_string(p.kind)), std::string::npos)
          << name << "\n"
          << text;
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
  test::put_be32(lie, lcmtypes::kHeaderFrameOffset + 4 + 6 + size_t{7} * 4, -5);  // nranges -5
  {
    auto w = LogWriter::create(log);
    ASSERT_TRUE(w.ok());
    for (int i = 0; i < 10; ++i) ASSERT_TRUE(w->write(1000 + i, "SCAN", i % 3 == 1 ? lie : test::encode(scan)).ok());
    ASSERT_TRUE(w->close().ok());
  }
  auto r = recorder::recover_log(log, dir.file("clean.lcm"), {});
  ASSERT_TRUE(r) << r.error().message;
  const nlohmann::json j = to_json(*r);
  EXPECT_EQ(j["events"], 7);
  EXPECT_EQ(j["problems_total"], 0);
  EXPECT_EQ(j["malformed"]["SCAN"]["count"], 3);
  const size_t second = 28 + 4 + test::encode(scan).size();  // the first lie is the second event
  EXPECT_EQ(j["malformed"]["SCAN"]["first"], "event at byte " + std::to_string(second) + ": ranges: length -5");
  for (const auto& e : test::read_all(dir.file("clean.lcm"))) EXPECT_EQ(lcmtypes::layout_problem(e.data), std::nullopt);
  EXPECT_NE(recorder::recovery_text(*r, 20).find("left out 3 intact events whose message does not hold its type's "
                                                 "layout (--keep-malformed keeps them):\n  SCAN: 3 (first: event at"),
            std::string::npos);
  r = recorder::recover_log(log, dir.file("all.lcm"), {.keep_malformed = true});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->events, 10);
}

TEST(Recover, AnIntactLogComesOutByteForByte) {
  test::TempDir dir;
  auto r = recorder::recover_log(kData + "/sample.lcm", dir.file("copy.lcm"), {});
  ASSERT_TRUE(r);
  EXPECT_NE(recorder::recovery_text(*r, 20).find("nothing left out"), std::string::npos);
  EXPECT_EQ(test::read_file(dir.file("copy.lcm")), test::read_file(kData + "/sample.lcm"));
}

}  // namespace
}  // namespace driftlab
