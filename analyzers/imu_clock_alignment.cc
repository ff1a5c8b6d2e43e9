#include "analyzers/imu_clock_alignment.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>

#include "analyzers/correlation.h"
#include "analyzers/time_offset.h"
#include "analyzers/trajectory.h"

namespace driftlab::analyzers {
namespace {

/// The drift is measured on overlaps at least this long [s]: over shorter ones a drift of tens of ppm moves the
/// offset by less than the offset's own uncertainty (a millisecond), so there is nothing to fit.
constexpr double kMinDriftSpan = 120;
/// Each segment is at least this long [s], so that each has turns of its own to correlate, and there are at most
/// this many: enough points for a line and its interval, each still long.
constexpr double kMinSegment = 30;
constexpr int kMaxSegments = 8;
/// A segment's offset counts for the drift when its own correlation is confident (analyzers/correlation.h) and it
/// lies within this of the whole overlap's offset [s] (a clock drifting 100 ppm moves by 0.36 s in an hour; a
/// segment further off matched another stretch of similar motion).
constexpr double kSegmentAgreement = 0.5;
/// Fewer segments than this give no line with an interval worth the name.
constexpr int kMinDriftSegments = 4;

/// The rates as a trajectory estimate_time_offset correlates: its position the angle turned so far, along x, so
/// that its speed over a window is the mean of |rate| over it, the same in any body frame; its orientation fixed
/// (the angular speed flat, left out). Not the orientation the rates integrate to: a vehicle that vibrates or rocks
/// turns back and forth, so its net rotation over a window is mostly the gyro's bias (on the shared FMUv4-Pro flight
/// the net rotation's correlation with a 50 Hz copy of itself with 0.005 rad/s of noise, at the true lag, is 0.04),
/// and averaged with the mean |rate|'s it biased the offset by 15 ms. A step across a gap longer than five median
/// intervals is not integrated (the Sampler does not interpolate across one either).
Trajectory integrate(const AngularRates& r) {
  Trajectory t;
  std::vector<double> steps;
  for (size_t i = 1; i < r.stamps.size(); ++i) steps.push_back(r.stamps[i] - r.stamps[i - 1]);
  double median = 0;
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
    median = steps[steps.size() / 2];
  }
  double turned = 0;
  for (size_t i = 0; i < r.stamps.size(); ++i) {
    if (i > 0) {
      const double dt = r.stamps[i] - r.stamps[i - 1];
      const double w = 0.5 * (r.rates[i].norm() + r.rates[i - 1].norm());
      if (dt > 0 && dt <= 5 * median && std::isfinite(w)) turned += w * dt;
    }
    t.push_back(r.stamps[i], Eigen::Vector3d(turned, 0, 0), Eigen::Quaterniond::Identity());
  }
  return t;
}

/// The rows of t from index a (inclusive) to b (exclusive).
Trajectory slice(const Trajectory& t, size_t a, size_t b) {
  Trajectory s;
  for (size_t i = a; i < b; ++i) s.push_back(t.stamps[i], t.positions[i], t.orientations[i]);
  return s;
}

/// Student's t for a two-sided 95% interval at dof degrees of freedom (1..10; 1.96 beyond).
double student_t95(int dof) {
  constexpr std::array<double, 10> kT = {12.71, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228};
  return dof >= 1 && dof <= 10 ? kT[static_cast<size_t>(dof - 1)] : 1.96;
}

/// Fits offset = a + drift (t - at) to the segments' offsets, at their mean time.
void fit_drift(const std::vector<std::pair<double, double>>& points, ClockAlignment& out) {
  const double n = static_cast<double>(points.size());
  double mt = 0, mo = 0;
  for (const auto& [t, o] : points) {
    mt += t / n;
    mo += o / n;
  }
  double stt = 0, sto = 0;
  for (const auto& [t, o] : points) {
    stt += (t - mt) * (t - mt);
    sto += (t - mt) * (o - mo);
  }
  if (!(stt > 0)) return;
  const double slope = sto / stt;
  double sse = 0;
  for (const auto& [t, o] : points) sse += std::pow(o - mo - slope * (t - mt), 2);
  const int dof = static_cast<int>(points.size()) - 2;
  const double se = std::sqrt(sse / dof / stt);
  out.drift_measured = true;
  out.segments = static_cast<int>(points.size());
  out.drift_measured_value = slope;
  out.drift_ci95 = student_t95(dof) * se;
  if (std::abs(slope) > out.drift_ci95) {
    out.drift_applied = true;
    out.drift = slope;
    out.offset_s = mo;
    out.at_s = mt;
  }
}

}  // namespace

ClockAlignment align_imu_clocks(const AngularRates& reference, const AngularRates& other) {
  ClockAlignment out;
  const Trajectory ref = integrate(reference), oth = integrate(other);
  const TimeOffset whole = estimate_time_offset(ref, oth);
  if (!whole.found) {
    out.problem = whole.problem;
    return out;
  }
  out.confidence = whole.confidence;
  out.overlap_s = whole.overlap_s;
  if (whole.confidence < kConfidentCorrelation) {
    char why[160];
    std::snprintf(why, sizeof(why), "the IMUs' angular rates do not match (best correlation %.2f, below %.1f)",
                  whole.confidence, kConfidentCorrelation);
    out.problem = why;
    return out;
  }
  out.found = true;
  out.offset_s = whole.offset_s;
  // The middle of the overlap on the other clock.
  const double from = std::max(oth.stamps.front(), ref.stamps.front() - whole.offset_s);
  const double to = std::min(oth.stamps.back(), ref.stamps.back() - whole.offset_s);
  out.at_s = 0.5 * (from + to);
  if (to - from < kMinDriftSpan) return out;

  const int n = std::min(kMaxSegments, static_cast<int>((to - from) / kMinSegment));
  std::vector<std::pair<double, double>> points;
  TimeOffsetOptions whole_segment;
  whole_segment.min_overlap = 0.9;  // a segment lies inside the overlap: it must be matched nearly whole
  for (int k = 0; k < n; ++k) {
    const double a = from + (to - from) * k / n, b = from + (to - from) * (k + 1) / n;
    const auto lo = std::lower_bound(oth.stamps.begin(), oth.stamps.end(), a);
    const auto hi = std::lower_bound(oth.stamps.begin(), oth.stamps.end(), b);
    const Trajectory seg =
        slice(oth, static_cast<size_t>(lo - oth.stamps.begin()), static_cast<size_t>(hi - oth.stamps.begin()));
    const TimeOffset o = estimate_time_offset(ref, seg, whole_segment);
    if (o.found && o.confidence >= kConfidentCorrelation &&
        std::abs(o.offset_s - whole.offset_s) <= kSegmentAgreement) {
      points.emplace_back(0.5 * (a + b), o.offset_s);
    }
  }
  if (static_cast<int>(points.size()) >= kMinDriftSegments) fit_drift(points, out);
  return out;
}

}  // namespace driftlab::analyzers
