#include "analyzers/time_offset.h"

#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numeric>
#include <optional>
#include <vector>

#include "core/quantile.h"

namespace driftlab::analyzers {
namespace {

/// The two motion signals, each independent of the trajectory's frame.
enum Signal { kSpeed = 0, kAngularSpeed = 1 };
constexpr const char* kSignalName[] = {"speed", "angular speed"};

/// The signals are speeds over this long [s] (or two sampling intervals, when longer): long enough to average out
/// the noise finite differences of poses have, short enough to keep a robot's turns and stops (on the TUM RGB-D
/// trajectories a 0.5 s window raises the peak correlation from 0.81-0.89 at one frame to 0.90-0.99).
constexpr double kWindow = 0.5;
/// Poses further apart than this many sampling intervals are a tracking loss: no motion is made up across it.
constexpr double kGapIntervals = 5;
/// Fewer common samples than this give no correlation.
constexpr double kMinSamples = 20;
/// A signal whose best correlation is below this carries no timing (a robot that never turns): left out.
constexpr double kInformative = 0.5;
/// Bounds of the fine search: lags a side, and grid points.
constexpr double kMaxFineLags = 400;
constexpr double kMaxFinePoints = 1 << 20;

enum class Use { kBoth, kSpeed, kAngularSpeed };

/// The correlation a lag gets: the mean of both signals', or the one used.
double combine(Use use, double speed, double angular) {
  switch (use) {
    case Use::kBoth: return std::isnan(speed) ? angular : std::isnan(angular) ? speed : (speed + angular) / 2;
    case Use::kSpeed: return speed;
    case Use::kAngularSpeed: return angular;
  }
  return NAN;
}

/// A sorted trajectory sampled at any time: linear in position, slerp in rotation, between the two poses around
/// it when they are at most max_gap apart (a longer gap is a tracking loss, not motion to invent).
class Sampler {
 public:
  Sampler(const Trajectory& t, double max_gap) : t_(t), max_gap_(max_gap) {}

  bool at(double s, Eigen::Vector3d& p, Eigen::Quaterniond& q) const {
    const auto& st = t_.stamps;
    if (st.empty() || s < st.front() || s > st.back()) return false;
    size_t b = static_cast<size_t>(std::lower_bound(st.begin(), st.end(), s) - st.begin());
    if (st[b] == s) {
      p = t_.positions[b];
      q = t_.orientations[b];
      return true;
    }
    const size_t a = b - 1;  // b > 0: s > st.front()
    const double span = st[b] - st[a];
    if (span > max_gap_) return false;
    const double f = (s - st[a]) / span;
    p = t_.positions[a] + f * (t_.positions[b] - t_.positions[a]);
    q = t_.orientations[a].slerp(f, t_.orientations[b]);
    return true;
  }

  /// Speed [m/s] and angular speed [rad/s] at s, over [s - w/2, s + w/2].
  bool signals(double s, double w, double out[2]) const {
    Eigen::Vector3d p0, p1;
    Eigen::Quaterniond q0, q1;
    if (!at(s - w / 2, p0, q0) || !at(s + w / 2, p1, q1)) return false;
    out[kSpeed] = (p1 - p0).norm() / w;
    out[kAngularSpeed] = rotation_angle(q0.conjugate() * q1) / w;
    return true;
  }

 private:
  const Trajectory& t_;
  double max_gap_;
};

/// Both signals of a trajectory every `step` from `start` (n samples), over windows of `window`; mask 0 where the
/// trajectory has no data.
struct Series {
  std::vector<double> mask;
  std::vector<double> value[2];
};

Series sample(const Sampler& s, double start, double step, size_t n, double window) {
  Series out;
  out.mask.assign(n, 0.0);
  for (auto& v : out.value) v.assign(n, 0.0);
  double sig[2];
  for (size_t i = 0; i < n; ++i) {
    if (!s.signals(start + static_cast<double>(i) * step, window, sig)) continue;
    out.mask[i] = 1;
    out.value[kSpeed][i] = sig[kSpeed];
    out.value[kAngularSpeed][i] = sig[kAngularSpeed];
  }
  // Centred on their means: Pearson's correlation does not change, and the sums below lose less to rounding.
  const double count = std::accumulate(out.mask.begin(), out.mask.end(), 0.0);
  for (auto& v : out.value) {
    if (count == 0) break;
    const double mean = std::accumulate(v.begin(), v.end(), 0.0) / count;
    for (size_t i = 0; i < n; ++i) v[i] = out.mask[i] > 0 ? v[i] - mean : 0.0;
  }
  return out;
}

/// Pearson's correlation from the sums over the n samples both have: sx, sy, sxx, syy, sxy. NaN when either
/// signal is flat there (a robot that does not turn says nothing about time through its angular speed).
double pearson(double n, double sx, double sy, double sxx, double syy, double sxy) {
  const double vx = sxx - sx * sx / n, vy = syy - sy * sy / n;
  if (!(vx > 1e-12 * n) || !(vy > 1e-12 * n)) return NAN;
  return (sxy - sx * sy / n) / std::sqrt(vx * vy);
}

/// Sums c[L] = sum_k a[k] b[k - L] for every lag L in [-(nb - 1), na - 1], stored at L + nb - 1, by FFT.
class Correlator {
 public:
  Correlator(size_t na, size_t nb) : na_(na), nb_(nb) {
    size_ = 1;
    while (size_ < na + nb - 1) size_ *= 2;
  }
  std::vector<std::complex<double>> spectrum(const std::vector<double>& x) {
    std::vector<std::complex<double>> in(size_, 0.0), out;
    for (size_t i = 0; i < x.size(); ++i) in[i] = x[i];
    fft_.fwd(out, in);
    return out;
  }
  std::vector<double> correlate(const std::vector<std::complex<double>>& fa, const std::vector<std::complex<double>>& fb) {
    std::vector<std::complex<double>> prod(size_), out;
    for (size_t i = 0; i < size_; ++i) prod[i] = fa[i] * std::conj(fb[i]);
    fft_.inv(out, prod);
    std::vector<double> c(na_ + nb_ - 1);
    for (size_t k = 0; k < c.size(); ++k) {
      const long lag = static_cast<long>(k) - static_cast<long>(nb_ - 1);
      c[k] = out[static_cast<size_t>(lag < 0 ? lag + static_cast<long>(size_) : lag)].real();
    }
    return c;
  }

