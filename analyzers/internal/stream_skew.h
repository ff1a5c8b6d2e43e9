// Skew between streams that observe the same motion (the yaw rate of the IMU's gyro, wheel odometry, poses and
// 2D scans), by cross-correlation over windows of their common time. Internal to analyzers (used by timing.cc).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "analyzers/internal/channel_samples.h"
#include "analyzers/timing.h"

namespace driftlab::analyzers::internal {

/// Keeps the yaw rate a message observes (fingerprint tells its type), during the pass over the log: a gyro's or
/// odometry's as it is, from consecutive poses or 2D scans the rotation between them over the time between them.
void add_motion(Samples& s, int64_t fingerprint, std::span<const uint8_t> data);
/// Appends to a channel's samples those of the next stretch of the log, as if one pass had read both. False when
/// that cannot be told: the channel's type or whether it has a header differs at the join.
bool append_samples(Samples& a, Samples& b);

/// The pairs of channels whose skew stream_pairs measures: every two that observe the robot turning (ground truth
/// first, then IMUs: the reference side of each pair), leaving out pairs that carry the same stamps. It reads the
/// channels' stamps, so it comes before anything changes them (channel_timing maps them for a while).
struct PairPlan {
  std::vector<const std::pair<const std::string, Samples>*> moving;
  std::vector<std::pair<size_t, size_t>> jobs;  // indices into moving
};
PairPlan plan_pairs(const std::map<std::string, Samples, std::less<>>& channels);

/// The skew of each planned pair, on two threads. It reads only the channels' motion (their yaw rates), so it may
/// run beside what changes their stamps. The log spans [start_utime, end_utime].
std::vector<StreamPair> stream_pairs(const PairPlan& plan, int64_t start_utime, int64_t end_utime,
                                     const DiagnoseOptions& options);

}  // namespace driftlab::analyzers::internal
