#include "analyzers/internal/channel_timing.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "core/quantile.h"
#include "core/time.h"

namespace driftlab::analyzers::internal {
namespace {

/// A stamp later than the channel's typical by less than this is never called late (see fit_clock).
constexpr double kLateStampMin_s = 0.001;

/// The source clock from the lower envelope of latency over time: window minima, then a Theil-Sen line, with
/// 95% confidence intervals (Sen's, from Kendall's tau, for the slope; the median's order statistics for the
/// envelope's level). Late stamps are left out first: a stamp later than its arrival by far more than the
/// channel's delivery varies is not the clock but a message stamped after the fact (or by another clock), and a
/// handful of them would otherwise set every window's minimum.
void fit_clock(const Samples& s, int64_t log_start, ChannelTiming& c) {
  const size_t n = s.stamp.size();
  if (n < 20) return;
  Array<double> lat(n);
  for (size_t i = 0; i < n; ++i) lat[i] = seconds_between(s.stamp[i], s.arrival[i]);
  Array<double> sorted(lat);
  const double p50 = quantile(sorted, 0.5), p10 = quantile(sorted, 0.1);
  // 10 times the spread of the faster half of deliveries, and at least 1 ms (a clock's resolution and a
  // scheduler's tick): a 1000 ppm drift over a minute spreads latency by 60 ms and leaves it well inside.
  const double bound = p50 - std::max(kLateStampMin_s, 10 * (p50 - p10));
  for (size_t i = 0; i < n; ++i) {
    if (lat[i] >= bound) continue;
    if (c.late_stamps++ == 0) c.first_late_stamp_s = seconds_between(log_start, s.stamp[i]);
    c.late_stamp_max_s = std::max(c.late_stamp_max_s, p50 - lat[i]);
  }
  const auto [lo, hi] = std::minmax_element(s.stamp.begin(), s.stamp.end());
  const double span = seconds_between(*lo, *hi);
  if (span < 10.0) return;  // too short to tell drift from jitter
  const size_t windows = std::clamp<size_t>(n / 20, 4, 200);
  std::vector<double> min_lat(windows, INFINITY), at_t(windows, 0);
  for (size_t i = 0; i < n; ++i) {
    if (lat[i] < bound) continue;
    const double t = seconds_between(*lo, s.stamp[i]);
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
  // The median of a copy: quantile() reorders what it is given (nth_element), and the interval below reads the
  // sorted slopes by rank (it read a reordered array before the calibration study found the intervals off).
  Array<double> scratch(slopes);
  const double slope = quantile(scratch, 0.5);
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
  scratch.assign(levels.begin(), levels.end());
  const double level = quantile(scratch, 0.5);
  const auto [r_lo, r_hi] = median_ci_ranks(levels.size());
  const double t0 = seconds_between(*lo, log_start);
  c.clock_valid = true;
  c.clock_drift_ppm = -slope * 1e6;
  c.clock_drift_ci_ppm = {-slope_hi * 1e6, -slope_lo * 1e6};
  c.clock_offset_s = -(level + slope * (t0 - tm));
  // Both parts of the level's uncertainty: its own, and the slope's carried from tm to the log's start.
  const double level_half = 0.5 * (levels[r_hi] - levels[r_lo]);
  const double slope_half = 0.5 * (slope_hi - slope_lo) * std::abs(t0 - tm);
  // And what the offset means: the clock against the fastest delivery the channel has, not against each window's
  // fastest. A window's minimum lies above that floor by the jitter of its fastest message, so the level (their
  // median) overstates the floor's latency and the offset is too small by that much: an interval around the
  // level alone held the injected offset 9 times in 36 on simulated logs with jitter (docs/diagnosis.md,
  // "Calibration"). The lowest of the m minima is near the floor: for minima spread exponentially above it (the
  // minimum of exponential jitter is exponential, of mean mu = (level - lowest) / ln 2), the floor is within
  // 3 mu / m below the lowest with 95% confidence. The interval reaches that far up; the stamps' whole
  // microseconds (stamp and arrival, each rounded or cut by up to one) widen both ends.
  constexpr double kResolution_s = 2e-6;
  const double above_floor = level - levels.front();
  const double floor_gap = above_floor * (1 + 3 / (std::log(2.0) * m));
  c.clock_offset_ci_s = {c.clock_offset_s - std::hypot(level_half, slope_half) - kResolution_s,
                         c.clock_offset_s + std::hypot(std::max(level_half, floor_gap), slope_half) + kResolution_s};
  Array<double> transport(n);
  for (size_t i = 0; i < n; ++i) {
    const double t = seconds_between(*lo, s.stamp[i]);
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
  // With stamps, each gap's messages' arrivals too: a consumer goes without from the one to the other.
  Array<int64_t> arrival_at;
  if (record_gaps && s.has_header) {
    Array<size_t> order(times.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return times[a] < times[b]; });
    arrival_at.resize(order.size());
    for (size_t i = 0; i < order.size(); ++i) {
      sorted[i] = times[order[i]];
      arrival_at[i] = s.arrival[order[i]];
    }
  } else if (!std::is_sorted(sorted.begin(), sorted.end())) {
    std::sort(sorted.begin(), sorted.end());
  }
  Array<double> intervals;
  for (size_t i = 1; i < sorted.size(); ++i) {
    if (sorted[i] > sorted[i - 1]) intervals.push_back(seconds_between(sorted[i - 1], sorted[i]));
  }
  if (intervals.empty()) return;
  const double median_interval = median(intervals);
  const double mean_interval = seconds_between(sorted.front(), sorted.back()) / static_cast<double>(sorted.size() - 1);
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
      if (seconds_between(sorted[i - 1], sorted[i]) < 0.5 * mean_interval) {
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
  // A period: a steady stream's intervals gather around it. One losing up to two thirds of its messages at random
  // still has a third of its intervals at one period (the gaps are geometric), and jitter of a quarter period is
  // more than a timer-driven source shows. Fewer than that, and the source sends when it has something (a logger
  // writing as data comes, an event-driven node): there is no period to count missing messages by, only seq.
  size_t near_median = 0;
  for (const double i : intervals) near_median += std::abs(i - median_interval) <= 0.25 * median_interval ? 1 : 0;
  c.regular_fraction = static_cast<double>(near_median) / static_cast<double>(intervals.size());
  // Without a sequence number a gap is told from time alone, and only a stream that keeps its period is believed:
  // three quarters of its intervals within a quarter of it (a timer-driven publisher losing a quarter of its
  // messages at random keeps that many; AMCL, publishing as the robot moves, keeps 57%).
  const bool steady = s.seq_counted ? 4 * near_median >= 3 * intervals.size() : 3 * near_median >= intervals.size();
  if (sorted.size() >= 10 && !steady) {
    c.irregular = true;
    c.expected_period_s = mean_interval;
    return;
  }
  c.expected_period_s = median_interval;
  if (c.expected_period_s <= 0) return;
  for (size_t i = 1; i < sorted.size(); ++i) {
    const double gap = seconds_between(sorted[i - 1], sorted[i]);
    if (gap > 1.5 * c.expected_period_s) {
      const auto missing = static_cast<int64_t>(std::llround(gap / c.expected_period_s)) - 1;
      if (missing <= 0) continue;
      c.missing_by_period += missing;
      if (!record_gaps) continue;
      c.gaps.push_back({sorted[i - 1], sorted[i], missing});
      if (!arrival_at.empty()) {
        c.gaps.back().start_arrival = arrival_at[i - 1];
        c.gaps.back().end_arrival = arrival_at[i];
      }
    }
  }
}

/// "41.3 s" from the log's start: where a hole begins.
std::string hole_text(const Gap& g, int64_t log_start) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), "%.2f s at %.1f s", seconds_between(g.start_arrival, g.end_arrival),
                seconds_between(log_start, g.start_arrival));
  return buf;
}

void judge(ChannelTiming& c, const Samples& s, int64_t log_start, bool mapped) {
  auto add = [&](const char* level, const std::string& why, Cause cause) {
    add_reason(c, std::string(level) == "fault", why, cause);
  };
  char buf[512];
  if (c.malformed > 0) {
    std::snprintf(buf, sizeof(buf), "%lld messages do not decode as %s (first: %s)",
                  static_cast<long long>(c.malformed), c.type.c_str(), c.malformed_example.c_str());
    add("fault", buf, Cause::kData);
  }
  if (c.seq_gaps > 0) {
    std::snprintf(buf, sizeof(buf), "%lld messages missing in %zu gaps of seq", static_cast<long long>(c.seq_gaps),
                  c.gaps.size());
    add("fault", buf, Cause::kLoss);
  } else if (c.seq_counted && c.missing_by_period > 0) {
    // No sequence number travelled (ROS 2): the holes in the stamps' steady period, each with its time, the
    // longest first.
    std::vector<Gap> holes = c.gaps;
    std::stable_sort(holes.begin(), holes.end(), [](const Gap& a, const Gap& b) {
      return a.end_arrival - a.start_arrival > b.end_arrival - b.start_arrival;
    });
    std::string list;
    for (size_t i = 0; i < holes.size() && i < 3; ++i) list += (i ? ", " : "") + hole_text(holes[i], log_start);
    if (holes.size() > 3) list += ", ...";
    std::snprintf(buf, sizeof(buf),
                  "about %lld messages missing in %zu hole%s of its %.1f ms period (the longest without a message: "
                  "%s); no sequence number travelled, so they are told from the stamps",
                  static_cast<long long>(c.missing_by_period), holes.size(), holes.size() == 1 ? "" : "s",
                  c.expected_period_s * 1e3, list.c_str());
    add("warn", buf, Cause::kLoss);
  } else if (!c.has_header && c.missing_by_period > 0) {
    std::snprintf(buf, sizeof(buf), "about %lld messages missing from gaps longer than 1.5 periods",
                  static_cast<long long>(c.missing_by_period));
    add("warn", buf, Cause::kLoss);
  }
  if (c.duplicates > 0) {
    std::snprintf(buf, sizeof(buf), "%lld duplicated messages", static_cast<long long>(c.duplicates));
    add("fault", buf, Cause::kSymptom);
  }
  if (c.out_of_order_stamp > 0) {
    std::snprintf(buf, sizeof(buf), "%lld messages arrived after a newer one (reordered)",
                  static_cast<long long>(c.out_of_order_stamp));
    add("fault", buf, Cause::kSymptom);
  }
  if (c.zero_stamps > 0 && !s.is_static_tf) {  // tf2 takes static transforms as timeless
    std::snprintf(buf, sizeof(buf), "%lld messages are stamped 0: the source never set their stamps",
                  static_cast<long long>(c.zero_stamps));
    add("fault", buf, Cause::kClock);
  }
  // Frozen stamps: most messages carry the stamp of the one before (a stamp set once, or every observation given
  // one time, as MRPT 2.5's carmen2rawlog does). A few repeats are a fast source's clock resolution.
  if (c.count >= 10 && c.repeated_stamps * 2 > c.count) {
    std::snprintf(buf, sizeof(buf), "%lld of %lld messages repeat the stamp of the one before: the stamps are frozen",
                  static_cast<long long>(c.repeated_stamps), static_cast<long long>(c.count));
    add("fault", buf, Cause::kClock);
  }
  if (c.out_of_order_arrival > 0) {
    std::snprintf(buf, sizeof(buf), "log times step back %lld times: events were written out of time order",
                  static_cast<long long>(c.out_of_order_arrival));
    add("warn", buf, Cause::kSymptom);
  }
  // On a clock of its own, a stream's latency is against its peers' fastest delivery: ahead of that is not a
  // clock running ahead (which that clock's mapping absorbs).
  if (c.latency_valid && !mapped && c.latency_s.p50 < -0.001) {
    std::snprintf(buf, sizeof(buf), "stamps are %.1f ms ahead of arrival: the source clock runs ahead",
                  -c.latency_s.p50 * 1e3);
    add("fault", buf, Cause::kClock);
  }
  // A drift is reported when its confidence interval leaves out zero: jitter alone can tilt a line a little.
  if (c.clock_valid && std::abs(c.clock_drift_ppm) >= 25 &&
      (c.clock_drift_ci_ppm[0] > 0 || c.clock_drift_ci_ppm[1] < 0)) {
    std::snprintf(buf, sizeof(buf), "source clock drifts %.0f ppm (95%%: %.0f to %.0f; %.1f ms per minute)",
                  c.clock_drift_ppm, c.clock_drift_ci_ppm[0], c.clock_drift_ci_ppm[1], c.clock_drift_ppm * 60e-3);
    add(std::abs(c.clock_drift_ppm) >= 100 ? "fault" : "warn", buf, Cause::kClock);
  }
  if (c.bursty) {
    std::snprintf(buf, sizeof(buf),
                  "messages come in bursts of about %.0f, %.1f ms apart, %.2f Hz on average: "
                  "drops are told by seq only",
                  c.burst_size, c.burst_interval_s * 1e3, 1 / c.expected_period_s);
    add("warn", buf, Cause::kSymptom);
  }
  // Without a sequence number and without a period, drops cannot be told: said once for all such streams
  // (diagnose's text), not as a fault of each.
  if (c.irregular && !c.seq_counted) {
    std::snprintf(
        buf, sizeof(buf),
        "no steady period (%.0f%% of the intervals within a quarter of the median), %.2f Hz on average: "
        "%s",
        100 * c.regular_fraction, 1 / c.expected_period_s,
        c.has_header && !c.seq_counted ? "drops are told by seq only" : "drops cannot be told from the times");
    add("warn", buf, Cause::kSymptom);
  }
  if (c.late_stamps > 0) {
    std::snprintf(buf, sizeof(buf),
                  "%lld stamps late by up to %.3f s against the channel's usual latency (the "
                  "first %.1f s into the log): stamped after the fact or by another clock; left out of the clock fit",
                  static_cast<long long>(c.late_stamps), c.late_stamp_max_s, c.first_late_stamp_s);
    add("warn", buf, Cause::kSymptom);
  }
  if (c.latency_valid && c.latency_s.p99 > 0.005 && c.latency_s.p99 > 5 * std::max(c.latency_s.p50, 0.0005)) {
    std::snprintf(buf, sizeof(buf), "latency spikes: p99 %.1f ms against a median of %.1f ms", c.latency_s.p99 * 1e3,
                  c.latency_s.p50 * 1e3);
    add("warn", buf, Cause::kSymptom);
  }
}

}  // namespace

}  // namespace driftlab::analyzers::internal

