#include "analyzers/timing.h"

#include "analyzers/tf_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <numeric>
#include <optional>
#include <thread>

#include "core/huge_page_allocator.h"
#include "core/log_format.h"
#include "core/log_reader.h"
#include "core/quantile.h"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers {
namespace {

/// A stamp later than the channel's typical by less than this is never called late (see fit_clock).
constexpr double kLateStampMin_s = 0.001;

template <typename T>
using Array = HugeVector<T>;

/// What one pass over the log keeps of a channel.
struct Samples {
  std::string type;
  bool has_header = false;
  Array<int64_t> arrival;  // log timestamp [us]
  Array<int64_t> stamp;    // header.utime [us] (empty without a header)
  Array<int64_t> seq;      // header.seq
  Array<uint64_t> digest;  // payload size and first bytes (duplicate detection without a header)
  // Yaw rate [rad/s] at a stamp [s], for channels that observe the robot's rotation.
  Array<double> motion_t, motion_w;
  bool motion_from_pose = false;
  std::string frame;  // header.frame_id of the first message
  int64_t malformed = 0;          // messages that do not hold their type's layout: counted, nothing else read
  std::string malformed_example;
  double last_yaw = 0, last_t = 0;
  bool have_last = false;
  std::vector<std::span<const uint8_t>> scans;  // 2D scans, as views into the mapped log
  // A spinning lidar stamps its first beam but is complete only at its last: that much later [us] (from the
  // first scan), which latency and the clock fit add to the stamp.
  int64_t ready_after_us = 0;
};

double quantile(Array<double>& v, double q) { return quantile_in_place(v, q); }

Distribution distribution(Array<double> v) {
  Distribution d;
  if (v.empty()) return d;
  d.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  d.max = *std::max_element(v.begin(), v.end());
  d.p99 = quantile(v, 0.99);
  d.p95 = quantile(v, 0.95);
  d.p50 = quantile(v, 0.5);
  return d;
}

double median(Array<double> v) { return v.empty() ? 0 : quantile(v, 0.5); }


}  // namespace

