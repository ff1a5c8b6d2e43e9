#include "analyzers/trajectory.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numeric>

#include "core/quantile.h"

namespace driftlab::analyzers {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

/// Indices of t's stamps in ascending order of (stamp + shift), ties by index; run_start[k] is the first
/// position of the run of equal values that position k belongs to.
struct SortedStamps {
  PoseArray<double> values;
  PoseArray<size_t> index;
  PoseArray<size_t> run_start;

  SortedStamps(const PoseArray<double>& stamps, double shift) {
    const size_t n = stamps.size();
    PoseArray<double> shifted(n);
    for (size_t k = 0; k < n; ++k) shifted[k] = stamps[k] + shift;  // as numpy: stamps + offset
    index.resize(n);
    std::iota(index.begin(), index.end(), 0);
    if (!std::is_sorted(shifted.begin(), shifted.end())) {
      std::stable_sort(index.begin(), index.end(), [&](size_t a, size_t b) { return shifted[a] < shifted[b]; });
    }
    values.resize(n);
    run_start.resize(n);
    for (size_t k = 0; k < n; ++k) {
      values[k] = shifted[index[k]];
      run_start[k] = (k > 0 && values[k] == values[k - 1]) ? run_start[k - 1] : k;
    }
  }

  /// numpy's argmin(|values - t|) over the original order: the nearest value, the smallest index on ties.
  /// hint: position to search from (queries in ascending order make this a linear merge).
  size_t nearest(double t, size_t& hint) const {
    size_t p = hint;
    if (p > 0 && values[p - 1] >= t) p = std::lower_bound(values.begin(), values.end(), t) - values.begin();
    while (p < values.size() && values[p] < t) ++p;
    hint = p;
    size_t best = std::numeric_limits<size_t>::max();
    double best_d = std::numeric_limits<double>::infinity();
    auto consider = [&](size_t pos) {
      const size_t first = run_start[pos];  // smallest index among equal values
      const double d = std::abs(values[first] - t);
      if (best == std::numeric_limits<size_t>::max() || d < best_d || (d == best_d && index[first] < index[best])) {
        best_d = d;
        best = first;
      }
    };
    if (p < values.size()) consider(p);
    if (p > 0) consider(p - 1);
    return best;
  }
};

/// Appends pose i of in, its orientation normalised.
void append(Trajectory& out, const Trajectory& in, size_t i) {
  out.push_back(in.stamps[i], in.positions[i], in.orientations[i].normalized());
}

void reserve(Matched& m, size_t n) {
  for (Trajectory* t : {&m.ref, &m.est}) {
    t->stamps.reserve(n);
    t->positions.reserve(n);
    t->orientations.reserve(n);
  }
}

double round_2_significant(double x) {
  if (x <= 0) return x;
  const double magnitude = std::pow(10.0, std::floor(std::log10(x)) - 1);
  return std::round(x / magnitude) * magnitude;
}

}  // namespace

double Trajectory::path_length() const {
  double length = 0;
  for (size_t i = 1; i < positions.size(); ++i) length += (positions[i] - positions[i - 1]).norm();
  return length;
}

StampOrder sort_by_stamp(Trajectory& t) {
  StampOrder o;
  const size_t n = t.size();
  for (size_t i = 1; i < n; ++i) {
    if (t.stamps[i] < t.stamps[i - 1] && o.out_of_order++ == 0) o.first_out_of_order = t.stamps[i];
  }
  if (o.out_of_order > 0) {
    PoseArray<size_t> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return t.stamps[a] < t.stamps[b]; });
    Trajectory sorted;
    sorted.stamps.reserve(n);
    sorted.positions.reserve(n);
    sorted.orientations.reserve(n);
    for (size_t i : order) sorted.push_back(t.stamps[i], t.positions[i], t.orientations[i]);
    sorted.stamped = t.stamped;
    t = std::move(sorted);
  }
  for (size_t i = 1; i < n; ++i) {
    if (t.stamps[i] == t.stamps[i - 1] && o.repeated++ == 0) o.first_repeated = t.stamps[i];
  }
  return o;
}

