#include "tests/fakes/fake_bus.h"

#include <regex>

#include "core/log_reader.h"

namespace driftlab::test {
namespace {

/// A borrowed module, for a host that owns its modules.
class Borrowed final : public Module {
 public:
  explicit Borrowed(Module& m) : m_(m) {}
  std::string name() const override { return m_.name(); }
  Status start(Bus& bus) override { return m_.start(bus); }
  void finish(Bus& bus) override { m_.finish(bus); }
  ModuleCounters counters() const override { return m_.counters(); }

 private:
  Module& m_;
};

constexpr const char* kStatsChannel = "MODULE_STATS";

}  // namespace

Status MemoryLog::write(int64_t utime, std::string_view channel, std::span<const uint8_t> data) {
  into_.push_back({static_cast<int64_t>(into_.size()), utime, std::string(channel), {data.begin(), data.end()}, 0});
  return {};
}

FakeBus::FakeBus(const Options& options)
    : host_(std::make_unique<runtime::ModuleHost>(runtime::HostOptions{
          .clock = runtime::HostClock::kVirtual,
          .loopback = true,
          .out = options.artifact_prefix.empty() ? "" : options.artifact_prefix + ".lcm",  // the prefix; no file
          .timing = false,
          .stats_period_s = options.stats_period_s,
          .stats_channel = kStatsChannel})) {}
FakeBus::~FakeBus() = default;

void FakeBus::add(Module& module) { host_->add_module(std::make_unique<Borrowed>(module)); }

Status FakeBus::start() { return host_->start(std::make_unique<MemoryLog>(recorded_)); }

Status FakeBus::advance(Time t) { return host_->advance(t); }

Status FakeBus::deliver(const std::string& channel, std::span<const uint8_t> data, Time t) {
  if (Status s = host_->advance(t); !s) return s;
  return host_->deliver(channel, data);
}

Status FakeBus::play(const std::string& log, const std::string& channels, const Rewrite& rewrite) {
  auto reader = LogReader::open(log, {.channels = channels});
  if (!reader) return reader.error();
  Event e;
  std::vector<uint8_t> rewritten;
  while (reader->next(e)) {
    const std::string channel(e.channel);
    std::span<const uint8_t> data = e.data;
    if (rewrite) {
      rewritten.assign(e.data.begin(), e.data.end());
      rewrite(channel, rewritten);
      data = rewritten;
    }
    if (Status s = deliver(channel, data, Time::from_us(e.utime)); !s) return s;
  }
  return {};
}

Status FakeBus::finish() {
  if (Status s = host_->finish(); !s) return s;
  return host_->close();
}

Status FakeBus::run(const std::string& log, const std::string& channels, const Rewrite& rewrite) {
  if (Status s = start(); !s) return s;
  if (Status s = play(log, channels, rewrite); !s) return s;
  return finish();
}

std::vector<OwnedEvent> FakeBus::published(const std::string& channel_regex) const {
  const std::regex re(channel_regex);
  std::vector<OwnedEvent> out;
  for (const auto& e : recorded_) {
    if (e.channel != kStatsChannel && std::regex_match(e.channel, re)) out.push_back(e);
  }
  return out;
}

}  // namespace driftlab::test