namespace {

/// The rotation between two consecutive 2D scans, as the beam shift that best lines up their range profiles
/// (a robot turning by +d sees the world at bearings smaller by d: new[j] = old[j + d / increment]), refined to
/// a fraction of a beam by a parabola. Enough for timing (a yaw rate to correlate), not a scan matcher.
std::optional<double> scan_rotation(const std::vector<float>& previous, const std::vector<float>& current,
                                    double increment, bool full_circle) {
  const int n = static_cast<int>(current.size());
  if (n < 16 || static_cast<int>(previous.size()) != n || increment <= 0) return std::nullopt;
  const int max_shift = std::min(n / 4, static_cast<int>(std::ceil(0.35 / increment)));  // 0.35 rad per scan
  std::vector<double> cost(2 * static_cast<size_t>(max_shift) + 1, INFINITY);
  // Mean squared range difference at shift k, over every step-th beam.
  auto cost_at = [&](int k, int step) {
    double sum = 0;
    int used = 0, tried = 0;
    for (int j = 0; j < n; j += step, ++tried) {
      int i = j + k;
      if (full_circle) {
        i = i < 0 ? i + n : (i >= n ? i - n : i);
      } else if (i < 0 || i >= n) {
        continue;
      }
      const float a = current[static_cast<size_t>(j)], b = previous[static_cast<size_t>(i)];
      if (!(a > 0 && b > 0 && a < INFINITY && b < INFINITY)) continue;
      sum += (a - b) * (a - b);
      ++used;
    }
    return used > tried / 2 ? sum / used : INFINITY;
  };
  // Coarse (every 3rd shift, every 3rd beam), then every shift around the best (every 2nd beam).
  int coarse = 0;
  double coarse_cost = INFINITY;
  for (int k = -max_shift; k <= max_shift; k += 3) {
    const double c = cost_at(k, 3);
    if (c < coarse_cost) {
      coarse_cost = c;
      coarse = k;
    }
  }
  for (int k = std::max(-max_shift, coarse - 4); k <= std::min(max_shift, coarse + 4); ++k) {
    cost[static_cast<size_t>(k + max_shift)] = cost_at(k, 2);
  }
  const size_t best = static_cast<size_t>(std::min_element(cost.begin(), cost.end()) - cost.begin());
  if (!std::isfinite(cost[best])) return std::nullopt;
  double refine = 0;
  if (best > 0 && best + 1 < cost.size() && std::isfinite(cost[best - 1]) && std::isfinite(cost[best + 1])) {
    const double denom = cost[best - 1] - 2 * cost[best] + cost[best + 1];
    if (denom > 0) refine = 0.5 * (cost[best - 1] - cost[best + 1]) / denom;
  }
  return (static_cast<double>(best) - max_shift + refine) * increment;
}

/// Scans: the yaw rate between consecutive scans (kept as views into the mapped log during the pass), at their
/// midpoint. Pairs of scans are independent, so two threads share them.
void add_scan_motion(Samples& s) {
  const size_t n = s.scans.size();
  if (n < 2) return;
  std::vector<double> t(n, NAN), w(n, NAN);
  auto work = [&](size_t begin, size_t end) {
    driftlab::laser_scan_t previous, current;
    bool have_previous = false;
    for (size_t i = begin; i < end; ++i) {
      if (!lcmtypes::decode(s.scans[i], current)) {
        have_previous = false;
        continue;
      }
      const double ti = static_cast<double>(current.header.utime) * 1e-6;
      const double tp = static_cast<double>(previous.header.utime) * 1e-6;
      const double span = static_cast<double>(current.angle_increment) * static_cast<double>(current.nranges);
      if (have_previous && i > begin && ti > tp) {
        if (auto d = scan_rotation(previous.ranges, current.ranges, current.angle_increment,
                                   std::abs(span - 2 * M_PI) < 0.05)) {
          // Beams are measured through the scan: on average half its duration after the stamp.
          const double beams = 0.5 * (current.nranges - 1) * std::max(0.0f, current.time_increment);
          t[i] = 0.5 * (ti + tp) + (beams < 1.0 ? beams : 0.0);
          w[i] = *d / (ti - tp);
        }
      }
      std::swap(previous, current);
      have_previous = true;
    }
  };
  // The second thread starts one scan early, to have the previous one of its first.
  const size_t half = n / 2;
  std::thread helper(work, half - 1, n);
  work(0, half);
  helper.join();
  for (size_t i = 1; i < n; ++i) {
    if (std::isfinite(t[i])) {
      s.motion_t.push_back(t[i]);
      s.motion_w.push_back(w[i]);
    }
  }
  s.scans.clear();
}

void add_motion(Samples& s, int64_t fingerprint, std::span<const uint8_t> data) {
  if (fingerprint == driftlab::laser_scan_t::getHash()) {
    if (s.scans.empty()) s.ready_after_us = lcmtypes::ready_after_us(data);
    s.scans.push_back(data);  // analysed after the pass, in parallel
    return;
  }
  const auto motion = lcmtypes::read_motion(data);
  if (!motion) return;
  const double t = motion->stamp_s, value = motion->value;
  if (!motion->is_pose) {
    s.motion_t.push_back(t);
    s.motion_w.push_back(value);
    return;
  }
  // Ground truth or an estimate: the yaw rate between consecutive poses, at their midpoint.
  s.motion_from_pose = true;
  if (s.have_last && t > s.last_t) {
    s.motion_t.push_back(0.5 * (t + s.last_t));
    s.motion_w.push_back(std::remainder(value - s.last_yaw, 2 * M_PI) / (t - s.last_t));
  }
  s.last_yaw = value;
  s.last_t = t;
  s.have_last = true;
}

/// The ranks of a distribution-free 95% confidence interval for the median of m values (binomial, normal
/// approximation): the lower and upper order statistics, clamped to the sample.
std::pair<size_t, size_t> median_ci_ranks(size_t m) {
  const double half = 1.96 * std::sqrt(static_cast<double>(m)) / 2;
  const double mid = static_cast<double>(m - 1) / 2;
  return {static_cast<size_t>(std::max(0.0, std::floor(mid - half))),
          static_cast<size_t>(std::min(static_cast<double>(m - 1), std::ceil(mid + half)))};
}

/// The source clock from the lower envelope of latency over time: window minima, then a Theil-Sen line, with
/// 95% confidence intervals (Sen's, from Kendall's tau, for the slope; the median's order statistics for the
/// envelope's level). Late stamps are left out first: a stamp later than its arrival by far more than the
/// channel's delivery varies is not the clock but a message stamped after the fact (or by another clock), and a
/// handful of them would otherwise set every window's minimum.
void fit_clock(const Samples& s, int64_t log_start, ChannelTiming& c) {
  const size_t n = s.stamp.size();
  if (n < 20) return;
  Array<double> lat(n);
  for (size_t i = 0; i < n; ++i) lat[i] = static_cast<double>(s.arrival[i] - s.stamp[i]) * 1e-6;
  Array<double> sorted(lat);
  const double p50 = quantile(sorted, 0.5), p10 = quantile(sorted, 0.1);
  // 10 times the spread of the faster half of deliveries, and at least 1 ms (a clock's resolution and a
  // scheduler's tick): a 1000 ppm drift over a minute spreads latency by 60 ms and leaves it well inside.
  const double bound = p50 - std::max(kLateStampMin_s, 10 * (p50 - p10));
  for (size_t i = 0; i < n; ++i) {
    if (lat[i] >= bound) continue;
    if (c.late_stamps++ == 0) c.first_late_stamp_s = static_cast<double>(s.stamp[i] - log_start) * 1e-6;
    c.late_stamp_max_s = std::max(c.late_stamp_max_s, p50 - lat[i]);
  }
  const auto [lo, hi] = std::minmax_element(s.stamp.begin(), s.stamp.end());
  const double span = static_cast<double>(*hi - *lo) * 1e-6;
  if (span < 10.0) return;  // too short to tell drift from jitter
  const size_t windows = std::clamp<size_t>(n / 20, 4, 200);
  std::vector<double> min_lat(windows, INFINITY), at_t(windows, 0);
  for (size_t i = 0; i < n; ++i) {
    if (lat[i] < bound) continue;
    const double t = static_cast<double>(s.stamp[i] - *lo) * 1e-6;
    const size_t w = std::min(windows - 1, static_cast<size_t>(t / span * static_cast<double>(windows)));
    if (lat[i] < min_lat[w]) {
      min_lat[w] = lat[i];
      at_t[w] = t;
    }
  }
  std::vector<double> ts, ls;
  for (size_t w = 0; w < windows; ++w) {
    if (std::isfinite(min_lat[w])) {
      ts.push_back(at_t[w]);
      ls.push_back(min_lat[w]);
    }
  }
  if (ts.size() < 4) return;
  Array<double> slopes;
  for (size_t i = 0; i < ts.size(); ++i) {
    for (size_t j = i + 1; j < ts.size(); ++j) {
      if (ts[j] - ts[i] > span / static_cast<double>(windows)) slopes.push_back((ls[j] - ls[i]) / (ts[j] - ts[i]));
    }
  }
  if (slopes.empty()) return;
  std::sort(slopes.begin(), slopes.end());
  const double slope = quantile(slopes, 0.5);
  // Sen's interval: ranks (N -+ C) / 2 of the N slopes, C = z sqrt(var S) with Kendall's var S for m points.
  const auto m = static_cast<double>(ts.size());
  const double big_c = 1.96 * std::sqrt(m * (m - 1) * (2 * m + 5) / 18);
  const auto slope_n = static_cast<double>(slopes.size());
  const double slope_lo = slopes[static_cast<size_t>(std::clamp(std::floor((slope_n - big_c) / 2), 0.0, slope_n - 1))];
  const double slope_hi = slopes[static_cast<size_t>(std::clamp(std::ceil((slope_n + big_c) / 2), 0.0, slope_n - 1))];
  // The envelope's level at the windows' median time, where it does not depend on the slope.
  Array<double> t_sorted(ts.begin(), ts.end());
  const double tm = quantile(t_sorted, 0.5);
  Array<double> levels;
  for (size_t i = 0; i < ts.size(); ++i) levels.push_back(ls[i] - slope * (ts[i] - tm));
  std::sort(levels.begin(), levels.end());
  const double level = quantile(levels, 0.5);
  const auto [r_lo, r_hi] = median_ci_ranks(levels.size());
  const double t0 = static_cast<double>(log_start - *lo) * 1e-6;
  c.clock_valid = true;
  c.clock_drift_ppm = -slope * 1e6;
  c.clock_drift_ci_ppm = {-slope_hi * 1e6, -slope_lo * 1e6};
  c.clock_offset_s = -(level + slope * (t0 - tm));
  // Both parts of the level's uncertainty: its own, and the slope's carried from tm to the log's start.
  const double level_half = 0.5 * (levels[r_hi] - levels[r_lo]);
  const double slope_half = 0.5 * (slope_hi - slope_lo) * std::abs(t0 - tm);
  const double half = std::hypot(level_half, slope_half);
  c.clock_offset_ci_s = {c.clock_offset_s - half, c.clock_offset_s + half};
  Array<double> transport(n);
  for (size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(s.stamp[i] - *lo) * 1e-6;
    transport[i] = lat[i] - (level + slope * (t - tm));
  }
  c.transport_s = distribution(std::move(transport));
}

void analyse_sequence(const Samples& s, ChannelTiming& c) {
  // Order by seq (stable: arrival order among equals), then walk it.
  Array<size_t> order(s.seq.size());
  std::iota(order.begin(), order.end(), 0);
  if (!std::is_sorted(s.seq.begin(), s.seq.end())) {
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return s.seq[a] < s.seq[b]; });
  }
  for (size_t k = 1; k < order.size(); ++k) {
    const int64_t prev = s.seq[order[k - 1]], cur = s.seq[order[k]];
    if (cur == prev) {
      ++c.duplicates;
    } else if (cur > prev + 1) {
      const int64_t missing = cur - prev - 1;
      c.seq_gaps += missing;
      c.gaps.push_back({s.stamp[order[k - 1]], s.stamp[order[k]], missing});
    }
  }
}