Stats compute_stats(PoseArray<double> e) {
  Stats s;
  s.count = e.size();
  if (e.empty()) return s;
  const double n = static_cast<double>(e.size());
  double sum = 0, sum_sq = 0;
  s.min = s.max = e[0];
  for (double v : e) {
    sum += v;
    sum_sq += v * v;
    s.min = std::min(s.min, v);
    s.max = std::max(s.max, v);
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  double var = 0;
  for (double v : e) var += (v - s.mean) * (v - s.mean);
  s.std = std::sqrt(var / n);
  s.median = quantile_in_place(e, 0.5);
  return s;
}

Matched match_nearest(const Trajectory& ref, const Trajectory& est, double max_dt, double offset) {
  Matched m;
  if (ref.size() == 0 || est.size() == 0) return m;
  const bool est_longer = est.size() > ref.size();
  const Trajectory& longer = est_longer ? est : ref;
  const Trajectory& shorter = est_longer ? ref : est;
  const SortedStamps sorted(longer.stamps, est_longer ? offset : -offset);
  reserve(m, shorter.size());
  size_t hint = 0;
  for (size_t s = 0; s < shorter.size(); ++s) {
    const size_t pos = sorted.nearest(shorter.stamps[s], hint);
    if (!(std::abs(sorted.values[pos] - shorter.stamps[s]) <= max_dt)) continue;
    const size_t l = sorted.index[pos];
    append(m.ref, ref, est_longer ? s : l);
    append(m.est, est, est_longer ? l : s);
  }
  return m;
}

Matched match_interpolated(const Trajectory& ref, const Trajectory& est, double max_gap, double offset) {
  Matched m;
  if (ref.size() < 2) return m;
  const SortedStamps sorted(ref.stamps, 0.0);
  size_t hint = 0;
  for (size_t e = 0; e < est.size(); ++e) {
    const double t = est.stamps[e] + offset;
    sorted.nearest(t, hint);  // hint: first position with value >= t
    const size_t p = hint;
    if (p == sorted.values.size()) continue;
    size_t a, b;
    if (sorted.values[p] == t) {
      a = b = sorted.index[sorted.run_start[p]];
    } else {
      if (p == 0) continue;
      a = sorted.index[p - 1];
      b = sorted.index[p];
      if (ref.stamps[b] - ref.stamps[a] > max_gap) continue;
    }
    const double alpha = a == b ? 0.0 : (t - ref.stamps[a]) / (ref.stamps[b] - ref.stamps[a]);
    m.ref.push_back(t, ref.positions[a] + alpha * (ref.positions[b] - ref.positions[a]),
                    ref.orientations[a].normalized().slerp(alpha, ref.orientations[b].normalized()));
    m.est.push_back(t, est.positions[e], est.orientations[e].normalized());
  }
  return m;
}

std::string explain_no_match(const Trajectory& ref, const Trajectory& est, double max_dt, double offset) {
  char buf[512];
  if (ref.size() == 0 || est.size() == 0) {
    std::snprintf(buf, sizeof(buf), "the %s trajectory has no poses", ref.size() == 0 ? "reference" : "estimated");
    return buf;
  }
  const auto [r0, r1] = std::minmax_element(ref.stamps.begin(), ref.stamps.end());
  const auto [e0, e1] = std::minmax_element(est.stamps.begin(), est.stamps.end());
  const double est_start = *e0 + offset, est_end = *e1 + offset;
  // The closest pair, over every estimate stamp.
  const SortedStamps sorted(ref.stamps, 0.0);
  size_t hint = 0;
  double best = std::numeric_limits<double>::infinity(), best_ref = 0, best_est = 0;
  PoseArray<double> queries(est.stamps);
  std::sort(queries.begin(), queries.end());
  for (double q : queries) {
    const size_t pos = sorted.nearest(q + offset, hint);
    const double d = std::abs(sorted.values[pos] - (q + offset));
    if (d < best) {
      best = d;
      best_ref = sorted.values[pos];
      best_est = q + offset;
    }
  }
  int n = std::snprintf(buf, sizeof(buf),
                        "no estimated pose is within %g s of a reference pose: reference spans %.6f..%.6f s, "
                        "estimate (with offset %g s) %.6f..%.6f s; the closest pair is %.6f s apart "
                        "(reference %.6f s, estimate %.6f s)",
                        max_dt, *r0, *r1, offset, est_start, est_end, best, best_ref, best_est);
  if (est_end < *r0 || est_start > *r1) {
    std::snprintf(buf + n, sizeof(buf) - n, "; the time ranges do not overlap: try --offset %.6f to align the starts",
                  offset + (*r0 - est_start));
  } else {
    std::snprintf(buf + n, sizeof(buf) - n, "; try --max-dt %.3g or --interpolate", best * 1.01);
  }
  return buf;
}

const char* to_string(AlignmentType type) {
  switch (type) {
    case AlignmentType::kNone: return "none";
    case AlignmentType::kSe3: return "se3";
    case AlignmentType::kSim3: return "sim3";
    case AlignmentType::kPosYaw: return "posyaw";
    case AlignmentType::kOrigin: return "origin";
  }
  return "none";
}

Alignment align(const Matched& m, AlignmentType type) {
  Alignment a;
  a.type = type;
  const size_t n = m.est.size();
  if (type == AlignmentType::kNone) return a;
  if (type == AlignmentType::kOrigin) {
    // evo's align_origin: the rigid motion that takes the first matched estimate pose onto the first matched
    // reference pose, T = T_ref0 T_est0^-1, applied to every estimate pose.
    if (n == 0) {
      a.problem = "no matched pose, origin alignment needs 1";
      return a;
    }
    a.rotation =
        (m.ref.orientations[0].normalized() * m.est.orientations[0].normalized().conjugate()).toRotationMatrix();
    a.translation = m.ref.positions[0] - a.rotation * m.est.positions[0];
    return a;
  }
  const size_t needed = type == AlignmentType::kPosYaw ? 2 : 3;
  if (n < needed) {
    a.problem = std::to_string(n) + " matched pose" + (n == 1 ? "" : "s") + ", " + to_string(type) + " alignment needs " +
                std::to_string(needed);
    return a;
  }
  Eigen::Matrix3Xd src(3, n), dst(3, n);
  for (size_t i = 0; i < n; ++i) {
    src.col(static_cast<long>(i)) = m.est.positions[i];
    dst.col(static_cast<long>(i)) = m.ref.positions[i];
  }
  const Eigen::Vector3d mu_src = src.rowwise().mean(), mu_dst = dst.rowwise().mean();
  if (type == AlignmentType::kPosYaw) {
    // Rotation about z only: the yaw that best maps the centred est xy onto the centred ref xy.
    double sin_sum = 0, cos_sum = 0, src_spread = 0, dst_spread = 0;
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d s = src.col(static_cast<long>(i)) - mu_src, d = dst.col(static_cast<long>(i)) - mu_dst;
      cos_sum += s.x() * d.x() + s.y() * d.y();
      sin_sum += s.x() * d.y() - s.y() * d.x();
      src_spread += s.head<2>().squaredNorm();
      dst_spread += d.head<2>().squaredNorm();
    }
    const double spread = src_spread + dst_spread;
    if (spread > 0 && (src_spread == 0 || dst_spread == 0)) {
      // One side stands still (an estimator that froze): every yaw puts its positions at the same place, so the
      // position error does not depend on the yaw; the means are matched and the yaw left at 0.
      a.translation = mu_dst - mu_src;
      return a;
    }
    if (!(std::hypot(sin_sum, cos_sum) > 1e-12 * spread) || !(spread > 0)) {
      a.problem = "the matched positions do not move in x and y, so no yaw aligns them";
      return a;
    }
    a.rotation = Eigen::AngleAxisd(std::atan2(sin_sum, cos_sum), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    a.translation = mu_dst - a.rotation * mu_src;
    return a;
  }
  // Umeyama needs the cross-covariance to have rank 2 at least (evo checks the same: singular values above the
  // machine epsilon): points all on one point or one line leave a rotation about that line free.
  const Eigen::Matrix3d cov = (dst.colwise() - mu_dst) * (src.colwise() - mu_src).transpose() / static_cast<double>(n);
  const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(cov).singularValues();
  if ((sv.array() > std::numeric_limits<double>::epsilon()).count() < 2 || !sv.allFinite()) {
    a.problem = "the matched positions lie on one point or one line, which leaves the " + std::string(to_string(type)) +
                " alignment undetermined";
    return a;
  }
  // Eigen's Umeyama: the same closed form evo uses (SVD of the cross-covariance, reflection fixed).
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, type == AlignmentType::kSim3);
  a.scale = type == AlignmentType::kSim3 ? t.block<3, 3>(0, 0).col(0).norm() : 1.0;
  a.rotation = t.block<3, 3>(0, 0) / a.scale;
  a.translation = t.block<3, 1>(0, 3);
  return a;
}

