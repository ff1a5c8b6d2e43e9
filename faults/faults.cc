#include "faults/faults.h"

#include <cmath>
#include <functional>
#include <utility>

#include "core/config.h"
#include "core/time.h"

namespace driftlab {
namespace {

driftlab::fault_t fault(const std::string& channel, const char* kind, int64_t start, int64_t end,
                        const std::vector<std::pair<std::string, double>>& params, std::vector<int64_t> affected = {}) {
  driftlab::fault_t f;
  f.channel = channel;
  f.kind = kind;
  f.start_utime = start;
  f.end_utime = end;
  for (auto& [name, value] : params) {
    f.param_names.push_back(name);
    f.param_values.push_back(value);
  }
  f.nparams = static_cast<int32_t>(f.param_names.size());
  f.affected_seq = std::move(affected);
  f.naffected = static_cast<int32_t>(f.affected_seq.size());
  return f;
}

}  // namespace

const config::Table<StreamFaults>& stream_faults_table() {
  using F = StreamFaults;
  static const auto t =
      config::Table<F>()
          .number("clock_offset_s", &F::clock_offset_s, config::between(-1e6, 1e6), "s",
                  "the source clock is ahead of true time by this much: header stamps move, arrivals do not")
          .number("clock_drift_ppm", &F::clock_drift_ppm, config::between(-1e5, 1e5), "ppm",
                  "the source clock runs fast by this much, from the start of the run")
          .number("latency_s", &F::latency_s, config::between(0, 1e3), "s",
                  "transport delay, fixed part: arrivals move, stamps do not")
          .number("jitter_s", &F::jitter_s, config::between(0, 1e3), "s",
                  "transport delay, random part: exponential with this mean")
          .number("drop_probability", &F::drop_probability, config::between(0, 1), "",
                  "each message lost independently with this probability; its seq goes missing")
          .number("burst_enter", &F::burst_enter, config::between(0, 1), "",
                  "burst loss (Gilbert-Elliott): probability, per message, of entering a burst (with burst_exit)")
          .number("burst_exit", &F::burst_exit, config::between(0, 1), "",
                  "... and of leaving it; every message in a burst is lost")
          .number("duplicate_probability", &F::duplicate_probability, config::between(0, 1), "",
                  "each message delivered twice (same seq and stamp) with this probability")
          .number("reorder_probability", &F::reorder_probability, config::between(0, 1), "",
                  "each message held back by reorder_delay_s with this probability, so later ones overtake it")
          .number("reorder_delay_s", &F::reorder_delay_s, config::between(0, 1e3), "s",
                  "how long a reordered message is held back")
          .check([](const config::Value& v, F& f) -> Status {
            if ((f.burst_enter > 0) != (f.burst_exit > 0)) return v.error("needs both burst_enter and burst_exit");
            return {};
          });
  return t;
}

const config::Table<FaultConfig>& fault_config_table() {
  static const auto t =
      config::Table<FaultConfig>()
          .integer("seed", &FaultConfig::seed, config::at_least(0), "",
                   "random seed of the injected faults; in the simulator, 0 or none means the scenario's")
          .map("streams", &FaultConfig::streams, "CHANNEL", stream_faults_table(), "the faults of each channel");
  return t;
}

Result<FaultConfig> parse_faults(const std::string& text, const std::string& origin) {
  auto root = config::parse_yaml(text, origin);
  if (!root) return root.error();
  return fault_config_table().parse(config::Value(*root, origin));
}

Result<FaultConfig> load_faults(const std::string& path) {
  auto root = config::load_yaml(path, "fault description");
  if (!root) return root.error();
  return fault_config_table().parse(config::Value(*root, path));
}

StreamFaultInjector::StreamFaultInjector(std::string channel, StreamFaults faults, uint64_t seed, int64_t start_utime)
    : channel_(std::move(channel)),
      f_(faults),
      start_utime_(start_utime),
      // One generator per stream, seeded from the run's seed and the channel, so streams are independent and
      // adding a stream does not change the others.
      rng_(seed ^ std::hash<std::string>{}(channel_)) {}

int64_t StreamFaultInjector::source_clock(int64_t true_utime) const {
  const double elapsed = static_cast<double>(true_utime - start_utime_);
  return true_utime + static_cast<int64_t>(std::llround(f_.clock_offset_s * 1e6 + elapsed * f_.clock_drift_ppm * 1e-6));
}

void StreamFaultInjector::apply(int64_t seq, int64_t true_utime, std::vector<Delivery>& out) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // Draw every random number every time, so one fault's setting does not shift another's sequence.
  const double u_burst = uniform(rng_), u_drop = uniform(rng_), u_dup = uniform(rng_), u_reorder = uniform(rng_);
  const double jitter = f_.jitter_s > 0 ? std::exponential_distribution<double>(1.0 / f_.jitter_s)(rng_) : 0.0;
  const double jitter2 = f_.jitter_s > 0 ? std::exponential_distribution<double>(1.0 / f_.jitter_s)(rng_) : 0.0;
  if (f_.burst_enter > 0) in_burst_ = in_burst_ ? u_burst >= f_.burst_exit : u_burst < f_.burst_enter;
  if (in_burst_) {
    burst_dropped_.push_back(seq);
    return;
  }
  if (u_drop < f_.drop_probability) {
    dropped_.push_back(seq);
    return;
  }
  const int64_t stamp = source_clock(true_utime);
  double delay = f_.latency_s + jitter;
  if (u_reorder < f_.reorder_probability) {
    delay += f_.reorder_delay_s;
    reordered_.push_back(seq);
  }
  out.push_back({stamp, true_utime + Duration::from_seconds_rounded(delay).us()});
  if (u_dup < f_.duplicate_probability) {
    duplicated_.push_back(seq);
    out.push_back({stamp, true_utime + Duration::from_seconds_rounded(delay + jitter2).us() + 1});
  }
}

std::vector<driftlab::fault_t> StreamFaultInjector::manifest(int64_t end_utime) const {
  std::vector<driftlab::fault_t> out;
  const int64_t s = start_utime_, e = end_utime;
  if (f_.clock_offset_s != 0) out.push_back(fault(channel_, "clock_offset", s, e, {{"offset_s", f_.clock_offset_s}}));
  if (f_.clock_drift_ppm != 0) out.push_back(fault(channel_, "clock_drift", s, e, {{"drift_ppm", f_.clock_drift_ppm}}));
  if (f_.latency_s != 0) out.push_back(fault(channel_, "latency", s, e, {{"latency_s", f_.latency_s}}));
  if (f_.jitter_s != 0) out.push_back(fault(channel_, "jitter", s, e, {{"mean_s", f_.jitter_s}}));
  if (f_.drop_probability != 0) {
    out.push_back(fault(channel_, "drop", s, e, {{"probability", f_.drop_probability}}, dropped_));
  }
  if (f_.burst_enter != 0) {
    out.push_back(fault(channel_, "burst_drop", s, e,
                        {{"enter_probability", f_.burst_enter}, {"exit_probability", f_.burst_exit}}, burst_dropped_));
  }
  if (f_.duplicate_probability != 0) {
    out.push_back(fault(channel_, "duplicate", s, e, {{"probability", f_.duplicate_probability}}, duplicated_));
  }
  if (f_.reorder_probability != 0) {
    out.push_back(fault(channel_, "reorder", s, e,
                        {{"probability", f_.reorder_probability}, {"delay_s", f_.reorder_delay_s}}, reordered_));
  }
  return out;
}

}  // namespace driftlab