void analyse_period(const Samples& s, ChannelTiming& c, bool record_gaps) {
  const Array<int64_t>& times = s.has_header ? s.stamp : s.arrival;
  Array<int64_t> sorted(times);
  if (!std::is_sorted(sorted.begin(), sorted.end())) std::sort(sorted.begin(), sorted.end());
  Array<double> intervals;
  for (size_t i = 1; i < sorted.size(); ++i) {
    if (sorted[i] > sorted[i - 1]) intervals.push_back(static_cast<double>(sorted[i] - sorted[i - 1]) * 1e-6);
  }
  if (intervals.empty()) return;
  const double median_interval = median(intervals);
  const double mean_interval = static_cast<double>(sorted.back() - sorted.front()) * 1e-6 /
                               static_cast<double>(sorted.size() - 1);
  // Bursts: the usual interval far shorter than the average one. A steady stream losing even 80% of its
  // messages at random keeps its median interval above half its mean (the gaps are geometric), so a quarter
  // means the messages come in groups: judged by the average rate, and its long gaps are not drops.
  if (sorted.size() >= 10 && median_interval < 0.25 * mean_interval) {
    c.bursty = true;
    c.expected_period_s = mean_interval;
    c.burst_interval_s = median_interval;
    Array<double> sizes;
    double size = 1;
    for (size_t i = 1; i < sorted.size(); ++i) {
      if (static_cast<double>(sorted[i] - sorted[i - 1]) * 1e-6 < 0.5 * mean_interval) {
        ++size;
      } else {
        sizes.push_back(size);
        size = 1;
      }
    }
    sizes.push_back(size);
    c.burst_size = median(sizes);
    return;
  }
  c.expected_period_s = median_interval;
  if (c.expected_period_s <= 0) return;
  for (size_t i = 1; i < sorted.size(); ++i) {
    const double gap = static_cast<double>(sorted[i] - sorted[i - 1]) * 1e-6;
    if (gap > 1.5 * c.expected_period_s) {
      const auto missing = static_cast<int64_t>(std::llround(gap / c.expected_period_s)) - 1;
      if (missing <= 0) continue;
      c.missing_by_period += missing;
      if (record_gaps) c.gaps.push_back({sorted[i - 1], sorted[i], missing});
    }
  }
}