Trajectory apply(const Alignment& a, Trajectory t) {
  const Eigen::Quaterniond q(a.rotation);
  for (size_t i = 0; i < t.size(); ++i) {
    t.positions[i] = a.scale * (a.rotation * t.positions[i]) + a.translation;
    t.orientations[i] = (q * t.orientations[i]).normalized();
  }
  return t;
}

double rotation_angle(const Eigen::Quaterniond& q) { return 2 * std::atan2(q.vec().norm(), std::abs(q.w())); }

ApeResult ape(const Matched& m) {
  ApeResult r;
  const size_t n = m.ref.size();
  r.trans_errors.resize(n);
  r.rot_errors_deg.resize(n);
  for (size_t i = 0; i < n; ++i) {
    r.trans_errors[i] = (m.est.positions[i] - m.ref.positions[i]).norm();
    const Eigen::Quaterniond e = m.ref.orientations[i].conjugate() * m.est.orientations[i];
    r.rot_errors_deg[i] = rotation_angle(e) * kRadToDeg;
  }
  r.trans = compute_stats(r.trans_errors);
  r.rot_deg = compute_stats(r.rot_errors_deg);
  return r;
}

const char* to_string(DeltaUnit unit) {
  switch (unit) {
    case DeltaUnit::kFrames: return "frames";
    case DeltaUnit::kMeters: return "m";
    case DeltaUnit::kSeconds: return "s";
    case DeltaUnit::kDegrees: return "deg";
    case DeltaUnit::kRadians: return "rad";
  }
  return "frames";
}

