#include "analyzers/internal/command_loop.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

#include "analyzers/internal/channel_samples.h"
#include "analyzers/internal/channel_timing.h"
#include "core/time.h"

namespace driftlab::analyzers::internal {
namespace {

// The lags searched: the joints may follow the commands up to a second later (a slow transport, a controller that
// starts plans late) or, with a sender's clock behind, up to half a second "earlier" than the stamps say.
constexpr int64_t kMaxLagUs = 1'000'000;
constexpr int64_t kMaxLeadUs = 500'000;
// The signals are sampled at 1 ms (a 5 ms answer needs a finer grid; the peak is refined by a parabola), coarser
// on long logs so that at most kMaxSamples are held per joint and signal.
constexpr int64_t kFineUs = 1000;
constexpr int64_t kMaxSamples = 200'000;
// The coarse search steps kCoarse samples; the fine one looks kCoarse samples either side of the coarse peak.
constexpr int64_t kCoarse = 10;
// Below this agreement at the best lag the motion does not say when the joints follow the commands: no motion, a
// controller that does not follow them (stale commands rejected), or a delay that changes during the log (a
// drifting clock). At the true delay the joints repeat the commanded positions up to the controller's tracking
// error, a few percent of their motion: agreement over 0.9.
constexpr double kMinConfidence = 0.5;
// The delays of the log's thirds agree with the whole's within this (the calibration study's yardstick for a right
// delay; a transport's jitter of a few ms moves each third's by less).
constexpr double kSteadyDelayUs = 5000;

/// How well b[i + lag] repeats a[i], over the samples both have with i in [from, to), every `stride`-th: 1 - the
/// mean squared difference over the mean squared deviation of a from its mean (1: b is a, `lag` samples later; 0
/// or less: no better than a's mean).
double agreement(const std::vector<std::vector<double>>& a, const std::vector<std::vector<double>>& b, int64_t lag,
                 int64_t stride, int64_t from = 0, int64_t to = std::numeric_limits<int64_t>::max()) {
  double diff = 0, var = 0;
  for (size_t j = 0; j < a.size(); ++j) {
    const auto n = std::min(static_cast<int64_t>(a[j].size()), to);
    double sum = 0, sq = 0, count = 0;
    for (int64_t i = std::max<int64_t>(from, -lag); i < n && i + lag < static_cast<int64_t>(b[j].size()); i += stride) {
      const double x = a[j][static_cast<size_t>(i)], y = b[j][static_cast<size_t>(i + lag)];
      diff += (x - y) * (x - y);
      sum += x;
      sq += x * x;
      count += 1;
    }
    if (count > 0) var += sq - sum * sum / count;
  }
  return var > 0 ? 1 - diff / var : 0;
}

/// The lag [samples, refined between them] at which b best repeats a over i in [from, to), and the agreement there:
/// a coarse search over every lag from lag_lo to lag_hi (each point into `curve` when given, at `step` us a
/// sample), then every sample and lag around the best one, and a parabola through the peak and its neighbours.
std::pair<double, double> best_lag(const std::vector<std::vector<double>>& a, const std::vector<std::vector<double>>& b,
                                   int64_t from, int64_t to, int64_t lag_lo, int64_t lag_hi, int64_t step,
                                   std::vector<std::pair<double, double>>* curve) {
  int64_t best = 0;
  double best_r = -std::numeric_limits<double>::infinity();
  for (int64_t lag = lag_lo; lag <= lag_hi; lag += kCoarse) {
    const double r = agreement(a, b, lag, kCoarse, from, to);
    if (curve != nullptr) curve->emplace_back(Duration::from_us(lag * step).seconds(), r);
    if (r > best_r) best_r = r, best = lag;
  }
  const int64_t centre = best;
  std::vector<double> fine;
  for (int64_t lag = centre - kCoarse; lag <= centre + kCoarse; ++lag) {
    fine.push_back(agreement(a, b, lag, 1, from, to));
    if (fine.back() > best_r || lag == centre - kCoarse) best_r = fine.back(), best = lag;
  }
  double lag = static_cast<double>(best);
  const auto k = static_cast<size_t>(best - (centre - kCoarse));
  if (k > 0 && k + 1 < fine.size()) {  // the parabola through the peak and its neighbours
    const double y0 = fine[k - 1], y1 = fine[k], y2 = fine[k + 1], den = y0 - 2 * y1 + y2;
    if (den < 0) lag += 0.5 * (y0 - y2) / den;
  }
  return {lag, best_r};
}

}  // namespace

void CommandLoopCheck::add_command(const std::string& channel, std::span<const uint8_t> data, int64_t arrival) {
  commands_[channel].add(data, arrival);
}

void CommandLoopCheck::add_state(const std::string& channel, std::span<const uint8_t> data) {
  states_[channel].add(data);
}

std::vector<CommandLoop> CommandLoopCheck::finish(int64_t start_utime) const {
  std::vector<CommandLoop> out;
  for (const auto& [channel, c] : commands_) {
    CommandLoop loop;
    loop.command_channel = channel;
    loop.commands = static_cast<int64_t>(c.list.size());
    for (const JointCommand& cmd : c.list) {
      // The arrival is any log time: the difference in doubles (a log's arrivals are not bounded like stamps).
      const double over = Time::from_us(cmd.arrival).seconds_since(Time::from_us(cmd.stamp + cmd.t.back()));
      if (over <= 0) continue;
      if (loop.stale++ == 0) loop.first_stale_s = Time::from_us(cmd.arrival).seconds_since(Time::from_us(start_utime));
      loop.stale_max_s = std::max(loop.stale_max_s, over);
    }
    // The state channel with every commanded joint; the one with the most messages.
    const JointStates* states = nullptr;
    for (const auto& [name, s] : states_) {
      if (s.has_all(c.joints) && s.stamp.size() >= 2 && (states == nullptr || s.stamp.size() > states->stamp.size())) {
        loop.state_channel = name;
        states = &s;
      }
    }
    const CommandedMotion motion(c);
    const std::vector<const JointCommand*>& by_stamp = motion.by_stamp();
    if (by_stamp.size() >= 2) {
      Array<double> gaps;
      for (size_t i = 1; i < by_stamp.size(); ++i) {
        gaps.push_back(seconds_between(by_stamp[i - 1]->stamp, by_stamp[i]->stamp));
      }
      loop.command_period_s = median(std::move(gaps));
    }
    if (states == nullptr || by_stamp.size() < 2) {
      out.push_back(std::move(loop));
      continue;
    }
    // Both signals on one grid where both are known: the commanded position of each joint is the plan of the last
    // command stamped at or before the time; the measured one interpolated between joint states.
    const int64_t t0 = std::max(by_stamp.front()->stamp, states->stamp.front());
    const int64_t t1 = std::min(motion.end(), states->stamp.back());
    if (t1 - t0 < 4 * kMaxLagUs) {
      out.push_back(std::move(loop));
      continue;
    }
    const int64_t step = std::max(kFineUs, (t1 - t0) / kMaxSamples + 1);
    const auto n = static_cast<size_t>((t1 - t0) / step);
    const size_t joints = c.joints.size();
    std::vector<std::vector<double>> commanded(joints, std::vector<double>(n)),
        measured(joints, std::vector<double>(n));
    std::vector<std::vector<double>> state_q(joints);
    for (size_t j = 0; j < joints; ++j) {
      const size_t col = states->index.at(c.joints[j]);
      state_q[j].reserve(states->q.size());
      for (const auto& q : states->q) state_q[j].push_back(q[col]);
    }
    std::vector<double> q;
    for (size_t i = 0; i < n; ++i) {
      const int64_t t = t0 + static_cast<int64_t>(i) * step;
      motion.at(t, q);  // t0 is at or after the first command's stamp
      for (size_t j = 0; j < joints; ++j) {
        commanded[j][i] = q[j];
        measured[j][i] = interpolate(states->stamp, state_q[j], t, false);
      }
    }
    // The lag at which the measured positions best repeat the commanded ones: positions, not velocities, because a
    // loop whose commander adds a share of the measured error to each command (as the report's does) puts the
    // measured motion into the commanded one at lag zero, which biases a correlation of velocities towards zero;
    // the positions the joints reach are the commanded ones, corrections included, one delay later.
    const int64_t lag_lo = -kMaxLeadUs / step, lag_hi = kMaxLagUs / step;
    const auto [lag, best_r] =
        best_lag(commanded, measured, 0, static_cast<int64_t>(n), lag_lo, lag_hi, step, &loop.curve);
    loop.delay_s = lag * Duration::from_us(step).seconds();
    // One delay for the whole log only if each third of it has the same (within kSteadyDelayUs): a commander whose
    // clock drifts has a delay from stamp to motion that grows along the log, and one lag fits such slow, smooth
    // motion well (agreement 0.998 at its middle for a clock losing 0.5%, 0.97 for 2%: docs/diagnosis.md,
    // "Calibration"). The confidence is the agreement times the share of thirds that agree.
    int steady = 0;
    for (int part = 0; part < 3; ++part) {
      const auto from = static_cast<int64_t>(n) * part / 3, to = static_cast<int64_t>(n) * (part + 1) / 3;
      const double part_lag = best_lag(commanded, measured, from, to, lag_lo, lag_hi, step, nullptr).first;
      if (std::abs(part_lag - lag) * static_cast<double>(step) <= kSteadyDelayUs) ++steady;
    }
    loop.confidence = std::max(0.0, best_r) * steady / 3.0;
    loop.delay_valid = loop.confidence >= kMinConfidence;
    out.push_back(std::move(loop));
  }
  return out;
}

void judge_loop(const CommandLoop& l, std::vector<ChannelTiming>& channels) {
  const auto c = std::find_if(channels.begin(), channels.end(),
                              [&](const ChannelTiming& x) { return x.name == l.command_channel; });
  if (c == channels.end()) return;
  char buf[512];
  // The tolerance: the time between commands (a streaming commander corrects against states the next commands have
  // already moved on from: the loop lags and overshoots), and at most 50 ms (a plan sent once, as MoveIt does, is
  // followed within a controller's few periods; the simulator's clean arm follows its commands 0.2 ms late).
  constexpr double kMaxLoopDelay_s = 0.050;
  const double tolerance = l.command_period_s > 0 ? std::min(l.command_period_s, kMaxLoopDelay_s) : kMaxLoopDelay_s;
  if (l.delay_valid && l.delay_s > tolerance) {
    const bool streaming = l.command_period_s > 0 && l.delay_s > l.command_period_s;
    std::snprintf(
        buf, sizeof(buf),
        "the joints (%s) follow its commands %.0f ms late, more than %s: %s (a slow transport, or a "
        "controller starting plans late)",
        l.state_channel.c_str(), l.delay_s * 1e3,
        streaming ? ("the " + std::to_string(std::lround(l.command_period_s * 1e3)) + " ms between commands").c_str()
                  : "the 50 ms a controller takes",
        streaming ? "the loop corrects against old states, so it lags and overshoots"
                  : "the arm is where it was told to be that much later");
    add_reason(*c, true, buf, Cause::kLate);
  }
  if (l.stale > 0) {
    std::snprintf(buf, sizeof(buf),
                  "%lld of %lld commands arrived after their plan was over (the first at %.1f s, the worst %.0f ms "
                  "over): stamped on a clock behind, or held up",
                  static_cast<long long>(l.stale), static_cast<long long>(l.commands), l.first_stale_s,
                  l.stale_max_s * 1e3);
    add_reason(*c, true, buf, Cause::kClock);
  }
}

}  // namespace driftlab::analyzers::internal