void judge(ChannelTiming& c) {
  auto add = [&](const char* level, const std::string& why) {
    if (std::string(level) == "fault" || c.verdict == "ok") c.verdict = level;
    c.reasons.push_back(why);
  };
  char buf[256];
  if (c.malformed > 0) {
    std::snprintf(buf, sizeof(buf), "%lld messages do not decode as %s (first: %s)", static_cast<long long>(c.malformed),
                  c.type.c_str(), c.malformed_example.c_str());
    add("fault", buf);
  }
  if (c.seq_gaps > 0) {
    std::snprintf(buf, sizeof(buf), "%lld messages missing in %zu gaps of seq",
                  static_cast<long long>(c.seq_gaps), c.gaps.size());
    add("fault", buf);
  } else if (!c.has_header && c.missing_by_period > 0) {
    std::snprintf(buf, sizeof(buf), "about %lld messages missing from gaps longer than 1.5 periods",
                  static_cast<long long>(c.missing_by_period));
    add("warn", buf);
  }
  if (c.duplicates > 0) {
    std::snprintf(buf, sizeof(buf), "%lld duplicated messages", static_cast<long long>(c.duplicates));
    add("fault", buf);
  }
  if (c.out_of_order_stamp > 0) {
    std::snprintf(buf, sizeof(buf), "%lld messages arrived after a newer one (reordered)",
                  static_cast<long long>(c.out_of_order_stamp));
    add("fault", buf);
  }
  if (c.zero_stamps > 0) {
    std::snprintf(buf, sizeof(buf), "%lld messages are stamped 0: the source never set their stamps",
                  static_cast<long long>(c.zero_stamps));
    add("fault", buf);
  }
  // Frozen stamps: most messages carry the stamp of the one before (a stamp set once, or every observation given
  // one time, as MRPT 2.5's carmen2rawlog does). A few repeats are a fast source's clock resolution.
  if (c.count >= 10 && c.repeated_stamps * 2 > c.count) {
    std::snprintf(buf, sizeof(buf), "%lld of %lld messages repeat the stamp of the one before: the stamps are frozen",
                  static_cast<long long>(c.repeated_stamps), static_cast<long long>(c.count));
    add("fault", buf);
  }
  if (c.out_of_order_arrival > 0) {
    std::snprintf(buf, sizeof(buf), "log times step back %lld times: events were written out of time order",
                  static_cast<long long>(c.out_of_order_arrival));
    add("warn", buf);
  }
  // Stamps on another time base than arrival, by more than a second: name the usual causes.
  if (c.has_header && c.zero_stamps * 2 < c.count && std::abs(c.latency_s.p50) >= 1.0) {
    const double behind = c.latency_s.p50;  // arrival - stamp [s]
    constexpr double kWallClock = 1e9;      // 2001-09-09 in seconds since the epoch: stamps before are not dates
    const double stamp_s = static_cast<double>(c.median_stamp_utime) * 1e-6;
    std::string cause;
    auto near = [&](double seconds) { return std::abs(std::abs(behind) - seconds) < 0.5; };
    if (stamp_s < kWallClock && stamp_s + behind >= kWallClock) {
      std::snprintf(buf, sizeof(buf), "stamps count from %.0f s while arrivals are wall-clock dates: the source "
                    "stamps with simulation time or time since boot (use_sim_time?)", stamp_s);
      cause = buf;
    } else if (near(37) || near(18) || near(19)) {
      const double s = std::round(std::abs(behind));
      const char* which = s == 37 ? "TAI and UTC" : s == 18 ? "GPS time and UTC" : "TAI and GPS time";
      std::snprintf(buf, sizeof(buf), "stamps are %.3f s %s arrival: the %.0f s between %s", std::abs(behind),
                    behind > 0 ? "behind" : "ahead of", s, which);
      cause = buf;
    } else if (std::abs(behind) >= 1800 && std::abs(std::remainder(behind, 1800)) < 1) {
      std::snprintf(buf, sizeof(buf), "stamps are %.1f h %s arrival: a time zone applied to one clock",
                    std::abs(behind) / 3600, behind > 0 ? "behind" : "ahead of");
      cause = buf;
    }
    if (!cause.empty()) add("fault", cause);
  }
  if (c.has_header && c.latency_s.p50 < -0.001) {
    std::snprintf(buf, sizeof(buf), "stamps are %.1f ms ahead of arrival: the source clock runs ahead",
                  -c.latency_s.p50 * 1e3);
    add("fault", buf);
  }
  // A drift is reported when its confidence interval leaves out zero: jitter alone can tilt a line a little.
  if (c.clock_valid && std::abs(c.clock_drift_ppm) >= 25 &&
      (c.clock_drift_ci_ppm[0] > 0 || c.clock_drift_ci_ppm[1] < 0)) {
    std::snprintf(buf, sizeof(buf), "source clock drifts %.0f ppm (95%%: %.0f to %.0f; %.1f ms per minute)",
                  c.clock_drift_ppm, c.clock_drift_ci_ppm[0], c.clock_drift_ci_ppm[1], c.clock_drift_ppm * 60e-3);
    add(std::abs(c.clock_drift_ppm) >= 100 ? "fault" : "warn", buf);
  }
  if (c.bursty) {
    std::snprintf(buf, sizeof(buf), "messages come in bursts of about %.0f, %.1f ms apart, %.2f Hz on average: "
                  "drops are told by seq only", c.burst_size, c.burst_interval_s * 1e3, 1 / c.expected_period_s);
    add("warn", buf);
  }
  if (c.late_stamps > 0) {
    std::snprintf(buf, sizeof(buf), "%lld stamps late by up to %.3f s against the channel's usual latency (the "
                  "first %.1f s into the log): stamped after the fact or by another clock; left out of the clock fit",
                  static_cast<long long>(c.late_stamps), c.late_stamp_max_s,
                  c.first_late_stamp_s);
    add("warn", buf);
  }
  if (c.has_header && c.latency_s.p99 > 0.005 && c.latency_s.p99 > 5 * std::max(c.latency_s.p50, 0.0005)) {
    std::snprintf(buf, sizeof(buf), "latency spikes: p99 %.1f ms against a median of %.1f ms",
                  c.latency_s.p99 * 1e3, c.latency_s.p50 * 1e3);
    add("warn", buf);
  }
}