namespace {

using Pairs = std::vector<std::pair<size_t, size_t>>;

/// The distance between two positions as numpy's norm of their difference computes it (the squares summed in
/// order), so that thresholds on a path fall exactly where evo's do.
double step_length(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const double dx = a.x() - b.x(), dy = a.y() - b.y(), dz = a.z() - b.z();
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

/// Consecutive pairs along a distance: the poses where the steps since the previous such pose add up to delta.
Pairs consecutive_by_distance(size_t n, const std::function<double(size_t)>& step, double delta) {
  std::vector<size_t> ids;
  double since = 0.0;
  for (size_t i = 0; i < n; ++i) {
    if (i > 0) since += step(i);
    if (since >= delta) {
      ids.push_back(i);
      since = 0.0;
    }
  }
  Pairs pairs;
  for (size_t k = 1; k < ids.size(); ++k) pairs.emplace_back(ids[k - 1], ids[k]);
  return pairs;
}

/// All pairs along a distance: from each i, the j > i whose (along[j] - along[i]) - delta is closest to 0 (the
/// first on ties), kept when within tol. along is non-decreasing, so that miss is too (rounding is monotonic) and
/// two binary searches find what evo's argmin over every j finds.
Pairs all_by_distance(const PoseArray<double>& along, double delta, double tol) {
  Pairs pairs;
  const size_t n = along.size();
  for (size_t i = 0; i + 1 < n; ++i) {
    auto miss = [&](size_t j) { return (along[j] - along[i]) - delta; };
    // First j >= first with miss(j) >= v.
    auto first_at_least = [&](size_t first, double v) {
      size_t lo = first, hi = n;
      while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (miss(mid) >= v) {
          hi = mid;
        } else {
          lo = mid + 1;
        }
      }
      return lo;
    };
    const size_t k = first_at_least(i + 1, 0.0);
    size_t best = k;
    if (k > i + 1) {
      const size_t below = first_at_least(i + 1, miss(k - 1));  // the first of the poses missing by miss(k - 1)
      if (k == n || -miss(k - 1) <= miss(k)) best = below;
    }
    if (best < n && std::abs(miss(best)) <= tol) pairs.emplace_back(i, best);
  }
  return pairs;
}

Pairs rpe_pairs(const Trajectory& t, const RpeOptions& o) {
  Pairs pairs;
  const size_t n = t.size();
  switch (o.unit) {
    case DeltaUnit::kFrames: {
      const size_t d = static_cast<size_t>(o.delta);
      if (d == 0) return pairs;
      for (size_t i = 0; i + d < n; i += o.all_pairs ? 1 : d) pairs.emplace_back(i, i + d);
      return pairs;
    }
    case DeltaUnit::kMeters:
    case DeltaUnit::kSeconds: {
      const bool metres = o.unit == DeltaUnit::kMeters;
      if (!o.all_pairs) {
        return consecutive_by_distance(
            n,
            [&](size_t i) {
              return metres ? step_length(t.positions[i], t.positions[i - 1]) : t.stamps[i] - t.stamps[i - 1];
            },
            o.delta);
      }
      PoseArray<double> along(n, 0.0);
      for (size_t i = 1; i < n; ++i) {
        along[i] = metres ? along[i - 1] + step_length(t.positions[i - 1], t.positions[i]) : t.stamps[i] - t.stamps[0];
      }
      return all_by_distance(along, o.delta, o.delta * o.delta_tol);
    }
    case DeltaUnit::kDegrees:
    case DeltaUnit::kRadians: {
      // evo converts the delta and the tolerance (delta * delta_tol, in the delta's unit) with numpy's deg2rad.
      const double to_rad = o.unit == DeltaUnit::kDegrees ? M_PI / 180.0 : 1.0;
      const double delta = o.delta * to_rad, tol = (o.delta * o.delta_tol) * to_rad;
      const auto& q = t.orientations;
      if (!o.all_pairs) {
        double angle = 0.0;
        size_t start = 0;
        for (size_t i = 0; i + 1 < n; ++i) {
          angle += rotation_angle(q[i].conjugate() * q[i + 1]);
          if (angle >= delta) {
            pairs.emplace_back(start, i + 1);
            angle = 0.0;
            start = i + 1;
          }
        }
        return pairs;
      }
      const double lower = delta - tol, upper = delta + tol;
      // The angle between unit quaternions a and b is 2 acos(|a . b|): a dot product rules out the pairs far from
      // the band (with a margin for rounding), and only the rest get the angle computed as everywhere else, so
      // the pairs are the same as comparing every angle, about 10x sooner.
      constexpr double kMargin = 1e-9;
      const double dot_min = upper >= M_PI ? -1.0 : std::cos(upper / 2) - kMargin;
      const double dot_max = lower <= 0 ? 2.0 : std::cos(lower / 2) + kMargin;
      for (size_t i = 0; i + 1 < n; ++i) {
        const Eigen::Quaterniond& a = q[i];
        const Eigen::Quaterniond qi = a.conjugate();
        for (size_t j = i + 1; j < n; ++j) {
          const Eigen::Quaterniond& b = q[j];
          const double dot = std::abs(a.w() * b.w() + a.x() * b.x() + a.y() * b.y() + a.z() * b.z());
          if (dot < dot_min || dot > dot_max) continue;
          const double angle = rotation_angle(qi * b);
          if (lower <= angle && angle <= upper) pairs.emplace_back(i, j);
        }
      }
      return pairs;
    }
  }
  return pairs;
}

/// The error (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) of the estimated motion from i to j against the true one, as its
/// translation norm [m] and rotation angle [rad], with quaternions (cheaper than 4x4 matrices, as exact).
class RelativeError {
 public:
  /// m's orientations must be unit quaternions, as match_* and apply() make them.
  explicit RelativeError(const Matched& m) : ref_(m.ref), est_(m.est) {}