namespace driftlab::analyzers {

const char* cause_name(Cause c) {
  switch (c) {
    case Cause::kClock: return "clock";
    case Cause::kLate: return "late";
    case Cause::kLoss: return "loss";
    case Cause::kData: return "data";
    case Cause::kSymptom: return "symptom";
  }
  return "symptom";
}

Cause cause_from_name(std::string_view name) {
  for (const Cause c : {Cause::kClock, Cause::kLate, Cause::kLoss, Cause::kData}) {
    if (name == cause_name(c)) return c;
  }
  return Cause::kSymptom;
}

int problem_rank(std::string_view verdict, Cause first_cause, size_t reasons) {
  const int level = verdict == "fault" ? 2 : verdict == "warn" ? 1 : 0;
  if (level == 0) return 0;
  const int cause = static_cast<int>(Cause::kSymptom) - static_cast<int>(first_cause);  // 4: a clock, 0: a symptom
  return level * 100000 + cause * 10000 + static_cast<int>(std::min<size_t>(reasons, 9999));
}

}  // namespace driftlab::analyzers

namespace driftlab::analyzers::internal {

void add_reason(ChannelTiming& c, bool fault, const std::string& why, Cause cause) {
  if (fault || c.verdict == "ok") c.verdict = fault ? "fault" : "warn";
  c.reasons.push_back(why);
  c.causes.push_back(cause);
}

void order_reasons(ChannelTiming& c) {
  std::vector<size_t> order(c.reasons.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return c.causes[a] < c.causes[b]; });
  std::vector<std::string> reasons;
  std::vector<Cause> causes;
  for (size_t i : order) {
    reasons.push_back(std::move(c.reasons[i]));
    causes.push_back(c.causes[i]);
  }
  c.reasons = std::move(reasons);
  c.causes = std::move(causes);
}