/// Whether two channels carry the same stamps, message for message (90% of each one's stamps appear in the
/// other): stamped by one clock at one instant, as a scan and the pose logged with it, so there is no skew between
/// them to measure, whatever a correlation of their motion says. Streams at different rates on one clock (a 200 Hz
/// IMU, 100 Hz ground truth) share only some stamps and are still compared.
bool same_stamps(const Samples& a, const Samples& b) {
  if (a.stamp.empty() || b.stamp.empty()) return false;
  Array<int64_t> x(a.stamp), y(b.stamp);
  std::sort(x.begin(), x.end());
  std::sort(y.begin(), y.end());
  size_t i = 0, j = 0, common = 0;
  while (i < x.size() && j < y.size()) {
    if (x[i] < y[j]) {
      ++i;
    } else if (y[j] < x[i]) {
      ++j;
    } else {
      ++common, ++i, ++j;
    }
  }
  return common * 10 >= std::max(x.size(), y.size()) * 9;
}

/// Linear interpolation of (t, v) (t ascending) at time x; false outside.
bool sample_at(const Array<double>& t, const Array<double>& v, double x, size_t& hint, double& out) {
  if (t.empty() || x < t.front() || x > t.back()) return false;
  if (hint == 0 || t[hint] > x) {  // first call, or a jump back: search rather than walk
    hint = static_cast<size_t>(std::upper_bound(t.begin(), t.end(), x) - t.begin());
    hint = hint > 0 ? hint - 1 : 0;
  }
  while (hint + 1 < t.size() && t[hint + 1] < x) ++hint;
  if (hint + 1 >= t.size()) {
    out = v.back();
    return true;
  }
  const double span = t[hint + 1] - t[hint];
  const double f = span > 0 ? (x - t[hint]) / span : 0;
  out = v[hint] * (1 - f) + v[hint + 1] * f;
  return true;
}

/// A channel's yaw rate resampled (linearly) on the log's 1 ms grid, index 0 at the log's start; NaN where the
/// channel has no data. Built once per channel and shared by every pair and window.
struct Grid {
  static constexpr double kStep = 0.001;
  std::vector<float> v;
};

