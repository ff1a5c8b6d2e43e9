// Late measurements re-applied, for any filter: the measurements of the last `window_s` are kept with the filter
// state after each; a measurement stamped before the filter's time rewinds to the state before it, is inserted and
// everything after it is re-applied in stamp order (the result equals in-order processing); older ones are rejected
// and counted. The planar EKF (ekf.h) and the drone's 3D EKF (drone_ekf.h) share it.
//
// Filter: copyable, with `Time time() const` and `bool update(Time at, const M&)`, which predicts to `at` (a no-op
// for earlier times) and applies the measurement, or refuses it (false) and stays as it was.
// Rank: orders measurements of the same stamp (lower first), so that the result does not depend on which of them
// arrived first: the drone's IMU sample, which carries the filter to its stamp, before the corrections at it.
// Thread-safety: plain values; one thread.
#pragma once

#include <algorithm>
#include <cstdint>
#include <deque>
#include <iterator>
#include <utility>

#include "core/time.h"

namespace driftlab::estimator {

/// Every measurement of the same rank: same-stamp measurements stay in arrival order.
struct SameRank {
  template <class M>
  int operator()(const M&) const {
    return 0;
  }
};

template <class Filter, class M, class Rank = SameRank>
class DelayedFilter {
 public:
  struct Counters {
    int64_t applied = 0;    ///< measurements applied in stamp order
    int64_t reapplied = 0;  ///< late measurements inserted into the past (the ones after them re-applied)
    int64_t rejected = 0;   ///< measurements older than the window
    int64_t replays = 0;    ///< measurements re-applied because of late ones
    int64_t refused = 0;    ///< measurements the filter refused (its update: implausible or overflowing values)
  };

  DelayedFilter(Filter filter, double window_s)
      : filter_(std::move(filter)), window_(Duration::from_seconds_truncated(window_s)), base_(filter_) {}

  /// Starts again from `filter` (a freshly initialised one): the history is forgotten.
  void reset(const Filter& filter) {
    filter_ = filter;
    base_ = filter;
    history_.clear();
  }

  /// Applies a measurement stamped `at`; false when it was older than the window and rejected, or refused by the
  /// filter.
  bool add(Time at, const M& m) {
    const int rank = Rank()(m);
    const bool in_order =
        at > filter_.time() ||
        (at == filter_.time() && (history_.empty() || history_.back().at < at || history_.back().rank <= rank));
    if (in_order) {  // the common case
      if (!filter_.update(at, m)) {
        ++counters_.refused;
        return false;
      }
      history_.push_back({at, rank, m, filter_});
      ++counters_.applied;
    } else {
      if (older_than_window(at) || at < base_.time()) {
        ++counters_.rejected;
        return false;
      }
      // Rewind to the state before the first entry after this one (by stamp, then rank), insert it, and re-apply
      // the rest.
      auto pos = std::upper_bound(history_.begin(), history_.end(), std::pair{at, rank},
                                  [](const std::pair<Time, int>& k, const Entry& e) {
                                    return k.first < e.at || (k.first == e.at && k.second < e.rank);
                                  });
      Filter before = pos == history_.begin() ? base_ : std::prev(pos)->after;
      if (!before.update(at, m)) {  // the filter as it was stays
        ++counters_.refused;
        return false;
      }
      filter_ = before;
      pos = history_.insert(pos, {at, rank, m, filter_});
      for (auto it = std::next(pos); it != history_.end(); ++it) {
        filter_.update(it->at, it->m);  // one refused now leaves the state as it was before it
        it->after = filter_;
      }
      counters_.replays += static_cast<int64_t>(std::distance(pos, history_.end())) - 1;
      ++counters_.reapplied;
    }
    // Forget what is older than the window; the last forgotten state becomes the base.
    while (!history_.empty() && older_than_window(history_.front().at)) {
      base_ = history_.front().after;
      history_.pop_front();
    }
    return true;
  }

  const Filter& filter() const { return filter_; }
  const Counters& counters() const { return counters_; }

 private:
  bool older_than_window(Time at) const {
    // Exact whatever the stamps, where their difference in int64_t could overflow.
    return filter_.time().us_past(at) > static_cast<uint64_t>(window_.us());
  }
  struct Entry {
    Time at;
    int rank;
    M m;
    Filter after;  ///< the filter after applying m
  };
  Filter filter_;
  Duration window_;
  Filter base_;                ///< the filter before the first entry in the history
  std::deque<Entry> history_;  ///< applied measurements within the window, by stamp
  Counters counters_;
};

}  // namespace driftlab::estimator
