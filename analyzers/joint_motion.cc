#include "analyzers/internal/joint_motion.h"

#include <algorithm>
#include <cmath>

#include "driftlab/joint_state_t.hpp"
#include "driftlab/joint_trajectory_t.hpp"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers::internal {
namespace {

// Stamps and plan times are taken within these bounds (any real clock's microseconds since 1970 are far below 2^62;
// a plan of over 12 days is not a command), so that sums and differences of two of them cannot overflow.
constexpr int64_t kMaxStampUs = int64_t{1} << 62;
constexpr int64_t kMaxPlanUs = int64_t{1} << 40;

// More joints than any robot's command carries: left out (the signals hold joints x samples numbers).
constexpr size_t kMaxJoints = 64;

bool finite(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

}  // namespace

double interpolate(const std::vector<int64_t>& xs, const std::vector<double>& ys, int64_t x, bool extrapolate_front) {
  if (x >= xs.back()) return ys.back();
  if (x <= xs.front() && (!extrapolate_front || xs.size() < 2)) return ys.front();
  const auto hi =
      x <= xs.front() ? size_t{1} : static_cast<size_t>(std::upper_bound(xs.begin(), xs.end(), x) - xs.begin());
  const double f = static_cast<double>(x - xs[hi - 1]) / static_cast<double>(xs[hi] - xs[hi - 1]);
  return ys[hi - 1] + f * (ys[hi] - ys[hi - 1]);
}

bool JointCommands::add(std::span<const uint8_t> data, int64_t arrival) {
  driftlab::joint_trajectory_t m;
  if (!lcmtypes::decode(data, m) || m.npoints < 1) return false;
  if (m.joint_names.empty() || m.joint_names.size() > kMaxJoints) return false;
  if (list.empty()) joints = m.joint_names;
  if (m.joint_names != joints) return false;
  if (m.header.utime < 0 || m.header.utime >= kMaxStampUs) return false;
  JointCommand cmd;
  cmd.stamp = m.header.utime;
  cmd.arrival = arrival;
  for (const auto& p : m.points) {
    if (p.positions.size() != joints.size() || p.time_from_start_us < 0 || p.time_from_start_us >= kMaxPlanUs ||
        (!cmd.t.empty() && p.time_from_start_us <= cmd.t.back())) {
      return false;
    }
    if (!finite(p.positions)) return false;
    cmd.t.push_back(p.time_from_start_us);
    cmd.q.push_back(p.positions);
  }
  list.push_back(std::move(cmd));
  return true;
}

bool JointStates::add(std::span<const uint8_t> data) {
  driftlab::joint_state_t m;
  if (!lcmtypes::decode(data, m)) return false;
  if (m.name.empty() || m.name.size() > kMaxJoints || m.position.size() != m.name.size()) return false;
  if (stamp.empty() && index.empty()) {
    for (size_t i = 0; i < m.name.size(); ++i) index.emplace(m.name[i], i);
    if (index.size() != m.name.size()) {  // a name twice: which one is the joint?
      index.clear();
      return false;
    }
    names = m.name;
  }
  if (m.name != names || m.header.utime < 0 || m.header.utime >= kMaxStampUs ||
      (!stamp.empty() && m.header.utime <= stamp.back()) || !finite(m.position)) {
    return false;
  }
  stamp.push_back(m.header.utime);
  q.push_back(std::move(m.position));
  v.push_back(m.velocity.size() == m.name.size() && finite(m.velocity) ? std::move(m.velocity) : std::vector<double>{});
  return true;
}

bool JointStates::has_all(const std::vector<std::string>& joints) const {
  return std::all_of(joints.begin(), joints.end(), [&](const std::string& j) { return index.count(j) > 0; });
}

CommandedMotion::CommandedMotion(const JointCommands& commands) : joints_(commands.joints.size()) {
  for (const JointCommand& cmd : commands.list) by_stamp_.push_back(&cmd);
  std::stable_sort(by_stamp_.begin(), by_stamp_.end(),
                   [](const JointCommand* a, const JointCommand* b) { return a->stamp < b->stamp; });
}

int64_t CommandedMotion::start() const { return by_stamp_.empty() ? 0 : by_stamp_.front()->stamp; }

int64_t CommandedMotion::end() const {
  return by_stamp_.empty() ? 0 : by_stamp_.back()->stamp + by_stamp_.back()->t.back();
}

bool CommandedMotion::at(int64_t t, std::vector<double>& q) const {
  if (by_stamp_.empty() || t < by_stamp_.front()->stamp) return false;
  if (active_ >= by_stamp_.size() || by_stamp_[active_]->stamp > t) {  // not moving forward: search
    active_ = static_cast<size_t>(std::upper_bound(by_stamp_.begin(), by_stamp_.end(), t,
                                                   [](int64_t x, const JointCommand* c) { return x < c->stamp; }) -
                                  by_stamp_.begin()) -
              1;
  }
  while (active_ + 1 < by_stamp_.size() && by_stamp_[active_ + 1]->stamp <= t) ++active_;
  const JointCommand& cmd = *by_stamp_[active_];
  q.resize(joints_);
  for (size_t j = 0; j < joints_; ++j) {
    plan_j_.clear();
    for (const auto& p : cmd.q) plan_j_.push_back(p[j]);
    q[j] = interpolate(cmd.t, plan_j_, t - cmd.stamp, true);
  }
  return true;
}

}  // namespace driftlab::analyzers::internal
