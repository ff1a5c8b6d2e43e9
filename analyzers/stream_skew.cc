#include "analyzers/internal/stream_skew.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <thread>

#include "core/huge_page_allocator.h"
#include "core/time.h"
#include "driftlab/laser_scan_t.hpp"
#include "lcmtypes/planar.h"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers::internal {
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
  // Each range that is not a measurement (not positive, or not finite) as NaN, so a difference involving one is
  // NaN; the previous scan with max_shift beams before and after it (wrapped around on a full circle, NaN where
  // the scan does not reach), so a shift never needs an index check. Scratch reused from scan to scan.
  thread_local std::vector<float> cur, prev;
  auto measured = [](float r) { return r > 0 && r < INFINITY ? r : NAN; };
  cur.resize(static_cast<size_t>(n));
  prev.assign(static_cast<size_t>(n) + 2 * static_cast<size_t>(max_shift), NAN);
  for (int j = 0; j < n; ++j) cur[static_cast<size_t>(j)] = measured(current[static_cast<size_t>(j)]);
  for (int m = 0; m < n + 2 * max_shift; ++m) {
    int i = m - max_shift;
    if (full_circle) i = i < 0 ? i + n : (i >= n ? i - n : i);
    if (i >= 0 && i < n) prev[static_cast<size_t>(m)] = measured(previous[static_cast<size_t>(i)]);
  }
  // Mean squared range difference at shift k, over every step-th beam, where both beams are measurements. Four
  // sums, each of every fourth beam taken, so that no addition waits for the one before (the pass spent a fifth
  // of its time here with one).
  auto cost_at = [&](int k, int step) {
    const float* a = cur.data();
    const float* b = prev.data() + max_shift + k;
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;  // named, so they stay in registers
    int u0 = 0, u1 = 0, u2 = 0, u3 = 0;
    auto add = [](float d, double& sum, int& used) {
      if (d == d) {
        sum += d * d;
        ++used;
      }
    };
    int j = 0;
    for (; j + 3 * step < n; j += 4 * step) {
      add(a[j] - b[j], s0, u0);
      add(a[j + step] - b[j + step], s1, u1);
      add(a[j + 2 * step] - b[j + 2 * step], s2, u2);
      add(a[j + 3 * step] - b[j + 3 * step], s3, u3);
    }
    for (; j < n; j += step) add(a[j] - b[j], s0, u0);
    const int used = u0 + u1 + u2 + u3;
    const int tried = (n + step - 1) / step;
    return used > tried / 2 ? ((s0 + s1) + (s2 + s3)) / used : INFINITY;
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
    const int at = k + max_shift;  // >= 0
    cost[static_cast<size_t>(at)] = cost_at(k, 2);
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

/// The yaw rate between two consecutive scans, at their midpoint, where it can be told.
std::optional<std::pair<double, double>> scan_motion(const driftlab::laser_scan_t& previous,
                                                     const driftlab::laser_scan_t& current) {
  const double ti = Time::from_us(current.header.utime).seconds();
  const double tp = Time::from_us(previous.header.utime).seconds();
  if (!(ti > tp)) return std::nullopt;
  const double span = static_cast<double>(current.angle_increment) * static_cast<double>(current.nranges);
  const auto d =
      scan_rotation(previous.ranges, current.ranges, current.angle_increment, std::abs(span - 2 * M_PI) < 0.05);
  if (!d) return std::nullopt;
  // Beams are measured through the scan: on average half its duration after the stamp.
  const double beams = 0.5 * (current.nranges - 1) * std::max(0.0f, current.time_increment);
  return std::pair{0.5 * (ti + tp) + (beams < 1.0 ? beams : 0.0), *d / (ti - tp)};
}

}  // namespace

/// A channel's scans, as the pass meets them: the last one decoded, to measure the rotation to the next.
struct ScanMotion {
  driftlab::laser_scan_t previous, current;
  bool have_previous = false;
  std::span<const uint8_t> first;  // the stretch's first scan, for the rotation across a join (append_samples)
  size_t first_at = 0;             // motion_t.size() when it came
};

namespace {

void add_scan(Samples& s, std::span<const uint8_t> data) {
  ScanMotion& m = *s.scan;
  if (!lcmtypes::decode(data, m.current)) {
    m.have_previous = false;
    return;
  }
  if (m.have_previous) {
    if (const auto tw = scan_motion(m.previous, m.current)) {
      s.motion_t.push_back(tw->first);
      s.motion_w.push_back(tw->second);
    }
  }
  std::swap(m.previous, m.current);
  m.have_previous = true;
}

}  // namespace

