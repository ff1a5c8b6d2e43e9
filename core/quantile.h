// One definition of a sample quantile for the whole project: linear interpolation between order statistics, as
// numpy's default (`np.quantile(v, q)`, method "linear", Hyndman and Fan type 7), equal to it to the last bit
// (tests/core/quantile_test.cc holds it to numpy). The diagnosis, the module statistics, the trajectory errors and
// the report (numpy) all give the same p50/p95/p99 for the same data.
// Thread-safety: pure functions; a RunningQuantile, one caller.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <iterator>
#include <utility>
#include <vector>

namespace driftlab {

namespace internal {
/// Where the q-quantile of n values lies: the index of the order statistic at or below it, and the position
/// (i + t, t in [0, 1)).
inline std::pair<size_t, double> quantile_position(size_t n, double q) {
  const double pos = std::clamp(q, 0.0, 1.0) * static_cast<double>(n - 1);
  return {static_cast<size_t>(pos), pos};
}
/// Between the order statistics at i and i + 1: numpy's linear interpolation to the last bit
/// (numpy/lib/function_base.py, _lerp: from the nearer one).
inline double interpolate(double lo, double hi, size_t i, double pos) {
  const double t = pos - static_cast<double>(i), diff = hi - lo;
  return t >= 0.5 ? hi - diff * (1 - t) : lo + diff * t;
}
}  // namespace internal

/// The q-quantile (0 <= q <= 1) of [first, last), partially reordering the range; NaN when it is empty.
template <typename RandomIt>
double quantile_in_place(RandomIt first, RandomIt last, double q) {
  const auto n = static_cast<size_t>(std::distance(first, last));
  if (n == 0) return NAN;
  const auto [i, pos] = internal::quantile_position(n, q);
  const auto at = first + static_cast<std::ptrdiff_t>(i);
  std::nth_element(first, at, last);
  const double lo = static_cast<double>(*at);
  if (i + 1 >= n) return lo;
  return internal::interpolate(lo, static_cast<double>(*std::min_element(at + 1, last)), i, pos);
}

/// One quantile of a growing sample: what quantile_in_place gives for every value added so far, to the last bit,
/// in O(log n) a value and O(1) a question (a figure asked for again and again as the values come). The values up
/// to the order statistic at or below the quantile are in a max-heap, the rest in a min-heap. Values are compared
/// with <: no NaN.
template <typename T>
class RunningQuantile {
 public:
  explicit RunningQuantile(double q) : q_(q) {}

  void add(T v) {
    if (lower_.empty() || v < lower_.front()) {
      lower_.push_back(v), std::push_heap(lower_.begin(), lower_.end(), std::less<T>());
    } else {
      upper_.push_back(v), std::push_heap(upper_.begin(), upper_.end(), std::greater<T>());
    }
    // The lower heap holds the order statistics 0..i.
    const size_t keep = internal::quantile_position(size(), q_).first + 1;
    while (lower_.size() > keep) move(lower_, std::less<T>(), upper_, std::greater<T>());
    while (lower_.size() < keep) move(upper_, std::greater<T>(), lower_, std::less<T>());
  }
  size_t size() const { return lower_.size() + upper_.size(); }
  /// NaN when no value was added.
  double value() const {
    if (lower_.empty()) return NAN;
    const auto [i, pos] = internal::quantile_position(size(), q_);
    const double lo = static_cast<double>(lower_.front());
    if (upper_.empty()) return lo;
    return internal::interpolate(lo, static_cast<double>(upper_.front()), i, pos);
  }

 private:
  /// The top of one heap onto the other.
  template <typename From, typename To>
  static void move(std::vector<T>& from, From from_order, std::vector<T>& to, To to_order) {
    std::pop_heap(from.begin(), from.end(), from_order);
    to.push_back(from.back()), std::push_heap(to.begin(), to.end(), to_order);
    from.pop_back();
  }
  double q_;
  std::vector<T> lower_, upper_;
};

/// The q-quantile of a container, partially reordering it; NaN when it is empty.
template <typename Container>
double quantile_in_place(Container& v, double q) {
  return quantile_in_place(std::begin(v), std::end(v), q);
}

}  // namespace driftlab
