// ModuleHost (runtime/module_host.h), the one host of replay, live and module tests: the two clocks (every tick
// on the virtual one, a late timer once on the wall one, now() the tick time in both), time never going back,
// outputs looped back in publication order or handed to the outlet, malformed inputs and modules that throw
// (in a handler or a timer) counted and skipped, statistics every period, the artifact prefix, the atomic output
// log, starting in two steps; and the fake bus module tests use (tests/fakes/fake_bus.h).
#include "runtime/module_host.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <limits>
#include <stdexcept>

#include "driftlab/imu_t.hpp"
#include "driftlab/module_stats_t.hpp"
#include "tests/fakes/fake_bus.h"
#include "tests/test_util.h"

namespace driftlab::runtime {
namespace {

constexpr int64_t kT0 = 1763776800000000;  // a whole second

std::vector<uint8_t> imu(int64_t seq, int64_t stamp) {
  driftlab::imu_t m{};
  m.header.seq = seq;
  m.header.utime = stamp;
  m.header.frame_id = "imu";
  return test::encode(m);
}

/// A module made of lambdas: what it does in start(), and what it saw.
struct Probe : Module {
  explicit Probe(std::string n = "probe") : name_(std::move(n)) {}
  std::string name() const override { return name_; }
  Status start(Bus& bus) override {
    bus_ = &bus;
    if (on_start) on_start(bus);
    return {};
  }
  std::string name_;
  std::function<void(Bus&)> on_start;
  Bus* bus_ = nullptr;
};

std::vector<int64_t> ticks_after(HostClock clock, int64_t to) {
  ModuleHost host({.clock = clock, .stats_period_s = 0});
  auto probe = std::make_unique<Probe>();
  std::vector<int64_t> ticks;
  probe->on_start = [&ticks](Bus& bus) {
    bus.every(Duration::from_us(100000), [&ticks, &bus] { ticks.push_back(bus.now().us()); });
  };
  host.add_module(std::move(probe));
  EXPECT_TRUE(host.start());
  EXPECT_TRUE(host.advance(Time::from_us(kT0 + 50000)));  // the timer is placed: first tick at kT0 + 100 ms
  EXPECT_EQ(host.next_due(), Time::from_us(kT0 + 100000));
  EXPECT_TRUE(host.advance(Time::from_us(to)));
  EXPECT_EQ(host.now().us(), to);
  return ticks;
}

TEST(ModuleHost, VirtualClockFiresEveryTickAtItsOwnTime) {
  EXPECT_EQ(ticks_after(HostClock::kVirtual, kT0 + 420000),
            (std::vector<int64_t>{kT0 + 100000, kT0 + 200000, kT0 + 300000, kT0 + 400000}));
}

TEST(ModuleHost, WallClockFiresALateTimerOnceAtItsLatestTick) {
  // Live, a host that fell 320 ms behind runs the controller once, with now() at the latest due tick, not a burst
  // of four stale ticks.
  EXPECT_EQ(ticks_after(HostClock::kWall, kT0 + 420000), (std::vector<int64_t>{kT0 + 400000}));
}

TEST(ModuleHost, ALogTimeFarAheadSkipsTheTicksInBetweenAndSaysSo) {
  // One corrupt log time, years ahead, made replay fire every 100 ms tick up to it: 3e11 ticks at the end of
  // int64_t, where the tick arithmetic also overflowed. Past a million ticks in one jump, the timer goes to the last
  // tick before the new time, and the skip is counted; at the end of int64_t the ticks run out.
  ModuleHost host({.stats_period_s = 0});
  auto probe = std::make_unique<Probe>();
  std::vector<int64_t> ticks;
  probe->on_start = [&ticks](Bus& bus) {
    bus.every(Duration::from_us(100000), [&ticks, &bus] { ticks.push_back(bus.now().us()); });
  };
  host.add_module(std::move(probe));
  ASSERT_TRUE(host.start());
  ASSERT_TRUE(host.advance(Time::from_us(kT0)));
  const int64_t far = kT0 + int64_t{1000000} * 100000 + 250000;  // 1e6 ticks and 2.5 more: skipped
  ASSERT_TRUE(host.advance(Time::from_us(far)));
  EXPECT_EQ(ticks, (std::vector<int64_t>{kT0, far - 50000}));
  ASSERT_TRUE(host.advance(Time::from_us(std::numeric_limits<int64_t>::max())));
  ASSERT_TRUE(host.advance(Time::from_us(std::numeric_limits<int64_t>::max())));
  EXPECT_EQ(ticks.size(), 3u);
  EXPECT_EQ(ticks.back(), std::numeric_limits<int64_t>::max() / 100000 * 100000);
  const auto report = host.reports().front();
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_EQ(report.warnings[0].rfind("92216082600545 timer ticks skipped", 0), 0u)
      << report.warnings[0];  // 1000001 + the rest
  EXPECT_NE(report.warnings[0].find(" timer ticks skipped where the time jumped ahead (first: " +
                                    std::to_string(kT0 + 100000) + " to " + std::to_string(far - 50000) + " us)"),
            std::string::npos)
      << report.warnings[0];
}

TEST(ModuleHost, TimeNeverGoesBack) {
  ModuleHost host({.stats_period_s = 0});
  auto probe = std::make_unique<Probe>();
  std::vector<std::pair<int64_t, int64_t>> seen;  // message time, now()
  probe->on_start = [&seen](Bus& bus) {
    bus.subscribe("IMU", [&seen, &bus](const BusMessage& m) { seen.emplace_back(m.time.us(), bus.now().us()); });
  };
  host.add_module(std::move(probe));
  ASSERT_TRUE(host.start());
  ASSERT_TRUE(host.advance(Time::from_us(kT0 + 2000)));
  ASSERT_TRUE(host.deliver("IMU", imu(0, kT0 + 2000)));
  ASSERT_TRUE(host.advance(Time::from_us(kT0 + 1000)));  // an input stamped earlier by its receiver is handled now
  ASSERT_TRUE(host.deliver("IMU", imu(1, kT0 + 1000)));
  EXPECT_EQ(seen, (std::vector<std::pair<int64_t, int64_t>>{{kT0 + 2000, kT0 + 2000}, {kT0 + 2000, kT0 + 2000}}));
}

TEST(ModuleHost, LoopbackDeliversOutputsInPublicationOrderAtTheSameInstant) {
  test::FakeBus bus;
  Probe relay("relay"), sink("sink");
  relay.on_start = [](Bus& b) {
    b.subscribe("IN", [&b](const BusMessage& m) {
      b.publish("FIRST", m.data);
      b.publish("SECOND", m.data);
    });
  };
  std::vector<std::pair<std::string, int64_t>> seen;
  sink.on_start = [&seen](Bus& b) {
    b.subscribe("FIRST|SECOND", [&seen, &b](const BusMessage& m) { seen.emplace_back(m.channel, b.now().us()); });
  };
  bus.add(relay);
  bus.add(sink);
  ASSERT_TRUE(bus.start());
  ASSERT_TRUE(bus.deliver("IN", imu(0, kT0), Time::from_us(kT0)));
  ASSERT_TRUE(bus.deliver("IN", imu(1, kT0 + 10), Time::from_us(kT0 + 10)));
  ASSERT_TRUE(bus.finish());
  EXPECT_EQ(seen, (std::vector<std::pair<std::string, int64_t>>{
                      {"FIRST", kT0}, {"SECOND", kT0}, {"FIRST", kT0 + 10}, {"SECOND", kT0 + 10}}));
  const auto out = bus.published();
  ASSERT_EQ(out.size(), 4u);
  EXPECT_EQ(out[1].channel, "SECOND");
  EXPECT_EQ(out[1].utime, kT0);
  EXPECT_EQ(bus.recorded().back().channel, "MODULE_STATS");  // the last statistics, at finish
}

TEST(ModuleHost, WithoutLoopbackOutputsGoToTheOutletOnly) {
  // Live: LCM brings what a module publishes back as input; the host must not deliver it twice.
  ModuleHost host({.clock = HostClock::kWall, .loopback = false, .stats_period_s = 0});
  auto relay = std::make_unique<Probe>();
  int handled = 0;
  relay->on_start = [&handled](Bus& b) {
    b.subscribe(".*", [&handled, &b](const BusMessage& m) {
      ++handled;
      if (m.channel == "IN") b.publish("OUT", m.data);
    });
  };
  host.add_module(std::move(relay));
  std::vector<std::string> outlet;
  host.set_outlet([&outlet](const BusMessage& m) { outlet.emplace_back(m.channel); });
  ASSERT_TRUE(host.start());
  ASSERT_TRUE(host.advance(Time::from_us(kT0)));
  ASSERT_TRUE(host.deliver("IN", imu(0, kT0)));
  EXPECT_EQ(handled, 1);
  EXPECT_EQ(outlet, std::vector<std::string>{"OUT"});
  EXPECT_EQ(host.outputs(), 1);
}

TEST(ModuleHost, MalformedInputsAndModulesThatThrowAreCountedAndSkipped) {
  test::FakeBus bus;
  Probe fragile("fragile"), steady("steady");
  int fragile_handled = 0, steady_handled = 0, ticks = 0;
  fragile.on_start = [&](Bus& b) {
    b.subscribe("IMU", [&](const BusMessage&) {
      if (++fragile_handled == 2) throw std::runtime_error("cannot take this one");
    });
    b.every(Duration::from_us(1000000), [&] {
      if (++ticks == 1) throw std::runtime_error("timer trouble");
    });
  };
  steady.on_start = [&](Bus& b) { b.subscribe("IMU", [&](const BusMessage&) { ++steady_handled; }); };
  bus.add(fragile);
  bus.add(steady);
  ASSERT_TRUE(bus.start());
  std::vector<uint8_t> bad = imu(9, kT0);
  test::put_be32(bad, 8 + 8 + 8, 1 << 30);  // the frame_id's length: far past the end
  for (int64_t i = 0; i < 4; ++i)
    ASSERT_TRUE(bus.deliver("IMU", i == 1 ? bad : imu(i, kT0 + i * 700000), Time::from_us(kT0 + i * 700000)));
  ASSERT_TRUE(bus.finish());
  EXPECT_EQ(fragile_handled, 3);  // the malformed one reached no handler
  EXPECT_EQ(steady_handled, 3);
  EXPECT_EQ(ticks, 3);  // at kT0 (threw), kT0 + 1 s and kT0 + 2 s: the run went on
  const auto reports = bus.reports();
  ASSERT_EQ(reports.size(), 2u);
  EXPECT_EQ(reports[0].inputs, 3);
  EXPECT_EQ(reports[0].dropped, 3);  // one malformed, one message and one tick thrown on
  ASSERT_EQ(reports[0].warnings.size(), 2u);
  EXPECT_EQ(reports[0].warnings[0].rfind("1 malformed messages dropped before delivery (first: IMU: ", 0), 0u)
      << reports[0].warnings[0];
  EXPECT_EQ(reports[0].warnings[1], "2 messages the module failed on and skipped (first: a timer: timer trouble)");
  EXPECT_EQ(reports[1].dropped, 1);
}

TEST(ModuleHost, StatisticsEveryPeriodOfHostTime) {
  test::FakeBus bus({.stats_period_s = 1.0});
  Probe probe;
  probe.on_start = [](Bus& b) { b.subscribe("IMU", [](const BusMessage&) {}); };
  bus.add(probe);
  ASSERT_TRUE(bus.start());
  for (int64_t i = 0; i <= 25; ++i) {
    ASSERT_TRUE(bus.deliver("IMU", imu(i, kT0 + i * 100000), Time::from_us(kT0 + i * 100000)));
  }
  ASSERT_TRUE(bus.finish());
  std::vector<int64_t> at;
  for (const auto& e : bus.recorded()) {
    driftlab::module_stats_t s;
    ASSERT_GE(s.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
    EXPECT_EQ(s.header.seq, static_cast<int64_t>(at.size()));
    at.push_back(e.utime);
  }
  // One period after the first input, then every period, then the last at finish.
  EXPECT_EQ(at, (std::vector<int64_t>{kT0 + 1000000, kT0 + 2000000, kT0 + 2500000}));
}

TEST(ModuleHost, OutputLogAppearsWholeOnCloseAndNamesTheArtifactPrefix) {
  test::TempDir dir;
  const std::string out = dir.file("run.lcm");
  ModuleHost host({.out = out, .stats_period_s = 0});
  auto probe = std::make_unique<Probe>();
  std::string prefix;
  probe->on_start = [&prefix](Bus& b) { prefix = b.artifact_prefix(); };
  host.add_module(std::move(probe));
  ASSERT_TRUE(host.start());
  EXPECT_EQ(prefix, dir.file("run"));
  ASSERT_TRUE(host.advance(Time::from_us(kT0)));
  ASSERT_TRUE(host.record("NOTE", imu(0, kT0), true, false));
  ASSERT_TRUE(host.finish());
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_TRUE(std::filesystem::exists(out + ".partial"));
  ASSERT_TRUE(host.close());
  const auto events = test::read_all(out);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].channel, "NOTE");
  EXPECT_EQ(events[1].channel, "MODULE_STATS");
}

TEST(ModuleHost, StartsInTwoStepsListingWhatTheModulesSubscribedBeforeTheLogAppears) {
  // The live runner subscribes on LCM to these between the steps, so a log on disk says it listens.
  test::TempDir dir;
  ModuleHost host({.out = dir.file("live.lcm")});
  auto a = std::make_unique<Probe>("a");
  a->on_start = [](Bus& b) {
    b.subscribe("IMU|ODOM", [](const BusMessage&) {});
    b.subscribe("SCAN", [](const BusMessage&) {});
  };
  auto b = std::make_unique<Probe>("b");
  b->on_start = [](Bus& bus) { bus.subscribe("SLAM_.*", [](const BusMessage&) {}); };
  host.add_module(std::move(a));
  host.add_module(std::move(b));
  ASSERT_TRUE(host.start_modules());
  EXPECT_EQ(host.subscriptions(), (std::vector<std::string>{"IMU|ODOM", "SCAN", "SLAM_.*"}));
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
  ASSERT_TRUE(host.open_log());
  EXPECT_TRUE(std::filesystem::exists(dir.file("live.lcm.partial")));
  ASSERT_TRUE(host.close());
}

TEST(ModuleHost, AModuleThatFailsToStartIsNamedAndNoLogIsCreated) {
  test::TempDir dir;
  struct Picky : Module {
    std::string name() const override { return "picky"; }
    Status start(Bus&) override { return Error{"needs a map"}; }
  };
  ModuleHost host({.out = dir.file("x.lcm")});
  host.add_module(std::make_unique<Picky>());
  const Status s = host.start();
  ASSERT_FALSE(s);
  EXPECT_EQ(s.message(), "module picky: needs a map");
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

}  // namespace
}  // namespace driftlab::runtime
