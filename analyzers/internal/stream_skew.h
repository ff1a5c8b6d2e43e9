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

/// Keeps the yaw rate a message observes (fingerprint tells its type), during the pass over the log; 2D scans are
/// kept as views into the log and turned into a yaw rate by stream_pairs().
void add_motion(Samples& s, int64_t fingerprint, std::span<const uint8_t> data);

/// The skew of every two channels that observe the robot turning (ground truth first, then IMUs: the reference
/// side of each pair), leaving out pairs that carry the same stamps. The log spans [start_utime, end_utime].
std::vector<StreamPair> stream_pairs(std::map<std::string, Samples, std::less<>>& channels, int64_t start_utime,
                                     int64_t end_utime, const DiagnoseOptions& options);

}  // namespace driftlab::analyzers::internal