bool written_at_once(const Samples& s) {
  if (!s.has_header || s.stamp.size() < 20 || s.stamp.size() != s.arrival.size()) return false;
  const auto [s0, s1] = std::minmax_element(s.stamp.begin(), s.stamp.end());
  const auto [a0, a1] = std::minmax_element(s.arrival.begin(), s.arrival.end());
  const double stamps = seconds_between(*s0, *s1);
  return stamps >= 10.0 && seconds_between(*a0, *a1) <= 0.01 * stamps;
}

ChannelTiming channel_timing(const std::string& name, Samples& s, int64_t log_start,
                             const std::function<int64_t(int64_t)>& to_arrival) {
  if (s.has_header && s.stamp.size() != s.arrival.size()) s.has_header = false;
  ChannelTiming c;
  c.name = name;
  c.type = s.type;
  c.has_header = s.has_header;
  c.seq_counted = s.has_header && s.seq_counted;
  c.malformed = s.malformed;
  c.malformed_example = s.malformed_example;
  c.count = static_cast<int64_t>(s.arrival.size());
  const auto [a0, a1] = std::minmax_element(s.arrival.begin(), s.arrival.end());
  if (c.count > 1 && *a1 > *a0) c.rate_hz = static_cast<double>(c.count - 1) / seconds_between(*a0, *a1);
  for (size_t i = 1; i < s.arrival.size(); ++i) {
    if (s.arrival[i] < s.arrival[i - 1]) ++c.out_of_order_arrival;
  }
  if (written_at_once(s)) {  // a result, not a stream: nothing of its timing to judge
    c.written_at_once = true;
    c.rate_hz = 0;
    return c;
  }
  if (s.has_header) {
    // The median stamp on the source's own clock, by the one quantile definition (core/quantile.h, numpy's), to
    // the nearest microsecond. In doubles the stamps are exact up to 2^53 us (285 years); hostile ones beyond are
    // held inside int64_t.
    Array<int64_t> stamps(s.stamp);
    if (!stamps.empty()) {
      constexpr double kLast = 9223372036854774784.0;  // the largest double below 2^63
      const double median = std::clamp(quantile_in_place(stamps, 0.5), -kLast, kLast);
      c.median_stamp_utime = static_cast<int64_t>(std::llround(median));
    }
    // The rest on the recorder's clock: the stamps mapped through their clock domain for a while (restored below).
    Array<int64_t> own;
    if (to_arrival) {
      own = s.stamp;
      for (auto& t : s.stamp) t = to_arrival(t);
    }
    if (!s.seq_counted) analyse_sequence(s, c);
    analyse_period(s, c, s.seq_counted);
    int64_t newest = INT64_MIN;
    Array<double> latency;
    latency.reserve(s.stamp.size());
    for (size_t i = 0; i < s.stamp.size(); ++i) {
      // A TF channel carries many transforms, often from several publishers: each is judged on its own (tf_check).
      if (!s.is_tf && s.stamp[i] < newest && s.seq[i] != s.seq[i - 1]) ++c.out_of_order_stamp;
      if (i > 0 && s.stamp[i] == s.stamp[i - 1] && s.seq[i] != s.seq[i - 1]) ++c.repeated_stamps;
      c.zero_stamps += s.stamp[i] == 0;
      newest = std::max(newest, s.stamp[i]);
      // A stamp of 0 was never set, and a static transform's says nothing of time (tf2 takes it as timeless).
      if (s.stamp[i] != 0 && !s.is_static_tf) {
        latency.push_back(seconds_between(s.stamp[i], s.arrival[i]) - Duration::from_us(s.ready_after_us).seconds());
      }
    }
    c.latency_valid = !latency.empty();
    c.latency_s = distribution(std::move(latency));
    // The clock is fitted to when the data was complete (a scan's last beam), then the stamps restored.
    for (auto& t : s.stamp) t += s.ready_after_us;
    fit_clock(s, log_start, c);
    for (auto& t : s.stamp) t -= s.ready_after_us;
    if (to_arrival) s.stamp = std::move(own);
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
  judge(c, s, log_start, static_cast<bool>(to_arrival));
  return c;
}

}  // namespace driftlab::analyzers::internal
