// Tests for faults/faults.h: the YAML fault description and its errors, and the injector's effects and manifest.
#include "faults/faults.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>

namespace driftlab {
namespace {

TEST(ParseFaults, ReadsStreamsAndSeed) {
  auto c = parse_faults(R"(seed: 7
streams:
  IMU:
    clock_offset_s: 0.015
    jitter_s: 0.001
  SCAN: {drop_probability: 0.02, burst_enter: 0.01, burst_exit: 0.3}
)",
                        "faults.yaml");
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_EQ(c->seed, 7u);
  EXPECT_EQ(c->streams.at("IMU").clock_offset_s, 0.015);
  EXPECT_EQ(c->streams.at("IMU").jitter_s, 0.001);
  EXPECT_EQ(c->streams.at("SCAN").burst_exit, 0.3);
  EXPECT_TRUE(parse_faults("", "empty.yaml").ok());
}

TEST(ParseFaults, ErrorsNameTheFileLineAndKey) {
  const std::pair<const char*, const char*> cases[] = {
      {"streams:\n  IMU:\n    clock_ofset_s: 1\n",
       "faults.yaml:3: unknown key 'streams.IMU.clock_ofset_s': did you mean 'clock_offset_s'? (known: clock_offset_s, "
       "clock_drift_ppm, "},
      {"streams:\n  IMU:\n    drop_probability: 1.5\n",
       "faults.yaml:3: streams.IMU.drop_probability = 1.5 is outside 0..1"},
      {"streams:\n  IMU:\n    jitter_s: fast\n", "faults.yaml:3: streams.IMU.jitter_s = fast must be a number"},
      {"streams:\n  IMU:\n    latency_s: 1e309\n",
       "faults.yaml:3: streams.IMU.latency_s = 1e309 is too large for a number"},
      {"streams:\n  IMU:\n    burst_enter: 0.1\n", "faults.yaml:3: streams.IMU needs both burst_enter and burst_exit"},
      {"seed: 1\nstreem: {}\n", "faults.yaml:2: unknown key 'streem'"},
      {"streams: [1, 2\n", "faults.yaml:"},
      {"streams:\n  IMU: 3\n", "faults.yaml:2: streams.IMU must be a map of key: value"},
      {"seed: -3\n", "faults.yaml:1: seed = -3 must be >= 0"},
  };
  for (const auto& [text, expected] : cases) {
    auto c = parse_faults(text, "faults.yaml");
    ASSERT_FALSE(c.ok()) << text;
    EXPECT_EQ(c.error().message.rfind(expected, 0), 0u) << c.error().message;
  }
  auto missing = load_faults("/nonexistent/faults.yaml");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("/nonexistent/faults.yaml"), std::string::npos);
}

constexpr int64_t kStart = 1'000'000'000;

TEST(StreamFaultInjector, OffsetsAndDriftsTheSourceClockExactly) {
  StreamFaults f;
  f.clock_offset_s = 0.015;
  f.clock_drift_ppm = 100;
  f.latency_s = 0.002;
  StreamFaultInjector inj("IMU", f, 1, kStart);
  std::vector<Delivery> out;
  inj.apply(0, kStart + 10'000'000, out);  // 10 s in: 15 ms + 1 ms of drift
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].stamp_utime, kStart + 10'000'000 + 16'000);
  EXPECT_EQ(out[0].arrival_utime, kStart + 10'000'000 + 2'000);
  const auto m = inj.manifest(kStart + 20'000'000);
  ASSERT_EQ(m.size(), 3u);
  EXPECT_EQ(m[0].kind, "clock_offset");
  EXPECT_EQ(m[0].param_values[0], 0.015);
  EXPECT_EQ(m[1].kind, "clock_drift");
  EXPECT_EQ(m[2].kind, "latency");
}

TEST(StreamFaultInjector, DropsDuplicatesAndReordersAsTheManifestSays) {
  StreamFaults f;
  f.drop_probability = 0.1;
  f.burst_enter = 0.01;
  f.burst_exit = 0.25;
  f.duplicate_probability = 0.05;
  f.reorder_probability = 0.02;
  f.jitter_s = 0.001;
  StreamFaultInjector inj("SCAN", f, 42, kStart);
  std::multiset<int64_t> delivered;
  const int n = 20000;
  for (int64_t seq = 0; seq < n; ++seq) {
    std::vector<Delivery> out;
    inj.apply(seq, kStart + seq * 100'000, out);
    for (size_t i = 0; i < out.size(); ++i) delivered.insert(seq);
    for (const auto& d : out) EXPECT_GE(d.arrival_utime, kStart + seq * 100'000);
  }
  std::map<std::string, std::vector<int64_t>> affected;
  for (const auto& fault : inj.manifest(kStart + static_cast<int64_t>(n) * 100'000))
    affected[fault.kind] = fault.affected_seq;
  const auto& dropped = affected["drop"];
  const auto& burst = affected["burst_drop"];
  const auto& duplicated = affected["duplicate"];
  EXPECT_NEAR(static_cast<double>(dropped.size()) / n, 0.1 * (1 - static_cast<double>(burst.size()) / n), 0.01);
  // Bursts: 1% of messages start one, each lasting 1 / 0.25 = 4 messages on average.
  EXPECT_NEAR(static_cast<double>(burst.size()) / n, 0.01 * 4 / (1 + 0.01 * 4), 0.01);
  EXPECT_FALSE(affected["reorder"].empty());
  for (int64_t seq = 0; seq < n; ++seq) {
    const bool lost =
        std::binary_search(dropped.begin(), dropped.end(), seq) || std::binary_search(burst.begin(), burst.end(), seq);
    const bool twice = std::binary_search(duplicated.begin(), duplicated.end(), seq);
    ASSERT_EQ(delivered.count(seq), lost ? 0u : (twice ? 2u : 1u)) << seq;
  }
}

TEST(StreamFaultInjector, IsDeterministicPerSeedAndChannel) {
  StreamFaults f;
  f.drop_probability = 0.3;
  f.jitter_s = 0.01;
  auto run = [&](const std::string& channel, uint64_t seed) {
    StreamFaultInjector inj(channel, f, seed, kStart);
    std::vector<Delivery> out;
    for (int64_t seq = 0; seq < 1000; ++seq) inj.apply(seq, kStart + seq * 1000, out);
    std::vector<int64_t> arrivals;
    arrivals.reserve(out.size());
    for (const auto& d : out) arrivals.push_back(d.arrival_utime);
    return arrivals;
  };
  EXPECT_EQ(run("A", 1), run("A", 1));
  EXPECT_NE(run("A", 1), run("A", 2));
  EXPECT_NE(run("A", 1), run("B", 1));
}

}  // namespace
}  // namespace driftlab