Grid make_grid(const Samples& s, double log_start, double log_end) {
  Grid g;
  g.v.assign(static_cast<size_t>((log_end - log_start) / Grid::kStep) + 1, NAN);
  size_t hint = 0;
  double value = 0;
  const size_t first = static_cast<size_t>(std::max(0.0, std::ceil((s.motion_t.front() - log_start) / Grid::kStep)));
  for (size_t i = first; i < g.v.size(); ++i) {
    if (!sample_at(s.motion_t, s.motion_w, log_start + static_cast<double>(i) * Grid::kStep, hint, value)) break;
    g.v[i] = static_cast<float>(value);
  }
  return g;
}

/// The lag (b later than a) maximising the normalised correlation of two yaw-rate signals over [from, to] (times
/// relative to the log's start): lags are searched every 10 ms (on half the points), then every 1 ms within 15 ms
/// of the best, and a parabola through the top three gives the sub-millisecond peak. Long windows use every k-th
/// grid point (at most 5,000): the signals are smooth, so that loses nothing. Confidence is the peak correlation
/// (0 when a signal barely moves or has no data there). `coarse`, when given, receives the correlation at every
/// 10 ms of lag from -max_lag (NaN where it is undefined).
std::pair<double, double> correlate(const Grid& a, const Grid& b, double from, double to, double max_lag,
                                    std::vector<double>* coarse = nullptr) {
  const int lags = static_cast<int>(std::round(max_lag / Grid::kStep));
  const long lo = static_cast<long>(std::ceil((from + max_lag) / Grid::kStep));
  const long hi = static_cast<long>(std::floor((to - max_lag) / Grid::kStep));
  if ((hi - lo) * Grid::kStep < 2.0 || lo - lags < 0 || hi + lags >= static_cast<long>(b.v.size()) ||
      hi >= static_cast<long>(a.v.size())) {
    return {0, 0};
  }
  const size_t n = static_cast<size_t>(hi - lo);
  const size_t stride = std::max<size_t>(1, n / 5000);
  const float* sa = a.v.data() + lo;
  const float* sb = b.v.data() + (lo - lags);
  double mean_a = 0, var_a = 0, points = 0;
  for (size_t i = 0; i < n; i += stride, ++points) mean_a += sa[i];
  mean_a /= points;
  for (size_t i = 0; i < n; i += stride) var_a += (sa[i] - mean_a) * (sa[i] - mean_a);
  // A robot that barely turns (yaw rate varying by less than 0.01 rad/s) says nothing about skew.
  if (!(var_a / points >= 1e-4)) return {0, 0};  // also false for NaN: a has gaps here
  auto correlation = [&](int k, size_t step) {
    const float* y = sb + k;
    double sum = 0, sum_sq = 0, dot = 0, count = 0;
    for (size_t i = 0; i < n; i += step, ++count) {
      sum += y[i];
      sum_sq += static_cast<double>(y[i]) * y[i];
      dot += (sa[i] - mean_a) * y[i];
    }
    const double var_b = sum_sq - sum * sum / count;
    const double c = dot / std::sqrt(var_a * (count / points) * var_b);
    return var_b > 1e-12 && std::isfinite(c) ? c : -2.0;
  };
  constexpr int kCoarse = 10;
  int coarse_best = lags;
  double coarse_value = -3;
  for (int k = 0; k <= 2 * lags; k += kCoarse) {
    const double c = correlation(k, 2 * stride);
    if (coarse != nullptr) coarse->push_back(c > -2 ? c : NAN);
    if (c > coarse_value) {
      coarse_value = c;
      coarse_best = k;
    }
  }
  std::vector<double> corr(2 * static_cast<size_t>(lags) + 1, -2);
  for (int k = std::max(0, coarse_best - 15); k <= std::min(2 * lags, coarse_best + 15); ++k) {
    corr[static_cast<size_t>(k)] = correlation(k, stride);
  }
  const size_t best = static_cast<size_t>(std::max_element(corr.begin(), corr.end()) - corr.begin());
  if (corr[best] <= -2) return {0, 0};
  double refine = 0;
  if (best > 0 && best + 1 < corr.size() && corr[best - 1] > -2 && corr[best + 1] > -2) {
    const double y0 = corr[best - 1], y1 = corr[best], y2 = corr[best + 1];
    const double denom = y0 - 2 * y1 + y2;
    if (denom < 0) refine = 0.5 * (y0 - y2) / denom;
  }
  const double lag = (static_cast<double>(best) - lags + refine) * Grid::kStep;
  return {lag, std::max(0.0, corr[best])};
}

