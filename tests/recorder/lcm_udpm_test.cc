// Tests for recorder/lcm_udpm.h: LCM URLs, and reassembly with loss accounting, from crafted datagrams.
#include "recorder/lcm_udpm.h"

#include <gtest/gtest.h>

#include "core/log_format.h"

namespace driftlab::recorder {
namespace {

std::vector<uint8_t> short_packet(uint32_t seqno, const std::string& channel, const std::string& data) {
  std::vector<uint8_t> p(8);
  logfmt::store_be32(p.data(), 0x4c433032);
  logfmt::store_be32(p.data() + 4, seqno);
  p.insert(p.end(), channel.begin(), channel.end());
  p.push_back(0);
  p.insert(p.end(), data.begin(), data.end());
  return p;
}

std::vector<uint8_t> fragment(uint32_t seqno, uint32_t size, uint32_t offset, uint16_t number, uint16_t count,
                              const std::string& channel, const std::string& data) {
  std::vector<uint8_t> p(20);
  logfmt::store_be32(p.data(), 0x4c433033);
  logfmt::store_be32(p.data() + 4, seqno);
  logfmt::store_be32(p.data() + 8, size);
  logfmt::store_be32(p.data() + 12, offset);
  p[16] = static_cast<uint8_t>(number >> 8);
  p[17] = static_cast<uint8_t>(number);
  p[18] = static_cast<uint8_t>(count >> 8);
  p[19] = static_cast<uint8_t>(count);
  if (number == 0) {
    p.insert(p.end(), channel.begin(), channel.end());
    p.push_back(0);
  }
  p.insert(p.end(), data.begin(), data.end());
  return p;
}

std::string text(std::span<const uint8_t> d) { return {d.begin(), d.end()}; }

TEST(ParseUdpmUrl, ReadsGroupPortAndOptions) {
  auto u = parse_udpm_url("udpm://239.1.2.3:7000?ttl=1&recv_buf_size=1000");
  ASSERT_TRUE(u.ok());
  EXPECT_EQ(u->group, "239.1.2.3");
  EXPECT_EQ(u->port, 7000);
  EXPECT_EQ(u->ttl, 1);
  EXPECT_EQ(u->recv_buf_size, 1000);
  auto d = parse_udpm_url("udpm://");
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->group, "239.255.76.67");
  EXPECT_EQ(d->port, 7667);
  EXPECT_FALSE(parse_udpm_url("tcpq://localhost").ok());
  EXPECT_FALSE(parse_udpm_url("udpm://10.0.0.1:7667").ok());  // not multicast
  EXPECT_FALSE(parse_udpm_url("udpm://239.1.2.3:x").ok());
  EXPECT_FALSE(parse_udpm_url("udpm://239.1.2.3:7667?bogus=1").ok());
}

TEST(LcmReassembler, DeliversShortMessagesAndCountsSequenceGaps) {
  LcmReassembler r;
  for (uint32_t seq : {0u, 1u, 2u, 5u, 6u}) {
    const auto packet = short_packet(seq, "CH", "x" + std::to_string(seq));
    auto m = r.feed(1, packet, 100 + seq);
    ASSERT_TRUE(m.has_value());
    EXPECT_EQ(m->channel, "CH");
    EXPECT_EQ(text(m->data), "x" + std::to_string(seq));
    EXPECT_EQ(m->utime, 100 + seq);
  }
  const SenderCounters& c = r.senders().at(1);
  EXPECT_EQ(c.messages, 5);
  EXPECT_EQ(c.lost, 2);
  EXPECT_EQ(c.gaps, 1);
  // A late packet is counted, not taken as a huge gap; senders are independent.
  ASSERT_TRUE(r.feed(1, short_packet(4, "CH", ""), 0).has_value());
  EXPECT_EQ(r.senders().at(1).out_of_order, 1);
  EXPECT_EQ(r.senders().at(1).lost, 2);
  ASSERT_TRUE(r.feed(2, short_packet(1000, "CH", ""), 0).has_value());
  EXPECT_EQ(r.senders().at(2).lost, 0);
}

TEST(LcmReassembler, SequenceNumbersWrapAround) {
  LcmReassembler r;
  for (uint32_t seq : {0xfffffffeu, 0xffffffffu, 0u, 2u}) ASSERT_TRUE(r.feed(1, short_packet(seq, "C", ""), 0));
  EXPECT_EQ(r.senders().at(1).lost, 1);
  EXPECT_EQ(r.senders().at(1).gaps, 1);
}

TEST(LcmReassembler, ReassemblesFragmentsInAnyOrderOnce) {
  LcmReassembler r;
  EXPECT_FALSE(r.feed(1, fragment(7, 9, 6, 2, 3, "", "ghi"), 50));
  EXPECT_FALSE(r.feed(1, fragment(7, 9, 6, 2, 3, "", "ghi"), 51));  // a duplicate is ignored
  EXPECT_FALSE(r.feed(1, fragment(7, 9, 0, 0, 3, "BIG", "abc"), 52));
  auto m = r.feed(1, fragment(7, 9, 3, 1, 3, "", "def"), 53);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->channel, "BIG");
  EXPECT_EQ(text(m->data), "abcdefghi");
  EXPECT_EQ(m->utime, 50);  // when its first datagram arrived
  EXPECT_EQ(r.senders().at(1).messages, 1);
}

TEST(LcmReassembler, AcceptsAnEmptyFragment) {
  LcmReassembler r;
  EXPECT_FALSE(r.feed(1, fragment(3, 3, 0, 0, 2, "C", "abc"), 0));
  auto m = r.feed(1, fragment(3, 3, 3, 1, 2, "", ""), 0);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(text(m->data), "abc");
}

TEST(LcmReassembler, CountsIncompleteFragmentedMessagesAndGarbage) {
  LcmReassembler r;
  ASSERT_TRUE(r.feed(1, short_packet(0, "C", ""), 0));
  EXPECT_FALSE(r.feed(1, fragment(1, 6, 0, 0, 2, "BIG", "abc"), 0));  // fragment 1 never comes
  ASSERT_TRUE(r.feed(1, short_packet(2, "C", ""), 0));                 // so message 1 is lost
  EXPECT_FALSE(r.feed(1, fragment(3, 6, 0, 0, 2, "BIG", "abc"), 0));
  EXPECT_FALSE(r.feed(1, fragment(4, 6, 0, 0, 2, "BIG", "abc"), 0));  // and so is 3
  EXPECT_EQ(r.senders().at(1).fragments_incomplete, 2);
  EXPECT_EQ(r.senders().at(1).lost, 0);
  const std::vector<uint8_t> junk = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  EXPECT_FALSE(r.feed(1, junk, 0));
  EXPECT_FALSE(r.feed(1, short_packet(9, "", "no channel"), 0));
  EXPECT_FALSE(r.feed(1, fragment(9, 4, 2, 0, 1, "C", "too long"), 0));  // past the message size
  EXPECT_EQ(r.garbage(), 3);
}

}  // namespace
}  // namespace driftlab::recorder
