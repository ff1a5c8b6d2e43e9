// Our reader and writer against LCM's own C event-log API (lcm/eventlog.h), both directions.
#include <gtest/gtest.h>
#include <lcm/eventlog.h>

#include "core/log_writer.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

TEST(LcmEventlogCompat, LogsWrittenByLcmReadBackExactly) {
  test::TempDir dir;
  const std::string path = dir.file("lcm.lcm");
  std::vector<test::OwnedEvent> written;
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "w");
  ASSERT_NE(log, nullptr);
  for (int i = 0; i < 200; ++i) {
    std::string channel = "CHANNEL_" + std::to_string(i % 5);
    auto data = test::payload(i, static_cast<size_t>(i * 37 % 5000));
    lcm_eventlog_event_t ev{};
    ev.timestamp = 1700000000000000 + i * 1234;
    ev.channellen = static_cast<int32_t>(channel.size());
    ev.datalen = static_cast<int32_t>(data.size());
    ev.channel = channel.data();
    ev.data = data.data();
    ASSERT_EQ(lcm_eventlog_write_event(log, &ev), 0);
    written.push_back({i, ev.timestamp, channel, data, 0});
  }
  lcm_eventlog_destroy(log);
  std::vector<Problem> problems;
  EXPECT_EQ(test::without_offsets(test::read_all(path, &problems)), written);
  EXPECT_TRUE(problems.empty());
}

TEST(LcmEventlogCompat, LogsWrittenByDriftlabReadWithLcm) {
  test::TempDir dir;
  const std::string path = dir.file("ours.lcm");
  {
    auto w = LogWriter::create(path);
    ASSERT_TRUE(w.ok());
    for (int i = 0; i < 200; ++i) {
      ASSERT_TRUE(w->write(5000 + i, "CH" + std::to_string(i % 3), test::payload(i, i * 911 % 300000)).ok());
    }
    ASSERT_TRUE(w->close().ok());
  }
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "r");
  ASSERT_NE(log, nullptr);
  int i = 0;
  while (lcm_eventlog_event_t* ev = lcm_eventlog_read_next_event(log)) {
    EXPECT_EQ(ev->eventnum, i);
    EXPECT_EQ(ev->timestamp, 5000 + i);
    EXPECT_EQ(std::string(ev->channel, ev->channellen), "CH" + std::to_string(i % 3));
    const auto expected = test::payload(i, i * 911 % 300000);
    EXPECT_EQ(std::vector<uint8_t>(static_cast<uint8_t*>(ev->data), static_cast<uint8_t*>(ev->data) + ev->datalen),
              expected);
    lcm_eventlog_free_event(ev);
    ++i;
  }
  lcm_eventlog_destroy(log);
  EXPECT_EQ(i, 200);
}

}  // namespace
}  // namespace driftlab