/// The skew of b against a over the windows of their common time.
std::optional<StreamPair> skew(const std::string& a_name, const Samples& a, const Grid& ga, const std::string& b_name,
                               const Samples& b, const Grid& gb, double log_start, const DiagnoseOptions& options) {
  const double from = std::max(a.motion_t.front(), b.motion_t.front()) - log_start;
  const double to = std::min(a.motion_t.back(), b.motion_t.back()) - log_start;
  StreamPair p{a_name, b_name, 0, 0, "yaw-rate cross-correlation", {}, {}};
  // Windows (at most 64: long logs get longer ones) show changes along the log; the pair's offset is their
  // confidence-weighted median, its confidence their median. A short log is one window.
  const double window = to - from < 2 * options.window_s ? to - from : std::max(options.window_s, (to - from) / 64);
  std::vector<double> sum, weight, curve;
  for (double w = from; w + window <= to + 1e-9; w += window) {
    curve.clear();
    const auto [wl, wc] = correlate(ga, gb, w, w + window, options.max_lag_s, &curve);
    if (wc <= 0) continue;
    p.windows.push_back({w, w + window, wl, wc});
    sum.resize(curve.size(), 0);
    weight.resize(curve.size(), 0);
    for (size_t k = 0; k < curve.size(); ++k) {
      if (std::isnan(curve[k])) continue;
      sum[k] += wc * curve[k];
      weight[k] += wc;
    }
  }
  if (p.windows.empty()) return std::nullopt;
  const int lags = static_cast<int>(std::round(options.max_lag_s / Grid::kStep));
  for (size_t k = 0; k < sum.size(); ++k) {
    if (weight[k] > 0) p.curve.emplace_back((static_cast<double>(k) * 10 - lags) * Grid::kStep, sum[k] / weight[k]);
  }
  std::vector<SkewWindow> by_offset = p.windows;
  std::sort(by_offset.begin(), by_offset.end(), [](const auto& x, const auto& y) { return x.offset_s < y.offset_s; });
  double total = 0, acc = 0;
  for (const auto& w : by_offset) total += w.confidence;
  for (const auto& w : by_offset) {
    acc += w.confidence;
    if (acc >= total / 2) {
      p.offset_s = w.offset_s;
      break;
    }
  }
  Array<double> confidences;
  for (const auto& w : p.windows) confidences.push_back(w.confidence);
  p.confidence = median(std::move(confidences));
  return p;
}

}  // namespace