  std::pair<double, double> operator()(size_t i, size_t j) const {
    const auto& q = ref_.orientations;
    const auto& p = est_.orientations;
    const Eigen::Quaterniond q_rel = q[i].conjugate() * q[j];
    const Eigen::Vector3d t_rel = q[i].conjugate() * (ref_.positions[j] - ref_.positions[i]);
    const Eigen::Quaterniond p_rel = p[i].conjugate() * p[j];
    const Eigen::Vector3d u_rel = p[i].conjugate() * (est_.positions[j] - est_.positions[i]);
    // E = Q_rel^-1 P_rel: translation Q_rel.R^T (u_rel - t_rel), whose norm is |u_rel - t_rel|.
    const Eigen::Quaterniond e = q_rel.conjugate() * p_rel;
    return {(u_rel - t_rel).norm(), rotation_angle(e)};
  }

 private:
  const Trajectory& ref_;
  const Trajectory& est_;
};
}  // namespace

RpeResult rpe(const Matched& m, const RpeOptions& options) {
  RpeResult r;
  r.options = options;
  r.pairs = rpe_pairs(options.pairs_from_reference ? m.ref : m.est, options);
  PoseArray<double> trans(r.pairs.size()), rot(r.pairs.size());
  const RelativeError error(m);
  for (size_t k = 0; k < r.pairs.size(); ++k) {
    const auto [t, angle] = error(r.pairs[k].first, r.pairs[k].second);
    trans[k] = t;
    rot[k] = angle * kRadToDeg;
  }
  r.trans = compute_stats(std::move(trans));
  r.rot_deg = compute_stats(std::move(rot));
  return r;
}

