// What the runners (replay and live) count about each module: inputs, late and out-of-order inputs by their header
// stamps, outputs, processing time and the queue it implies; and the driftlab.module_stats_t that reports it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/quantile.h"
#include "core/time.h"
#include "driftlab/module_stats_t.hpp"
#include "runtime/bus.h"
#include "runtime/module_host.h"

namespace driftlab::runtime::internal {

class ModuleTally {
 public:
  /// An input on a channel (an interned name, stable for the run) with its header stamp, if it has one [us].
  void input(const std::string* channel, std::optional<int64_t> stamp) {
    ++inputs_;
    if (!stamp) return;
    if (*stamp < latest_stamp_) ++late_;  // older than the newest the module has seen
    latest_stamp_ = std::max(latest_stamp_, *stamp);
    StampRun& run = stamp_runs_[channel];
    if (run.count++ > 0) {
      if (*stamp < run.newest) ++out_of_order_;  // older than the previous one on its channel
      if (*stamp == run.previous) ++run.repeated;
    }
    run.newest = run.count > 1 ? std::max(run.newest, *stamp) : *stamp;
    run.previous = *stamp;
  }
  void output() { ++outputs_; }
  /// An input that was not delivered: its bytes are not a well-formed message of its type (why says how).
  void malformed(const std::string& channel, const std::string& why) {
    if (malformed_++ == 0) first_malformed_ = channel + ": " + why;
  }
  /// An input whose handler threw: the module skipped it (what() says why).
  void failed(const std::string& channel, const char* what) {
    if (failed_++ == 0) first_failure_ = channel + ": " + one_line(what);  // not MRPT's call stack
  }
  /// A timer's ticks left out of a jump in time [us] (a log time far ahead): `ticks` of them, from `from` to `to`.
  void skipped(int64_t ticks, int64_t from, int64_t to) {
    if (skipped_ticks_ == 0) first_skip_ = {from, to};
    skipped_ticks_ += ticks;
  }
  /// An input that arrived at `at` [us] took `seconds` to process: the queue a module with these processing times
  /// has (inputs wait while it is busy).
  void processed(int64_t at, double seconds) {
    proc_s_.push_back(seconds);
    while (!busy_until_.empty() && busy_until_.front() <= at) busy_until_.pop_front();
    const int64_t begin = busy_until_.empty() ? at : busy_until_.back();
    busy_until_.push_back(begin + Duration::from_seconds_rounded(seconds).us());
    queue_max_ = std::max(queue_max_, static_cast<int32_t>(busy_until_.size()));
  }
  /// An input handled without measuring its time (a queue of one).
  void unmeasured() { queue_max_ = std::max(queue_max_, int32_t{1}); }

  ModuleReport report(const Module& module) const {
    ModuleReport r;
    r.name = module.name();
    r.inputs = inputs_;
    r.late = late_;
    r.out_of_order = out_of_order_;
    const ModuleCounters counters = module.counters();
    r.dropped = counters.dropped + malformed_ + failed_;
    r.warnings = counters.warnings;
    r.metrics = counters.metrics;
    if (malformed_ > 0) {
      r.warnings.push_back(std::to_string(malformed_) +
                           " malformed messages dropped before delivery (first: " + first_malformed_ + ")");
    }
    if (failed_ > 0) {
      r.warnings.push_back(std::to_string(failed_) +
                           " messages the module failed on and skipped (first: " + first_failure_ + ")");
    }
    if (skipped_ticks_ > 0) {
      r.warnings.push_back(std::to_string(skipped_ticks_) +
                           " timer ticks skipped where the time jumped ahead (first: " +
                           std::to_string(first_skip_.first) + " to " + std::to_string(first_skip_.second) + " us)");
    }
    // Frozen stamps (issue 15): most inputs of a channel carry the stamp of the one before (a stamp set once, or
    // one time given to every observation, as MRPT 2.5's carmen2rawlog writes). A module that orders, interpolates
    // or integrates by stamp cannot tell time from them; `info` and `diagnose` say the same of the log. A few
    // repeats are a fast source's clock resolution (or a duplicated message), so more than half are needed.
    std::vector<std::pair<std::string, StampRun>> frozen;
    for (const auto& [channel, run] : stamp_runs_) {
      if (run.count >= kFrozenMinInputs && run.repeated * 2 > run.count) frozen.emplace_back(*channel, run);
    }
    std::sort(frozen.begin(), frozen.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& [channel, run] : frozen) {
      r.warnings.push_back(channel + ": " + std::to_string(run.repeated) + " of " + std::to_string(run.count) +
                           " inputs repeat the stamp of the one before (frozen stamps: the module cannot tell "
                           "time from them)");
    }
    r.outputs = outputs_;
    if (!proc_s_.empty()) {
      double sum = 0, max = 0;
      for (double v : proc_s_) sum += v, max = std::max(max, v);
      r.proc_mean_s = sum / static_cast<double>(proc_s_.size());
      std::vector<double> sorted = proc_s_;
      r.proc_p95_s = quantile_in_place(sorted, 0.95);
      r.proc_max_s = max;
    }
    r.queue_depth_max = queue_max_;
    return r;
  }

 private:
  int64_t inputs_ = 0, late_ = 0, out_of_order_ = 0, outputs_ = 0, malformed_ = 0, failed_ = 0;
  std::string first_malformed_, first_failure_;
  int64_t skipped_ticks_ = 0;
  std::pair<int64_t, int64_t> first_skip_;
  int64_t latest_stamp_ = std::numeric_limits<int64_t>::min();
  /// Per input channel: how many stamped inputs, the newest stamp and the last one, and how many inputs carried
  /// the stamp of the one before.
  struct StampRun {
    int64_t count = 0, repeated = 0, newest = 0, previous = 0;
  };
  static constexpr int64_t kFrozenMinInputs = 10;
  std::unordered_map<const std::string*, StampRun> stamp_runs_;
  std::vector<double> proc_s_;
  std::deque<int64_t> busy_until_;  ///< completion times of queued inputs [us]
  int32_t queue_max_ = 0;
};

/// A module's statistics as an encoded driftlab.module_stats_t.
inline std::vector<uint8_t> encode_stats(const ModuleReport& r, int64_t seq, int64_t utime) {
  driftlab::module_stats_t m;
  m.header.seq = seq;
  m.header.utime = utime;
  m.header.frame_id = "";
  m.module = r.name;
  m.inputs = r.inputs;
  m.late = r.late;
  m.out_of_order = r.out_of_order;
  m.dropped = r.dropped;
  m.proc_time_mean_s = r.proc_mean_s;
  m.proc_time_p95_s = r.proc_p95_s;
  m.proc_time_max_s = r.proc_max_s;
  m.queue_depth_max = r.queue_depth_max;
  std::vector<uint8_t> bytes(static_cast<size_t>(m.getEncodedSize()));
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

}  // namespace driftlab::runtime::internal