Result<Diagnosis> diagnose(const std::string& log, const DiagnoseOptions& options) {
  auto reader = LogReader::open(log);
  if (!reader) return reader.error();
  Diagnosis d;
  d.log = log;
  std::map<std::string, Samples, std::less<>> channels;
  internal::TfCheck tf;
  const int64_t tf_hash = driftlab::tf_t::getHash();
  Samples* last = nullptr;
  std::string_view last_name;
  Event e;
  bool first = true;
  while (reader->next(e)) {
    if (first) d.start_utime = d.end_utime = e.utime;
    first = false;
    d.start_utime = std::min(d.start_utime, e.utime);
    d.end_utime = std::max(d.end_utime, e.utime);
    if (last == nullptr || e.channel != last_name) {
      auto it = channels.find(e.channel);
      if (it == channels.end()) {
        it = channels.emplace(std::string(e.channel), Samples{}).first;
        const lcmtypes::TypeInfo* type = lcmtypes::find_type(logfmt::fingerprint(e.data));
        it->second.type = type != nullptr ? type->name : "";
        // Other programs' types may carry our header too: recognise it by its shape.
        it->second.has_header = lcmtypes::has_header(e.data, e.utime);
      }
      last = &it->second;
      last_name = it->first;
    }
    Samples& s = *last;
    if (!s.type.empty()) {
      if (auto why = lcmtypes::layout_problem(e.data)) {
        if (s.malformed++ == 0) s.malformed_example = *why;
        continue;
      }
    }
    const int64_t fp = logfmt::fingerprint(e.data);
    s.arrival.push_back(e.utime);
    if (fp == tf_hash) tf.add_tf(e.data, e.utime, internal::is_static_tf_channel(last_name));
    if (s.has_header) {
      if (const auto h = lcmtypes::read_header(e.data, e.utime)) {
        s.seq.push_back(h->seq);
        s.stamp.push_back(h->utime);
        if (s.stamp.size() == 1) s.frame.assign(h->frame_id);
        add_motion(s, fp, e.data);
      } else {
        // An unknown type whose header was a coincidence, or a message too short for one: the channel is untyped.
        s.has_header = false;
        s.seq.clear();
        s.stamp.clear();
      }
    }
    if (!s.has_header) {  // duplicates of untyped messages are told by their bytes
      uint64_t digest = e.data.size();
      for (size_t i = 0; i < std::min<size_t>(e.data.size(), 64); ++i) digest = (digest ^ e.data[i]) * 1099511628211ull;
      s.digest.push_back(digest);
    }
  }
  d.log_problems = reader->problems();

  for (auto& [name, s] : channels) {
    if (std::find(options.ignore_channels.begin(), options.ignore_channels.end(), name) !=
        options.ignore_channels.end()) {
      continue;
    }
    if (s.has_header && s.stamp.size() != s.arrival.size()) s.has_header = false;
    ChannelTiming c;
    c.name = name;
    c.type = s.type;
    c.has_header = s.has_header;
    c.malformed = s.malformed;
    c.malformed_example = s.malformed_example;
    c.count = static_cast<int64_t>(s.arrival.size());
    const auto [a0, a1] = std::minmax_element(s.arrival.begin(), s.arrival.end());
    if (c.count > 1 && *a1 > *a0) c.rate_hz = static_cast<double>(c.count - 1) / (static_cast<double>(*a1 - *a0) * 1e-6);
    for (size_t i = 1; i < s.arrival.size(); ++i) {
      if (s.arrival[i] < s.arrival[i - 1]) ++c.out_of_order_arrival;
    }
    if (s.has_header) {
      analyse_sequence(s, c);
      analyse_period(s, c, false);
      int64_t newest = INT64_MIN;
      Array<double> latency(s.stamp.size());
      for (size_t i = 0; i < s.stamp.size(); ++i) {
        if (s.stamp[i] < newest && s.seq[i] != s.seq[i - 1]) ++c.out_of_order_stamp;
        if (i > 0 && s.stamp[i] == s.stamp[i - 1] && s.seq[i] != s.seq[i - 1]) ++c.repeated_stamps;
        c.zero_stamps += s.stamp[i] == 0;
        newest = std::max(newest, s.stamp[i]);
        latency[i] = static_cast<double>(s.arrival[i] - s.stamp[i] - s.ready_after_us) * 1e-6;
      }
      c.latency_s = distribution(std::move(latency));
      Array<int64_t> stamps(s.stamp);
      std::nth_element(stamps.begin(), stamps.begin() + static_cast<ptrdiff_t>(stamps.size() / 2), stamps.end());
      c.median_stamp_utime = stamps.empty() ? 0 : stamps[stamps.size() / 2];
      // The clock is fitted to when the data was complete (a scan's last beam), then the stamps restored.
      for (auto& t : s.stamp) t += s.ready_after_us;
      fit_clock(s, d.start_utime, c);
      for (auto& t : s.stamp) t -= s.ready_after_us;
    } else {
      analyse_period(s, c, true);
      // Without a header, a duplicate is the same bytes again well within one period (a steady stream of
      // identical messages, like a heartbeat, is not duplication).
      const double window = 0.25 * c.expected_period_s * 1e6;
      for (size_t i = 1; i < s.digest.size() && s.digest.size() == s.arrival.size(); ++i) {
        if (s.digest[i] == s.digest[i - 1] && static_cast<double>(s.arrival[i] - s.arrival[i - 1]) < window) {
          ++c.duplicates;
        }
      }
    }
    judge(c);
    if (s.has_header && s.type != "driftlab.tf_t") tf.add_data(name, s.frame, s.stamp, s.arrival);
    d.channels.push_back(std::move(c));
  }
  d.tf = tf.finish();

  // Skew between every two streams that observe the yaw rate: IMU gyro, wheel odometry, poses.
  for (auto& [name, s] : channels) add_scan_motion(s);
  std::vector<const std::pair<const std::string, Samples>*> moving;
  for (const auto& entry : channels) {
    const auto& w = entry.second.motion_w;
    if (w.size() < 20) continue;
    const double mean = std::accumulate(w.begin(), w.end(), 0.0) / static_cast<double>(w.size());
    double var = 0;
    for (double x : w) var += (x - mean) * (x - mean);
    // A robot that barely turns (yaw rate varying by less than 0.01 rad/s) says nothing about skew.
    if (var / static_cast<double>(w.size()) >= 1e-4) moving.push_back(&entry);
  }
  // Ground truth first, then IMUs: the reference side of each pair.
  std::stable_sort(moving.begin(), moving.end(), [](const auto* x, const auto* y) {
    return x->second.motion_from_pose > y->second.motion_from_pose;
  });
  const double log_start = static_cast<double>(d.start_utime) * 1e-6;
  // Each pair is independent: two threads share them (this machine has two cores).
  std::vector<std::pair<size_t, size_t>> jobs;
  for (size_t i = 0; i < moving.size(); ++i) {
    for (size_t j = i + 1; j < moving.size(); ++j) {
      if (!same_stamps(moving[i]->second, moving[j]->second)) jobs.emplace_back(i, j);
    }
  }
  const double log_end = static_cast<double>(d.end_utime) * 1e-6;
  std::vector<Grid> grids(moving.size());
  std::vector<std::optional<StreamPair>> results(jobs.size());
  auto work = [&](size_t first, size_t stride) {
    for (size_t k = first; k < moving.size(); k += stride) grids[k] = make_grid(moving[k]->second, log_start, log_end);
  };
  auto pairs = [&](size_t first, size_t stride) {
    for (size_t k = first; k < jobs.size(); k += stride) {
      const auto [i, j] = jobs[k];
      results[k] = skew(moving[i]->first, moving[i]->second, grids[i], moving[j]->first, moving[j]->second, grids[j],
                        log_start, options);
    }
  };
  std::thread helper(work, 1, 2);
  work(0, 2);
  helper.join();
  helper = std::thread(pairs, 1, 2);
  pairs(0, 2);
  helper.join();
  for (auto& r : results) {
    if (r) d.pairs.push_back(std::move(*r));
  }
  return d;
}

}  // namespace driftlab::analyzers