DriftResult drift(const Matched& m, std::vector<double> lengths, size_t step) {
  DriftResult r;
  const size_t n = m.ref.size();
  PoseArray<double> dist(n, 0.0);
  for (size_t i = 1; i < n; ++i) dist[i] = dist[i - 1] + (m.ref.positions[i] - m.ref.positions[i - 1]).norm();
  if (lengths.empty() && n > 1) {
    for (double f : {0.1, 0.2, 0.3, 0.4, 0.5}) {
      const double l = round_2_significant(f * dist.back());
      if (l > 0 && (lengths.empty() || l != lengths.back())) lengths.push_back(l);
    }
  }
  double sum_t = 0, sum_r = 0;
  const RelativeError error(m);
  for (double length : lengths) {
    DriftSegment seg;
    seg.length_m = length;
    for (size_t first = 0; first < n; first += std::max<size_t>(step, 1)) {
      // KITTI: the first pose strictly more than `length` further along the path.
      const auto it = std::upper_bound(dist.begin() + static_cast<long>(first), dist.end(), dist[first] + length);
      if (it == dist.end()) break;
      const auto [t, angle] = error(first, static_cast<size_t>(it - dist.begin()));
      seg.trans_pct += 100.0 * t / length;
      seg.rot_deg_per_m += angle * kRadToDeg / length;
      ++seg.count;
    }
    sum_t += seg.trans_pct;
    sum_r += seg.rot_deg_per_m;
    r.count += seg.count;
    if (seg.count > 0) {
      seg.trans_pct /= static_cast<double>(seg.count);
      seg.rot_deg_per_m /= static_cast<double>(seg.count);
    }
    r.segments.push_back(seg);
  }
  if (r.count > 0) {
    r.trans_pct = sum_t / static_cast<double>(r.count);
    r.rot_deg_per_m = sum_r / static_cast<double>(r.count);
  }
  return r;
}

}  // namespace driftlab::analyzers