 private:
  size_t na_, nb_, size_ = 1;
  Eigen::FFT<double> fft_;
};

std::vector<double> squared(const std::vector<double>& v) {
  std::vector<double> s(v.size());
  for (size_t i = 0; i < v.size(); ++i) s[i] = v[i] * v[i];
  return s;
}

double median_interval(const Trajectory& t) {
  std::vector<double> d;
  d.reserve(t.size());
  for (size_t i = 1; i < t.size(); ++i) d.push_back(t.stamps[i] - t.stamps[i - 1]);
  return quantile_in_place(d, 0.5);
}

/// The vertex of the parabola through (-1, y0), (0, y1), (1, y2), when y1 is a peak: in [-0.5, 0.5].
double parabola_peak(double y0, double y1, double y2) {
  const double denom = y0 - 2 * y1 + y2;
  if (!(denom < 0)) return 0;
  return std::clamp(0.5 * (y0 - y2) / denom, -0.5, 0.5);
}

}  // namespace

TimeOffset estimate_time_offset(const Trajectory& ref, const Trajectory& est, const TimeOffsetOptions& options) {
  TimeOffset r;
  if (!ref.stamped || !est.stamped) {
    r.problem = "a trajectory without stamps has no time to offset";
    return r;
  }
  if (ref.size() < 10 || est.size() < 10) {
    r.problem = "fewer than 10 poses";
    return r;
  }
  const double span_r = ref.stamps.back() - ref.stamps.front(), span_e = est.stamps.back() - est.stamps.front();
  if (!(span_r >= 2.0) || !(span_e >= 2.0)) {
    r.problem = "a trajectory shorter than 2 s";
    return r;
  }
  const double interval = std::max(median_interval(ref), median_interval(est));
  if (!(interval > 0)) {
    r.problem = "the stamps do not advance";
    return r;
  }
  const Sampler sr(ref, kGapIntervals * interval), se(est, kGapIntervals * interval);
  const double window = std::max(kWindow, 2 * interval);
  const double min_overlap = options.min_overlap * std::min(span_r, span_e);

  // Coarse: every lag at once.
  // A fifth of the window; at most 2^17 points over both spans, and 8 per pose (stamps spread by a stray one
  // coarsen the grid, not lengthen the FFTs).
  const double hc = std::max({window / 5, (span_r + span_e) / 131072.0,
                              (span_r + span_e) / (8.0 * static_cast<double>(ref.size() + est.size()))});
  const size_t na = static_cast<size_t>(span_r / hc) + 1, nb = static_cast<size_t>(span_e / hc) + 1;
  const Series a = sample(sr, ref.stamps.front(), hc, na, window);
  const Series b = sample(se, est.stamps.front(), hc, nb, window);
  Correlator corr(na, nb);
  const auto fma = corr.spectrum(a.mask), fmb = corr.spectrum(b.mask);
  const std::vector<double> n = corr.correlate(fma, fmb);
  std::vector<double> curve[2];
  double peak[2] = {-2, -2};
  for (int sig : {kSpeed, kAngularSpeed}) {
    const auto fa = corr.spectrum(a.value[sig]), fb = corr.spectrum(b.value[sig]);
    const auto fa2 = corr.spectrum(squared(a.value[sig])), fb2 = corr.spectrum(squared(b.value[sig]));
    const auto sxy = corr.correlate(fa, fb), sx = corr.correlate(fa, fmb), sy = corr.correlate(fma, fb);
    const auto sxx = corr.correlate(fa2, fmb), syy = corr.correlate(fma, fb2);
    curve[sig].assign(n.size(), NAN);
    for (size_t k = 0; k < n.size(); ++k) {
      const double count = std::round(n[k]);
      if (count * hc < min_overlap || count < kMinSamples) continue;
      curve[sig][k] = pearson(count, sx[k], sy[k], sxx[k], syy[k], sxy[k]);
      if (curve[sig][k] > peak[sig]) peak[sig] = curve[sig][k];
    }
  }
  // Both signals when both follow the motion (each biased its own way: a lever arm between the tracked body and
  // the estimated frame adds to the speed, not to the angular speed), else the better one.
  const Use use = peak[kSpeed] >= kInformative && peak[kAngularSpeed] >= kInformative ? Use::kBoth
                  : peak[kSpeed] >= peak[kAngularSpeed]                                ? Use::kSpeed
                                                                                       : Use::kAngularSpeed;
  if (!(std::max(peak[kSpeed], peak[kAngularSpeed]) > -2)) {
    r.problem = "the two never overlap by half the shorter one's duration, or neither moves";
    return r;
  }
  size_t best_lag = 0;
  double best = -2;
  for (size_t k = 0; k < n.size(); ++k) {
    const double c = combine(use, curve[kSpeed][k], curve[kAngularSpeed][k]);
    if (c > best) {
      best = c;
      best_lag = k;
    }
  }
  const double coarse = (ref.stamps.front() - est.stamps.front()) +
                        (static_cast<double>(best_lag) - static_cast<double>(nb - 1)) * hc;

  // Fine: lags every fiftieth of the window within two coarse steps of the peak, over the time the two share
  // there; the signals are smooth over the window, so sums over every fifth grid point (a tenth of the window)
  // lose nothing. At most kMaxFineLags lags a side and kMaxFinePoints grid points: stamps spread over years (a
  // stray stamp) coarsen the step rather than take the memory.
  const double from = std::max(ref.stamps.front(), est.stamps.front() + coarse) - 2 * hc;
  const double to = std::min(ref.stamps.back(), est.stamps.back() + coarse) + 2 * hc;
  const double hf = std::max({window / 50, 2 * hc / kMaxFineLags, (to - from) / kMaxFinePoints});
  const long lags = static_cast<long>(std::ceil(2 * hc / hf));
  const size_t nf = static_cast<size_t>(std::max(0.0, to - from) / hf) + 1;
  const double t0 = from;
  const Series fa = sample(sr, t0, hf, nf, window);
  // The estimate at ref time t0 + j hf - (coarse + k hf), for k in [-lags, lags]: est index i = j - k + lags.
  const Series fb = sample(se, t0 - coarse - static_cast<double>(lags) * hf, hf, nf + 2 * static_cast<size_t>(lags),
                           window);
  std::vector<double> fine(2 * static_cast<size_t>(lags) + 1, NAN), counts(fine.size(), 0);
  for (long k = -lags; k <= lags; ++k) {
    double c[2] = {NAN, NAN}, cnt = 0;
    for (int sig : {kSpeed, kAngularSpeed}) {
      const auto& x = fa.value[sig];
      const auto& y = fb.value[sig];
      double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
      cnt = 0;
      for (size_t j = 0; j < nf; j += 5) {
        const size_t i = static_cast<size_t>(static_cast<long>(j) - k + lags);
        if (fa.mask[j] == 0 || fb.mask[i] == 0) continue;
        cnt += 1;
        sx += x[j];
        sy += y[i];
        sxx += x[j] * x[j];
        syy += y[i] * y[i];
        sxy += x[j] * y[i];
      }
      if (cnt * 5 * hf >= min_overlap && cnt >= kMinSamples) c[sig] = pearson(cnt, sx, sy, sxx, syy, sxy);
    }
    const size_t at = static_cast<size_t>(k + lags);
    counts[at] = cnt * 5;
    fine[at] = combine(use, c[kSpeed], c[kAngularSpeed]);
  }
  size_t top = fine.size();
  for (size_t k = 0; k < fine.size(); ++k) {
    if (!std::isnan(fine[k]) && (top == fine.size() || fine[k] > fine[top])) top = k;
  }
  if (top == fine.size()) {
    r.problem = "the fine search found no overlap";
    return r;
  }
  double refine = 0;
  if (top > 0 && top + 1 < fine.size() && !std::isnan(fine[top - 1]) && !std::isnan(fine[top + 1])) {
    refine = parabola_peak(fine[top - 1], fine[top], fine[top + 1]);
  }
  r.found = true;
  r.offset_s = coarse + (static_cast<double>(top) - static_cast<double>(lags) + refine) * hf;
  r.confidence = std::max(0.0, fine[top]);
  r.signal = use == Use::kBoth ? "speed and angular speed" : kSignalName[use == Use::kSpeed ? kSpeed : kAngularSpeed];
  r.overlap_s = counts[top] * hf;
  return r;
}

}  // namespace driftlab::analyzers