void add_motion(Samples& s, int64_t fingerprint, std::span<const uint8_t> data) {
  if (fingerprint == driftlab::laser_scan_t::getHash()) {
    if (!s.scan) {
      s.ready_after_us = lcmtypes::ready_after_us(data);
      s.scan = std::make_shared<ScanMotion>();
      s.scan->first = data;
      s.scan->first_at = s.motion_t.size();
    }
    add_scan(s, data);
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
  if (!s.have_last) {
    s.first_yaw = value;
    s.first_t = t;
    s.first_pose_at = s.motion_t.size();
  }
  if (s.have_last && t > s.last_t) {
    s.motion_t.push_back(0.5 * (t + s.last_t));
    s.motion_w.push_back(wrap_angle(value - s.last_yaw) / (t - s.last_t));
  }
  s.last_yaw = value;
  s.last_t = t;
  s.have_last = true;
}

bool append_samples(Samples& a, Samples& b) {
  // One pass decides at a channel's first message whether it has a header; b must begin as a ended.
  if (a.type != b.type || b.header_at_start != a.has_header) return false;
  if ((a.have_last || b.have_last) && (a.scan || b.scan)) return false;  // poses and scans on one channel
  auto append = [](auto& to, const auto& from) { to.insert(to.end(), from.begin(), from.end()); };
  if (a.malformed == 0) a.malformed_example = b.malformed_example;
  a.malformed += b.malformed;
  append(a.arrival, b.arrival);
  if (a.has_header && a.stamp.empty()) a.frame = b.frame;  // the first stamped message's
  if (a.has_header && !b.has_header) {  // lost in b, at the message where one pass would have lost it
    a.seq.clear();
    a.stamp.clear();
  }
  a.has_header = b.has_header;
  if (a.has_header) {
    append(a.seq, b.seq);
    append(a.stamp, b.stamp);
  }
  append(a.digest, b.digest);
  // The yaw rate across the join (from a's last pose or scan to b's first), where one pass would have put it.
  std::optional<std::pair<double, double>> join;
  size_t at = 0;
  if (a.have_last && b.have_last && b.first_t > a.last_t) {
    join = {0.5 * (b.first_t + a.last_t), wrap_angle(b.first_yaw - a.last_yaw) / (b.first_t - a.last_t)};
    at = b.first_pose_at;
  }
  if (a.scan && a.scan->have_previous && b.scan && lcmtypes::decode(b.scan->first, b.scan->current)) {
    join = scan_motion(a.scan->previous, b.scan->current);
    at = b.scan->first_at;
  }
  const auto split = static_cast<std::ptrdiff_t>(at);
  a.motion_t.insert(a.motion_t.end(), b.motion_t.begin(), b.motion_t.begin() + split);
  a.motion_w.insert(a.motion_w.end(), b.motion_w.begin(), b.motion_w.begin() + split);
  if (join) {
    a.motion_t.push_back(join->first);
    a.motion_w.push_back(join->second);
  }
  a.motion_t.insert(a.motion_t.end(), b.motion_t.begin() + split, b.motion_t.end());
  a.motion_w.insert(a.motion_w.end(), b.motion_w.begin() + split, b.motion_w.end());
  a.motion_from_pose = a.motion_from_pose || b.motion_from_pose;
  if (b.have_last) {
    a.last_yaw = b.last_yaw;
    a.last_t = b.last_t;
    a.have_last = true;
  }
  if (b.scan) {
    if (!a.scan) a.ready_after_us = b.ready_after_us;
    a.scan = std::move(b.scan);
  }
  return true;
}

namespace {

/// Whether two channels carry the same stamps, message for message (90% of each one's stamps appear in the
/// other): stamped by one clock at one instant, as a scan and the pose logged with it, so there is no skew between
/// them to measure, whatever a correlation of their motion says. Streams at different rates on one clock (a 200 Hz
/// IMU, 100 Hz ground truth) share only some stamps and are still compared.
bool same_stamps(const Samples& a, const Samples& b) {
  if (a.stamp.empty() || b.stamp.empty()) return false;
  const size_t most = std::max(a.stamp.size(), b.stamp.size());
  // 90% of the larger in common needs the smaller to be as large.
  if (std::min(a.stamp.size(), b.stamp.size()) * 10 < most * 9) return false;
  // Sorted copies only where the stamps are not already in order (they nearly always are).
  Array<int64_t> x_copy, y_copy;
  auto in_order = [](const Array<int64_t>& stamps, Array<int64_t>& copy) -> const Array<int64_t>& {
    if (std::is_sorted(stamps.begin(), stamps.end())) return stamps;
    copy = stamps;
    std::sort(copy.begin(), copy.end());
    return copy;
  };
  const Array<int64_t>& x = in_order(a.stamp, x_copy);
  const Array<int64_t>& y = in_order(b.stamp, y_copy);
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
  return common * 10 >= most * 9;
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
  HugeVector<float> v;  // 4 million points an hour: on huge pages, a page fault per 2 MiB
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
    // Two of each sum, of alternate points (named, so they stay in registers), so that no addition waits for the
    // one before.
    double sum0 = 0, sum1 = 0, sq0 = 0, sq1 = 0, dot0 = 0, dot1 = 0;
    size_t i = 0;
    for (; i + step < n; i += 2 * step) {
      const double v0 = y[i], v1 = y[i + step];
      sum0 += v0;
      sum1 += v1;
      sq0 += v0 * v0;
      sq1 += v1 * v1;
      dot0 += (sa[i] - mean_a) * v0;
      dot1 += (sa[i + step] - mean_a) * v1;
    }
    if (i < n) {
      const double v = y[i];
      sum0 += v;
      sq0 += v * v;
      dot0 += (sa[i] - mean_a) * v;
    }
    const size_t points_used = (n + step - 1) / step;  // whole points, as the loop counted them
    const auto count = static_cast<double>(points_used);
    const double sum = sum0 + sum1, sum_sq = sq0 + sq1, dot = dot0 + dot1;
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

/// Windows whose lag lies within this of the pair's offset agree with it [s]: twice the 1 ms search step.
constexpr double kSkewAgreement_s = 0.002;

/// The skew of b against a over the windows of their common time.
std::optional<StreamPair> skew(const std::string& a_name, const Samples& a, const Grid& ga, const std::string& b_name,
                               const Samples& b, const Grid& gb, double log_start, const DiagnoseOptions& options) {
  const double from = std::max(a.motion_t.front(), b.motion_t.front()) - log_start;
  const double to = std::min(a.motion_t.back(), b.motion_t.back()) - log_start;
  StreamPair p{a_name, b_name, 0, {}, 0, "yaw-rate cross-correlation", {}, {}};
  // Windows (at most 64: long logs get longer ones) show changes along the log; the pair's offset is their
  // confidence-weighted median (its confidence and interval below). A short log is one window.
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
  // The confidence: how well the streams' motions match (the windows' median peak correlation) times how well
  // the windows agree on the lag (the correlation-weighted share of them within kSkewAgreement_s of the pair's
  // offset). A peak correlation alone says the two signals look alike, not that the lag is known: on simulated
  // logs the scans' coarse rotation gave windows scattered over +-90 ms, each correlating at 0.9: the peak
  // correlation was 0.8 or more for all 180 pairs of the calibration study and 93 of them were wrong by more than
  // 2 ms (docs/diagnosis.md, "Calibration"). One window agrees with itself.
  Array<double> confidences;
  double agreeing = 0;
  for (const auto& w : p.windows) {
    confidences.push_back(w.confidence);
    if (std::abs(w.offset_s - p.offset_s) <= kSkewAgreement_s) agreeing += w.confidence;
  }
  p.confidence = median(std::move(confidences)) * agreeing / total;
  // The interval: the median's order statistics over the windows' offsets (distribution-free; with five windows
  // their smallest and largest, which hold the median 94% of the time), at least the 1 ms search step.
  Array<double> offsets;
  for (const auto& w : by_offset) offsets.push_back(w.offset_s);
  const auto [lo, hi] = median_ci_ranks(offsets.size());
  p.offset_ci_s = {std::min(offsets[lo], p.offset_s - Grid::kStep), std::max(offsets[hi], p.offset_s + Grid::kStep)};
  return p;
}

}  // namespace

PairPlan plan_pairs(const std::map<std::string, Samples, std::less<>>& channels) {
  PairPlan plan;
  auto& moving = plan.moving;
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
  for (size_t i = 0; i < moving.size(); ++i) {
    for (size_t j = i + 1; j < moving.size(); ++j) {
      if (!same_stamps(moving[i]->second, moving[j]->second)) plan.jobs.emplace_back(i, j);
    }
  }
  return plan;
}

std::vector<StreamPair> stream_pairs(const PairPlan& plan, int64_t start_utime, int64_t end_utime,
                                     const DiagnoseOptions& options) {
  const auto& moving = plan.moving;
  const auto& jobs = plan.jobs;
  const double log_start = Time::from_us(start_utime).seconds();
  const double log_end = Time::from_us(end_utime).seconds();
  // Each channel's grid, then each pair, is independent: two threads share them (this machine has two cores).
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
  std::vector<StreamPair> out;
  for (auto& r : results) {
    if (r) out.push_back(std::move(*r));
  }
  return out;
}

}  // namespace driftlab::analyzers::internal
