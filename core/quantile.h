// One definition of a sample quantile for the whole project: linear interpolation between order statistics, as
// numpy's default (`np.quantile(v, q)`, method "linear", Hyndman and Fan type 7), equal to it to the last bit
// (tests/core/quantile_test.cc holds it to numpy). The diagnosis, the module statistics, the trajectory errors and
// the report (numpy) all give the same p50/p95/p99 for the same data.
// Thread-safety: pure functions.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <iterator>

namespace driftlab {

namespace internal {
/// The q-quantile of [first, last), NaN when it is empty: numpy's linear interpolation between the two order
/// statistics around it, to the last bit (numpy/lib/function_base.py, _lerp: from the nearer one). Sorted: the
/// range is in ascending order already; else it is partially reordered to find them.
template <bool Sorted, typename RandomIt>
double quantile(RandomIt first, RandomIt last, double q) {
  const auto n = static_cast<size_t>(std::distance(first, last));
  if (n == 0) return NAN;
  const double pos = std::clamp(q, 0.0, 1.0) * static_cast<double>(n - 1);
  const auto i = static_cast<size_t>(pos);
  const auto at = first + static_cast<std::ptrdiff_t>(i);
  if constexpr (!Sorted) std::nth_element(first, at, last);
  const double lo = static_cast<double>(*at);
  if (i + 1 >= n) return lo;
  double hi = 0;
  if constexpr (Sorted) {
    hi = static_cast<double>(*(at + 1));
  } else {
    hi = static_cast<double>(*std::min_element(at + 1, last));
  }
  const double t = pos - static_cast<double>(i), diff = hi - lo;
  return t >= 0.5 ? hi - diff * (1 - t) : lo + diff * t;
}
}  // namespace internal

/// The q-quantile (0 <= q <= 1) of [first, last), partially reordering the range; NaN when it is empty.
template <typename RandomIt>
double quantile_in_place(RandomIt first, RandomIt last, double q) {
  return internal::quantile<false>(first, last, q);
}

/// The q-quantile of a range already sorted (ascending), in O(1): the value quantile_in_place gives.
template <typename RandomIt>
double quantile_of_sorted(RandomIt first, RandomIt last, double q) {
  return internal::quantile<true>(first, last, q);
}

/// The q-quantile of a container, partially reordering it; NaN when it is empty.
template <typename Container>
double quantile_in_place(Container& v, double q) {
  return quantile_in_place(std::begin(v), std::end(v), q);
}

}  // namespace driftlab
