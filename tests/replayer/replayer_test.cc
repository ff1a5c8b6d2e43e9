// Replayer: merge order, channel filter and remap, start/end, module dispatch and outputs on the virtual clock,
// timers, statistics, restamp, injected faults, stamp order, determinism.
#include "replayer/replayer.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

#include "core/log_format.h"
#include "core/log_writer.h"
#include "driftlab/fault_manifest_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/module_stats_t.hpp"
#include "lcmtypes/stream_header.h"
#include "driftlab/tf_t.hpp"
#include "tests/test_util.h"

namespace driftlab::replay {
namespace {

using test::OwnedEvent;
using test::TempDir;

constexpr int64_t kT0 = 1763776800000000;

std::vector<uint8_t> imu_bytes(int64_t seq, int64_t stamp) {
  driftlab::imu_t m{};
  m.header.seq = seq;
  m.header.utime = stamp;
  m.header.frame_id = "imu";
  m.angular_velocity.z = static_cast<double>(seq);
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

int64_t stamp_of(const OwnedEvent& e) {
  driftlab::imu_t m;
  EXPECT_GE(m.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
  return m.header.utime;
}

/// A log of `n` IMU messages on `channel`, one every `period` us from `start`, stamped `lag` us before arrival.
void write_imu_log(const std::string& path, const std::string& channel, int n, int64_t start, int64_t period,
                   int64_t lag = 0) {
  auto w = LogWriter::create(path);
  ASSERT_TRUE(w) << w.error().message;
  for (int i = 0; i < n; ++i) {
    const int64_t t = start + i * period;
    ASSERT_TRUE(w->write(t, channel, imu_bytes(i, t - lag)));
  }
  ASSERT_TRUE(w->close());
}

/// A module that records what it sees and echoes every input on OUT_<channel>.
class Echo : public Module {
 public:
  explicit Echo(std::string regex = ".*", std::string name = "echo") : regex_(std::move(regex)), name_(std::move(name)) {}
  std::string name() const override { return name_; }
  Status start(Bus& bus) override {
    bus.subscribe(regex_, [this, &bus](const BusMessage& m) {
      seen.push_back({std::string(m.channel), m.time.us(), bus.now().us()});
      if (m.channel.substr(0, 4) != "OUT_") bus.publish("OUT_" + std::string(m.channel), m.data);
    });
    return {};
  }
  void finish(Bus& bus) override { finished_at = bus.now().us(); }
  struct Seen {
    std::string channel;
    int64_t utime, now;
  };
  std::vector<Seen> seen;
  int64_t finished_at = 0;

 private:
  std::string regex_, name_;
};

TEST(Replayer, MergesLogsInTimeOrderAndDispatchesOutputsAtTheSameInstant) {
  TempDir dir;
  write_imu_log(dir.file("a.lcm"), "A", 5, kT0, 10000);
  write_imu_log(dir.file("b.lcm"), "B", 5, kT0 + 5000, 10000);
  ReplayOptions o;
  o.logs = {dir.file("a.lcm"), dir.file("b.lcm")};
  o.out = dir.file("out.lcm");
  o.stats_period_s = 0;
  Replayer r(o);
  auto echo = std::make_unique<Echo>();
  Echo* e = echo.get();
  r.add_module(std::move(echo));
  auto report = r.run();
  ASSERT_TRUE(report) << report.error().message;
  EXPECT_EQ(report->read, 10);
  EXPECT_EQ(report->dispatched, 10);
  EXPECT_EQ(report->outputs, 10);
  // The module sees A and B interleaved by time, then each of its outputs right after the input that caused it.
  ASSERT_EQ(e->seen.size(), 20u);
  for (size_t i = 0; i < 10; ++i) {
    const auto& in = e->seen[2 * i];
    const auto& out = e->seen[2 * i + 1];
    EXPECT_EQ(in.channel, i % 2 == 0 ? "A" : "B");
    EXPECT_EQ(in.utime, kT0 + static_cast<int64_t>(i) * 5000);
    EXPECT_EQ(in.now, in.utime);
    EXPECT_EQ(out.channel, "OUT_" + in.channel);
    EXPECT_EQ(out.utime, in.utime);
  }
  EXPECT_EQ(e->finished_at, kT0 + 9 * 5000);
  const auto events = test::read_all(dir.file("out.lcm"));
  ASSERT_EQ(events.size(), 20u + 1u);  // inputs, outputs, one final statistics message
  for (size_t i = 1; i < events.size(); ++i) EXPECT_LE(events[i - 1].utime, events[i].utime);
  EXPECT_EQ(events.back().channel, "MODULE_STATS");
  driftlab::module_stats_t stats;
  ASSERT_GE(stats.decode(events.back().data.data(), 0, static_cast<int>(events.back().data.size())), 0);
  EXPECT_EQ(stats.module, "echo");
  EXPECT_EQ(stats.inputs, 20);
  EXPECT_EQ(stats.proc_time_mean_s, 0.0);  // not measured without timing: the log stays reproducible
}

TEST(Replayer, FiltersRemapsAndCutsByStartAndEnd) {
  TempDir dir;
  write_imu_log(dir.file("a.lcm"), "IMU", 100, kT0, 10000);  // 0 .. 0.99 s
  write_imu_log(dir.file("b.lcm"), "OTHER", 100, kT0, 10000);
  ReplayOptions o;
  o.logs = {dir.file("a.lcm"), dir.file("b.lcm")};
  o.channels = "IMU";
  o.remap = {{"IMU", "IMU2"}};
  o.start_s = 0.2;
  o.end_s = 0.5;
  o.stats_period_s = 0;
  Replayer r(o);
  auto echo = std::make_unique<Echo>("IMU2");
  Echo* e = echo.get();
  r.add_module(std::move(echo));
  auto report = r.run();
  ASSERT_TRUE(report) << report.error().message;
  ASSERT_EQ(e->seen.size(), 31u);  // 0.20 .. 0.50 s inclusive, IMU only, delivered as IMU2
  EXPECT_EQ(e->seen.front().utime, kT0 + 200000);
  EXPECT_EQ(e->seen.back().utime, kT0 + 500000);
  for (const auto& s : e->seen) EXPECT_EQ(s.channel, "IMU2");
  EXPECT_EQ(report->channels.at("IMU2"), 31);
  EXPECT_EQ(report->channels.count("OTHER"), 0u);
}

TEST(Replayer, RemapItemsAndCorrectionsForAbsentChannelsAreRefused) {
  auto remap = parse_remap("IMU=IMU2");
  ASSERT_TRUE(remap);
  EXPECT_EQ(*remap, (std::pair<std::string, std::string>{"IMU", "IMU2"}));
  for (const char* bad : {"IMU", "=IMU2", "IMU="}) {
    auto r = parse_remap(bad);
    ASSERT_FALSE(r) << bad;
    EXPECT_EQ(r.error().message, std::string("--remap ") + bad + ": expected FROM=TO (channel names)");
  }
  TempDir dir;
  write_imu_log(dir.file("a.lcm"), "IMU", 10, kT0, 10000);
  write_imu_log(dir.file("b.lcm"), "ODOM", 10, kT0, 10000);
  const std::vector<std::string> logs = {dir.file("a.lcm"), dir.file("b.lcm")};
  EXPECT_TRUE(refuse_absent_channels("--restamp fix.yaml", {"IMU", "ODOM"}, logs));
  EXPECT_TRUE(refuse_absent_channels("--restamp fix.yaml", {}, logs));
  // A misspelt channel would change nothing: refused, with the channels the logs have.
  const Status s = refuse_absent_channels("--inject faults.yaml", {"IMU", "IMMU"}, logs);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.message(), "--inject faults.yaml: no channel 'IMMU' in the logs given (they have: IMU, ODOM)");
}

TEST(Replayer, TimersTickAtMultiplesOfTheirPeriodBeforeLaterMessages) {
  TempDir dir;
  write_imu_log(dir.file("a.lcm"), "IMU", 10, kT0 + 3000, 7000);  // 3 ms .. 66 ms
  struct Ticker : Module {
    std::string name() const override { return "ticker"; }
    Status start(Bus& bus) override {
      bus.every(Duration::from_us(20000), [this, &bus] { ticks.push_back(bus.now().us()); });
      return {};
    }
    std::vector<int64_t> ticks;
  };
  ReplayOptions o;
  o.logs = {dir.file("a.lcm")};
  Replayer r(o);
  auto t = std::make_unique<Ticker>();
  Ticker* ticker = t.get();
  r.add_module(std::move(t));
  ASSERT_TRUE(r.run());
  EXPECT_EQ(ticker->ticks, (std::vector<int64_t>{kT0 + 20000, kT0 + 40000, kT0 + 60000}));
}

TEST(Replayer, RestampCorrectsHeaderStampsWithOffsetAndDrift) {
  TempDir dir;
  // Stamps 15 ms ahead of arrival, plus 100 ppm of drift.
  {
    auto w = LogWriter::create(dir.file("a.lcm"));
    ASSERT_TRUE(w);
    for (int i = 0; i < 100; ++i) {
      const int64_t t = kT0 + i * 100000;
      const int64_t stamp = t + 15000 + (t - kT0) / 10000;
      ASSERT_TRUE(w->write(t, "IMU", imu_bytes(i, stamp)));
    }
    ASSERT_TRUE(w->close());
  }
  std::ofstream(dir.file("restamp.yaml")) << "channels:\n  IMU: {offset_s: 0.015, drift_ppm: 100}\n";
  auto restamp = load_restamp(dir.file("restamp.yaml"));
  ASSERT_TRUE(restamp) << restamp.error().message;
  ReplayOptions o;
  o.logs = {dir.file("a.lcm")};
  o.out = dir.file("out.lcm");
  o.restamp = *restamp;
  ASSERT_TRUE(Replayer(o).run());
  const auto events = test::read_all(dir.file("out.lcm"));
  ASSERT_EQ(events.size(), 100u);
  for (const auto& e : events) EXPECT_NEAR(stamp_of(e), e.utime, 2) << e.utime;
}

TEST(Replayer, RestampRewritesEveryTransformStampOfATfMessage) {
  TempDir dir;
  {
    auto w = LogWriter::create(dir.file("a.lcm"));
    ASSERT_TRUE(w);
    driftlab::tf_t tf{};
    tf.header.utime = kT0 + 5000;
    tf.transforms.resize(2);
    for (auto& t : tf.transforms) t.header.utime = kT0 + 5000, t.rotation.w = 1;
    tf.ntransforms = 2;
    std::vector<uint8_t> b(static_cast<size_t>(tf.getEncodedSize()));
    tf.encode(b.data(), 0, static_cast<int>(b.size()));
    ASSERT_TRUE(w->write(kT0, "TF", b));
    ASSERT_TRUE(w->close());
  }
  ReplayOptions o;
  o.logs = {dir.file("a.lcm")};
  o.out = dir.file("out.lcm");
  o.restamp["TF"] = {0.005, 0, 0};
  ASSERT_TRUE(Replayer(o).run());
  const auto events = test::read_all(dir.file("out.lcm"));
  ASSERT_EQ(events.size(), 1u);
  driftlab::tf_t tf;
  ASSERT_GE(tf.decode(events[0].data.data(), 0, static_cast<int>(events[0].data.size())), 0);
  EXPECT_EQ(tf.header.utime, kT0);
  for (const auto& t : tf.transforms) EXPECT_EQ(t.header.utime, kT0);
}

TEST(Replayer, InjectedFaultsDropDelayAndAreWrittenToTheManifest) {
  TempDir dir;
  write_imu_log(dir.file("a.lcm"), "IMU", 1000, kT0, 5000);
  write_imu_log(dir.file("b.lcm"), "ODOM", 200, kT0, 25000);
  auto faults = parse_faults("seed: 7\nstreams:\n  IMU: {drop_probability: 0.1, latency_s: 0.02, jitter_s: 0.01}\n",
                             "inject.yaml");
  ASSERT_TRUE(faults) << faults.error().message;
  ReplayOptions o;
  o.logs = {dir.file("a.lcm"), dir.file("b.lcm")};
  o.out = dir.file("out.lcm");
  o.inject = *faults;
  o.stats_period_s = 0;
  auto report = Replayer(o).run();
  ASSERT_TRUE(report) << report.error().message;
  const auto events = test::read_all(dir.file("out.lcm"));
  int64_t imu = 0, odom = 0, dropped = 0;
  bool manifest = false;
  for (size_t i = 0; i < events.size(); ++i) {
    const auto& e = events[i];
    if (i > 0) {
      EXPECT_LE(events[i - 1].utime, e.utime);  // delays re-sort the arrivals
    }
    if (e.channel == "IMU") {
      ++imu;
      const int64_t delay = e.utime - stamp_of(e);
      EXPECT_GE(delay, 20000);  // 20 ms of latency plus jitter
    } else if (e.channel == "ODOM") {
      ++odom;
      EXPECT_EQ(e.utime, stamp_of(e));  // untouched
    } else if (e.channel == "REPLAY_FAULTS") {
      driftlab::fault_manifest_t m;
      ASSERT_GE(m.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
      for (const auto& f : m.faults) {
        EXPECT_EQ(f.channel, "IMU");
        if (f.kind == "drop") dropped = f.naffected, manifest = true;
      }
    }
  }
  EXPECT_EQ(odom, 200);
  EXPECT_TRUE(manifest);
  EXPECT_EQ(imu + dropped, 1000);
  EXPECT_GT(dropped, 60);
  EXPECT_LT(dropped, 140);
  EXPECT_EQ(report->channels.at("IMU"), imu);
}

TEST(Replayer, StampOrderResortsWithinTheWindow) {
  TempDir dir;
  // Arrivals in order, stamps swapped pairwise: 1, 0, 3, 2, ...
  {
    auto w = LogWriter::create(dir.file("a.lcm"));
    ASSERT_TRUE(w);
    for (int i = 0; i < 20; ++i) {
      const int64_t t = kT0 + i * 10000;
      const int64_t stamp = kT0 + (i ^ 1) * 10000 - 1000;
      ASSERT_TRUE(w->write(t, "IMU", imu_bytes(i, stamp)));
    }
    ASSERT_TRUE(w->close());
  }
  for (Order order : {Order::kReceived, Order::kStamp}) {
    ReplayOptions o;
    o.logs = {dir.file("a.lcm")};
    o.order = order;
    o.reorder_window_s = 0.05;
    Replayer r(o);
    struct Stamps : Module {
      std::string name() const override { return "stamps"; }
      Status start(Bus& bus) override {
        bus.subscribe("IMU",
                      [this](const BusMessage& m) { stamps.push_back(*lcmtypes::header_stamp(m.data, m.time.us())); });
        return {};
      }
      std::vector<int64_t> stamps;
    };
    auto s = std::make_unique<Stamps>();
    Stamps* st = s.get();
    r.add_module(std::move(s));
    auto report = r.run();
    ASSERT_TRUE(report);
    ASSERT_EQ(st->stamps.size(), 20u);
    EXPECT_EQ(std::is_sorted(st->stamps.begin(), st->stamps.end()), order == Order::kStamp);
    EXPECT_EQ(report->modules[0].out_of_order, order == Order::kStamp ? 0 : 10);
  }
}

TEST(Replayer, ModuleThatFailsToStartStopsTheRunBeforeAnythingIsWritten) {
  TempDir dir;
  write_imu_log(dir.file("a.lcm"), "IMU", 10, kT0, 10000);
  struct Broken : Module {
    std::string name() const override { return "broken"; }
    Status start(Bus&) override { return Error{"needs a map"}; }
  };
  ReplayOptions o;
  o.logs = {dir.file("a.lcm")};
  o.out = dir.file("out.lcm");
  Replayer r(o);
  r.add_module(std::make_unique<Broken>());
  auto report = r.run();
  ASSERT_FALSE(report);
  EXPECT_EQ(report.error().message, "module broken: needs a map");
  EXPECT_FALSE(std::ifstream(dir.file("out.lcm")).good());
  EXPECT_FALSE(std::ifstream(dir.file("out.lcm.partial")).good());
}

TEST(Replayer, MissingLogAndBadRestampFileNameTheFile) {
  TempDir dir;
  ReplayOptions o;
  o.logs = {dir.file("nope.lcm")};
  auto report = Replayer(o).run();
  ASSERT_FALSE(report);
  EXPECT_NE(report.error().message.find("nope.lcm"), std::string::npos);
  std::ofstream(dir.file("r.yaml")) << "channels:\n  IMU: {offset: 0.015}\n";
  auto r = load_restamp(dir.file("r.yaml"));
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().message,
            dir.file("r.yaml") +
                ":2: unknown key 'channels.IMU.offset': did you mean 'offset_s'? (known: offset_s, drift_ppm, "
                "reference_utime)");
}

TEST(Replayer, TheSameInputsGiveAByteIdenticalOutputLog) {
  TempDir dir;
  write_imu_log(dir.file("a.lcm"), "IMU", 2000, kT0, 5000);
  auto faults = parse_faults("seed: 3\nstreams:\n  IMU: {drop_probability: 0.05, jitter_s: 0.01, duplicate_probability: 0.02}\n",
                             "inject.yaml");
  ASSERT_TRUE(faults);
  for (const char* name : {"one.lcm", "two.lcm"}) {
    ReplayOptions o;
    o.logs = {dir.file("a.lcm")};
    o.out = dir.file(name);
    o.inject = *faults;
    Replayer r(o);
    r.add_module(std::make_unique<Echo>("IMU"));
    ASSERT_TRUE(r.run());
  }
  EXPECT_EQ(test::read_file(dir.file("one.lcm")), test::read_file(dir.file("two.lcm")));
  EXPECT_GT(test::read_file(dir.file("one.lcm")).size(), 100000u);
}

}  // namespace
}  // namespace driftlab::replay
