// Command loops for `driftlab diagnose`: the delay from a joint trajectory command to the joints' motion, measured
// from the motion, and the commands that arrived after their plan was over. Internal to analyzers (used by
// timing.cc). Thread-safety: plain values.
#pragma once

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "analyzers/internal/joint_motion.h"
#include "analyzers/timing.h"

namespace driftlab::analyzers::internal {

class CommandLoopCheck {
 public:
  /// A driftlab.joint_trajectory_t message on `channel` that arrived at arrival [us].
  void add_command(const std::string& channel, std::span<const uint8_t> data, int64_t arrival);
  /// A driftlab.joint_state_t message on `channel`.
  void add_state(const std::string& channel, std::span<const uint8_t> data);
  /// One loop per command channel, paired with the state channel that has all its joints (the one with the most
  /// messages when several do); start_utime: the log's start [us].
  std::vector<CommandLoop> finish(int64_t start_utime) const;

 private:
  std::map<std::string, JointCommands> commands_;
  std::map<std::string, JointStates> states_;
};

/// A loop's findings as reasons of its command stream: joints that follow the commands later than the interval
/// between commands (the loop corrects against states the next commands have moved on from: it lags and
/// overshoots), and commands whose plan was over when they arrived.
void judge_loop(const CommandLoop& loop, std::vector<ChannelTiming>& channels);

}  // namespace driftlab::analyzers::internal
