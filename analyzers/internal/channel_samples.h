// What the timing diagnosis keeps of each channel in its one pass over the log, and the statistics its parts
// share. Internal to analyzers (timing.cc fills the samples; channel_timing.cc and stream_skew.cc read them).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numeric>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "analyzers/timing.h"
#include "core/huge_page_allocator.h"
#include "core/quantile.h"

namespace driftlab::analyzers::internal {

template <typename T>
using Array = HugeVector<T>;

struct ScanMotion;

/// What one pass over the log keeps of a channel.
struct Samples {
  std::string type;
  bool has_header = false;
  bool seq_counted = false;   // header.seq was counted by an import (channel_source_t::SEQ_COUNTED), not sent
  bool is_tf = false;         // driftlab.tf_t: its transforms are judged one by one (tf_check.cc)
  bool is_static_tf = false;  // static transforms (tf_check.h's is_static_tf_channel): timeless, stamped 0 or not
  Array<int64_t> arrival;  // log timestamp [us]
  Array<int64_t> stamp;    // header.utime [us] (empty without a header)
  Array<int64_t> seq;      // header.seq
  Array<uint64_t> digest;  // payload size and first bytes (duplicate detection without a header)
  // Yaw rate [rad/s] at a stamp [s], for channels that observe the robot's rotation.
  Array<double> motion_t, motion_w;
  bool motion_from_pose = false;
  std::string frame;      // header.frame_id of the first message
  int64_t malformed = 0;  // messages that do not hold their type's layout: counted, nothing else read
  std::string malformed_example;
  double last_yaw = 0, last_t = 0;
  bool have_last = false;
  // For a pass read in stretches (timing.cc), what joins a stretch to the one before: whether its first message
  // had a header, and its first pose (the yaw rate across the join needs the pose before it).
  bool header_at_start = false;
  double first_yaw = 0, first_t = 0;
  size_t first_pose_at = 0;          // motion_t.size() at the first pose
  std::shared_ptr<ScanMotion> scan;  // 2D scans: the rotation between consecutive ones (stream_skew.cc)
  // A spinning lidar stamps its first beam but is complete only at its last: that much later [us] (from the
  // first scan), which latency and the clock fit add to the stamp.
  int64_t ready_after_us = 0;
};

inline double quantile(Array<double>& v, double q) { return quantile_in_place(v, q); }

inline Distribution distribution(Array<double> v) {
  Distribution d;
  if (v.empty()) return d;
  d.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  d.max = *std::max_element(v.begin(), v.end());
  d.p99 = quantile(v, 0.99);
  d.p95 = quantile(v, 0.95);
  d.p50 = quantile(v, 0.5);
  return d;
}

inline double median(Array<double> v) { return v.empty() ? 0 : quantile(v, 0.5); }

/// The ranks of a distribution-free 95% confidence interval for the median of m > 0 sorted values (binomial,
/// normal approximation): the lower and upper order statistics, clamped to the sample.
inline std::pair<size_t, size_t> median_ci_ranks(size_t m) {
  const double half = 1.96 * std::sqrt(static_cast<double>(m)) / 2;
  const double mid = static_cast<double>(m - 1) / 2;
  return {static_cast<size_t>(std::max(0.0, std::floor(mid - half))),
          static_cast<size_t>(std::min(static_cast<double>(m - 1), std::ceil(mid + half)))};
}

}  // namespace driftlab::analyzers::internal
