#include "analyzers/arm_tracking.h"

#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <cmath>
#include <complex>
#include <map>
#include <numeric>

#include "analyzers/internal/joint_motion.h"
#include "core/log_format.h"
#include "core/log_reader.h"
#include "core/time.h"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/joint_trajectory_state_t.hpp"
#include "driftlab/joint_trajectory_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/robot_description_t.hpp"
#include "kinematics/arm_chain.h"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers {
namespace {

using internal::CommandedMotion;
using internal::JointCommands;
using internal::JointStates;

constexpr double kRadToDeg = 180.0 / M_PI;
/// Ground truth of the base is interpolated between poses at most this far apart [us].
constexpr int64_t kMaxTruthGapUs = 100'000;
constexpr size_t kMaxSpectrumSamples = size_t{1} << 22;
/// The oscillation's resampling step [us]: 100 Hz, the simulator's ground truth rate (a 50 Hz Nyquist frequency, above
/// any motion an arm's controller makes).
constexpr int64_t kSpectrumStepUs = 10'000;

/// The controller states of one channel: desired positions at their stamps.
struct ControllerStates {
  std::vector<std::string> joints;
  std::vector<int64_t> stamp;
  std::vector<std::vector<double>> desired;
  void add(std::span<const uint8_t> data) {
    driftlab::joint_trajectory_state_t m;
    if (!lcmtypes::decode(data, m) || m.joint_names.empty() || m.desired_positions.size() != m.joint_names.size()) {
      return;
    }
    if (stamp.empty()) joints = m.joint_names;
    if (m.joint_names != joints || (!stamp.empty() && m.header.utime <= stamp.back())) return;
    if (!std::all_of(m.desired_positions.begin(), m.desired_positions.end(),
                     [](double v) { return std::isfinite(v); })) {
      return;
    }
    stamp.push_back(m.header.utime);
    desired.push_back(std::move(m.desired_positions));
  }
};

/// The poses of one ground-truth channel, with the body they are of.
struct TruthPoses {
  std::string frame, child;  // of the first message
  std::vector<int64_t> stamp;
  std::vector<Eigen::Isometry3d> pose;
  void add(std::span<const uint8_t> data) {
    driftlab::pose_t m;
    if (!lcmtypes::decode(data, m)) return;
    if (stamp.empty()) frame = m.header.frame_id, child = m.child_frame_id;
    if (m.header.frame_id != frame || m.child_frame_id != child || (!stamp.empty() && m.header.utime <= stamp.back())) {
      return;
    }
    const Eigen::Vector3d p(m.position.x, m.position.y, m.position.z);
    const Eigen::Quaterniond q(m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z);
    if (!p.allFinite() || !q.coeffs().allFinite() || std::abs(q.norm() - 1) > 0.01) return;
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.translation() = p;
    t.linear() = q.normalized().toRotationMatrix();
    stamp.push_back(m.header.utime);
    pose.push_back(t);
  }
  /// The pose at t, interpolated (linear, slerp) between the poses around it when at most kMaxTruthGapUs apart.
  bool at(int64_t t, Eigen::Isometry3d& out) const {
    const auto hi = std::lower_bound(stamp.begin(), stamp.end(), t) - stamp.begin();
    if (hi < static_cast<std::ptrdiff_t>(stamp.size()) && stamp[static_cast<size_t>(hi)] == t) {
      out = pose[static_cast<size_t>(hi)];
      return true;
    }
    if (hi == 0 || hi == static_cast<std::ptrdiff_t>(stamp.size())) return false;
    const auto b = static_cast<size_t>(hi), a = b - 1;
    if (stamp[b] - stamp[a] > kMaxTruthGapUs) return false;
    const double f = static_cast<double>(t - stamp[a]) / static_cast<double>(stamp[b] - stamp[a]);
    out = Eigen::Isometry3d::Identity();
    out.translation() = (1 - f) * pose[a].translation() + f * pose[b].translation();
    out.linear() = Eigen::Quaterniond(pose[a].rotation())
                       .slerp(f, Eigen::Quaterniond(pose[b].rotation()))
                       .normalized()
                       .toRotationMatrix();
    return true;
  }
};

/// The channel of `map` with the most samples of `size(value)`, among those `fits`.
template <typename Map, typename Size, typename Fits>
std::string most(const Map& map, Size size, Fits fits) {
  std::string best;
  size_t n = 0;
  for (const auto& [name, value] : map) {
    if (fits(value) && size(value) > n) best = name, n = size(value);
  }
  return best;
}

std::string channel_list(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "none" : out;
}

/// The reference positions of the commanded joints at t: the commands' plans or the controller's desired state.
class Reference {
 public:
  Reference(const CommandedMotion* commanded, const ControllerStates* desired, std::vector<size_t> columns)
      : commanded_(commanded), desired_(desired), columns_(std::move(columns)) {}
  int64_t start() const { return commanded_ != nullptr ? commanded_->start() : desired_->stamp.front(); }
  int64_t end() const { return commanded_ != nullptr ? commanded_->end() : desired_->stamp.back(); }
  bool at(int64_t t, std::vector<double>& q) const {
    if (commanded_ != nullptr) return commanded_->at(t, q);
    const auto& s = desired_->stamp;
    if (t < s.front() || t > s.back()) return false;
    const auto hi = static_cast<size_t>(std::lower_bound(s.begin(), s.end(), t) - s.begin());
    q.resize(columns_.size());
    for (size_t j = 0; j < columns_.size(); ++j) {
      const size_t c = columns_[j];
      if (s[hi] == t || hi == 0) {
        q[j] = desired_->desired[hi][c];
        continue;
      }
      const double f = static_cast<double>(t - s[hi - 1]) / static_cast<double>(s[hi] - s[hi - 1]);
      q[j] = desired_->desired[hi - 1][c] + f * (desired_->desired[hi][c] - desired_->desired[hi - 1][c]);
    }
    return true;
  }

 private:
  const CommandedMotion* commanded_;
  const ControllerStates* desired_;
  std::vector<size_t> columns_;  // desired: the commanded joints' columns of the controller state
};

/// The part of a 3D motion above cutoff_hz: each axis resampled every step_us (linearly between the samples at
/// stamps ts [us]), less its mean, through a Hann window (a motion that does not end where it starts would otherwise
/// leak into every frequency), by FFT; the power spectra of the three axes added.
Oscillation oscillation(const std::vector<int64_t>& ts, const std::vector<Eigen::Vector3d>& xs, int64_t step_us,
                        double cutoff_hz) {
  Oscillation o;
  o.cutoff_hz = cutoff_hz;
  if (ts.size() < 2) return o;
  // At most kMaxSpectrumSamples (11 hours at 100 Hz); a longer span is resampled more coarsely, and a cutoff above
  // the coarser grid's Nyquist frequency then finds nothing.
  step_us = std::max(step_us, (ts.back() - ts.front()) / static_cast<int64_t>(kMaxSpectrumSamples) + 1);
  const auto n = static_cast<size_t>((ts.back() - ts.front()) / step_us) + 1;
  if (n < 16) return o;
  const double step_s = Duration::from_us(step_us).seconds();
  std::vector<double> window(n), power(n / 2 + 1, 0.0), x(n);
  double window_power = 0;
  for (size_t i = 0; i < n; ++i) {
    window[i] = 0.5 - 0.5 * std::cos(2 * M_PI * static_cast<double>(i) / static_cast<double>(n - 1));
    window_power += window[i] * window[i] / static_cast<double>(n);
  }
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> spectrum;
  for (int axis = 0; axis < 3; ++axis) {
    size_t k = 0;
    for (size_t i = 0; i < n; ++i) {
      const int64_t t = ts.front() + static_cast<int64_t>(i) * step_us;
      while (k + 2 < ts.size() && ts[k + 1] <= t) ++k;
      const double f = std::clamp(static_cast<double>(t - ts[k]) / static_cast<double>(ts[k + 1] - ts[k]), 0.0, 1.0);
      x[i] = (1 - f) * xs[k][axis] + f * xs[k + 1][axis];
    }
    const double mean = std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(n);
    for (size_t i = 0; i < n; ++i) x[i] = (x[i] - mean) * window[i];
    fft.fwd(spectrum, x);
    // Parseval: the mean square is the sum over bins of |X_b|^2 / n^2, each bin but 0 and n/2 twice; the window's
    // mean square divided out.
    for (size_t b = 1; b <= n / 2; ++b) {
      power[b] += std::norm(spectrum[b]) * (b * 2 == n ? 1.0 : 2.0) /
                  (static_cast<double>(n) * static_cast<double>(n) * window_power);
    }
  }
  double above = 0, peak = 0;
  for (size_t b = 1; b < power.size(); ++b) {
    const double f = static_cast<double>(b) / (static_cast<double>(n) * step_s);
    if (f < cutoff_hz) continue;
    above += power[b];
    if (power[b] > peak) peak = power[b], o.peak_hz = f;
  }
  o.rms_m = std::sqrt(above);
  return o;
}

}  // namespace

const char* to_string(ArmReference reference) { return reference == ArmReference::kDesired ? "desired" : "commanded"; }

Result<ArmTracking> evaluate_arm(const std::string& log, const ArmTrackingOptions& options) {
  auto reader = LogReader::open(log);
  if (!reader) return reader.error();
  std::map<std::string, JointCommands> commands;
  std::map<std::string, JointStates> states;
  std::map<std::string, ControllerStates> controllers;
  std::map<std::string, TruthPoses> truths;
  std::string urdf, description_channel;
  const int64_t command_hash = driftlab::joint_trajectory_t::getHash();
  const int64_t state_hash = driftlab::joint_state_t::getHash();
  const int64_t controller_hash = driftlab::joint_trajectory_state_t::getHash();
  const int64_t pose_hash = driftlab::pose_t::getHash();
  const int64_t description_hash = driftlab::robot_description_t::getHash();
  int64_t log_start = 0;
  bool first = true;
  Event e;
  while (reader->next(e)) {
    if (first) log_start = e.utime;
    first = false;
    const int64_t fp = logfmt::fingerprint(e.data);
    const std::string channel(e.channel);
    if (fp == command_hash) {
      commands[channel].add(e.data, e.utime);
    } else if (fp == state_hash) {
      states[channel].add(e.data);
    } else if (fp == controller_hash) {
      controllers[channel].add(e.data);
    } else if (fp == pose_hash) {
      truths[channel].add(e.data);
    } else if (fp == description_hash && urdf.empty()) {
      driftlab::robot_description_t d;
      if (lcmtypes::decode(e.data, d)) urdf = std::move(d.urdf), description_channel = channel;
    }
  }

  ArmTracking out;
  out.log = log;
  out.reference = options.reference;
  // The commands.
  std::vector<std::string> command_channels;
  command_channels.reserve(commands.size());
  for (const auto& [name, c] : commands) command_channels.push_back(name);
  if (!options.command_channel.empty()) {
    if (commands.count(options.command_channel) == 0) {
      return Error{log + ": --arm-command " + options.command_channel +
                   " is not a channel of joint trajectories (driftlab.joint_trajectory_t; those: " +
                   channel_list(command_channels) + ")"};
    }
    out.command_channel = options.command_channel;
  } else {
    out.command_channel = most(
        commands, [](const JointCommands& c) { return c.list.size(); }, [](const JointCommands&) { return true; });
  }
  if (out.command_channel.empty() || commands[out.command_channel].list.empty()) {
    return Error{log + ": no joint trajectory commands (driftlab.joint_trajectory_t) to evaluate an arm against"};
  }
  const JointCommands& cmds = commands[out.command_channel];
  const std::vector<std::string>& joints = cmds.joints;
  out.commands = static_cast<int64_t>(cmds.list.size());
  // The measured joints.
  out.state_channel = most(
      states, [](const JointStates& s) { return s.stamp.size(); },
      [&](const JointStates& s) { return s.has_all(joints) && s.stamp.size() >= 2; });
  if (out.state_channel.empty()) {
    return Error{log + ": no joint states (driftlab.joint_state_t) of the joints " + out.command_channel +
                 " commands (" + channel_list(joints) + ")"};
  }
  const JointStates& js = states[out.state_channel];
  std::vector<size_t> state_columns;
  state_columns.reserve(joints.size());
  for (const auto& j : joints) state_columns.push_back(js.index.at(j));
  // The reference.
  const CommandedMotion motion(cmds);
  std::vector<size_t> controller_columns;
  out.controller_channel = most(
      controllers, [](const ControllerStates& c) { return c.stamp.size(); },
      [&](const ControllerStates& c) {
        return c.stamp.size() >= 2 && std::all_of(joints.begin(), joints.end(), [&](const std::string& j) {
                 return std::find(c.joints.begin(), c.joints.end(), j) != c.joints.end();
               });
      });
  const ControllerStates* desired = nullptr;
  if (options.reference == ArmReference::kDesired) {
    if (out.controller_channel.empty()) {
      return Error{log +
                   ": --arm-reference desired needs the controller's state (driftlab.joint_trajectory_state_t) "
                   "of the joints " +
                   out.command_channel + " commands, and the log has none"};
    }
    desired = &controllers[out.controller_channel];
    for (const auto& j : joints) {
      controller_columns.push_back(
          static_cast<size_t>(std::find(desired->joints.begin(), desired->joints.end(), j) - desired->joints.begin()));
    }
  }
  const Reference reference(options.reference == ArmReference::kCommanded ? &motion : nullptr, desired,
                            controller_columns);
  const int64_t t0 = std::max(reference.start(), js.stamp.front());
  const int64_t t1 = std::min(reference.end(), js.stamp.back());
  if (t1 <= t0) {
    return Error{log + ": the joint states of " + out.state_channel + " do not overlap the " +
                 to_string(options.reference) + " motion in time (stamps on different clocks?)"};
  }
  out.start_s = Time::from_us(t0).seconds_since(Time::from_us(log_start));
  out.end_s = Time::from_us(t1).seconds_since(Time::from_us(log_start));

  // The URDF, for the limits and the end effector.
  std::optional<kinematics::RobotModel> model;
  if (!urdf.empty()) {
    auto m = kinematics::RobotModel::parse(urdf, log + ":" + description_channel);
    if (!m) return m.error();
    model = std::move(*m);
  }

  // Joint errors at the joint states' stamps; positions and speeds over the whole log.
  std::vector<PoseArray<double>> abs_error(joints.size());
  std::vector<double> signed_sum(joints.size(), 0.0);
  std::vector<double> q_ref;
  for (size_t k = 0; k < js.stamp.size(); ++k) {
    if (js.stamp[k] < t0 || js.stamp[k] > t1 || !reference.at(js.stamp[k], q_ref)) continue;
    for (size_t j = 0; j < joints.size(); ++j) {
      const double err = js.q[k][state_columns[j]] - q_ref[j];
      abs_error[j].push_back(std::abs(err));
      signed_sum[j] += err;
    }
  }
  for (size_t j = 0; j < joints.size(); ++j) {
    JointTracking t;
    t.name = joints[j];
    const size_t n = abs_error[j].size();
    t.error_rad = compute_stats(std::move(abs_error[j]));
    t.mean_signed_rad = n > 0 ? signed_sum[j] / static_cast<double>(n) : 0;
    const kinematics::ModelJoint* mj = model ? model->joint(joints[j]) : nullptr;
    if (mj != nullptr) {
      t.has_position_limits = mj->limits.has_position;
      t.lower = mj->limits.lower;
      t.upper = mj->limits.upper;
      t.velocity_limit = mj->limits.velocity;
    }
    t.min = t.max = js.q.front()[state_columns[j]];
    for (size_t k = 0; k < js.stamp.size(); ++k) {
      const double q = js.q[k][state_columns[j]];
      t.min = std::min(t.min, q);
      t.max = std::max(t.max, q);
      if (t.has_position_limits && (q < t.lower || q > t.upper)) ++t.beyond_position;
      if (js.v[k].empty()) continue;
      const double speed = std::abs(js.v[k][state_columns[j]]);
      t.max_speed = std::max(t.max_speed, speed);
      if (t.velocity_limit > 0 && speed > t.velocity_limit) ++t.beyond_velocity;
    }
    out.joints.push_back(std::move(t));
  }

  // The end effector against ground truth: the deepest link the commanded joints move with a ground truth, and
  // the nearest link above the first commanded joint with one in the same frame.
  if (!model) {
    out.ee_problem = "no robot description (driftlab.robot_description_t) in the log: no forward kinematics";
    return out;
  }
  auto depth = [&](const std::string& link) {  // joints between the root and link; -1 for an unknown link
    if (!model->has_link(link)) return -1;
    int d = 0;
    for (const kinematics::ModelJoint* j = model->parent_joint(link); j != nullptr; j = model->parent_joint(j->parent))
      ++d;
    return d;
  };
  auto below = [&](const std::string& link, const std::string& joint) {  // joint moves link
    for (const kinematics::ModelJoint* j = model->parent_joint(link); j != nullptr; j = model->parent_joint(j->parent))
      if (j->name == joint) return true;
    return false;
  };
  const kinematics::ModelJoint* first_joint = model->joint(joints.front());
  std::vector<std::string> pose_channels;
  pose_channels.reserve(truths.size());
  for (const auto& [name, t] : truths) pose_channels.push_back(name);
  auto pick = [&](const std::string& given, const char* option, auto&& fits, auto&& better) -> Result<std::string> {
    if (!given.empty()) {
      const auto it = truths.find(given);
      if (it == truths.end() || it->second.stamp.empty()) {
        return Error{log + ": " + option + " " + given +
                     " is not a channel of poses (driftlab.pose_t; those: " + channel_list(pose_channels) + ")"};
      }
      return given;
    }
    std::string best;
    for (const auto& [name, t] : truths) {
      if (t.stamp.size() >= 2 && fits(t) && (best.empty() || better(t, truths.at(best)))) best = name;
    }
    return best;
  };
  auto ee = pick(
      options.ee_channel, "--arm-ee",
      [&](const TruthPoses& t) { return depth(t.child) >= 0 && below(t.child, joints.back()); },
      [&](const TruthPoses& a, const TruthPoses& b) { return depth(a.child) > depth(b.child); });
  if (!ee) return ee.error();
  out.ee_channel = *ee;
  if (out.ee_channel.empty()) {
    out.ee_problem = "no ground truth pose (driftlab.pose_t) of a link the commanded joints move (pose channels: " +
                     channel_list(pose_channels) + ")";
    return out;
  }
  const TruthPoses& ee_truth = truths.at(out.ee_channel);
  auto base = pick(
      options.base_channel, "--arm-base",
      [&](const TruthPoses& t) {
        return t.frame == ee_truth.frame && depth(t.child) >= 0 && first_joint != nullptr &&
               model->path(t.child, first_joint->parent).ok();
      },
      [&](const TruthPoses& a, const TruthPoses& b) { return depth(a.child) > depth(b.child); });
  if (!base) return base.error();
  out.base_channel = *base;
  if (out.base_channel.empty()) {
    out.ee_problem = "no ground truth pose (driftlab.pose_t) in " + ee_truth.frame + " of a link above " +
                     joints.front() + " (pose channels: " + channel_list(pose_channels) + ")";
    return out;
  }
  const TruthPoses& base_truth = truths.at(out.base_channel);
  auto chain = kinematics::ArmChain::create(*model, base_truth.child, ee_truth.child, false);
  if (!chain) return chain.error();
  out.base_link = base_truth.child;
  out.tip_link = ee_truth.child;
  // The chain's joints: commanded ones from the reference, others (not commanded) as measured.
  std::vector<int> from_reference;  // per chain joint: its index among the commanded joints, or -1
  std::vector<size_t> measured_column;
  for (const auto& name : chain->joint_names()) {
    const auto it = std::find(joints.begin(), joints.end(), name);
    from_reference.push_back(it == joints.end() ? -1 : static_cast<int>(it - joints.begin()));
    const auto col = js.index.find(name);
    if (it == joints.end() && col == js.index.end()) {
      out.ee_problem = "joint " + name + " between " + out.base_link + " and " + out.tip_link +
                       " is neither commanded nor in the joint states";
      return out;
    }
    measured_column.push_back(col == js.index.end() ? 0 : col->second);
  }
  PoseArray<double> position_errors, rotation_errors;
  std::vector<int64_t> motion_t;  // the end effector's true position in the base link's frame
  std::vector<Eigen::Vector3d> motion_xyz;
  Eigen::VectorXd q(chain->dof());
  size_t state_k = 0;
  for (size_t k = 0; k < ee_truth.stamp.size(); ++k) {
    const int64_t t = ee_truth.stamp[k];
    if (t < t0 || t > t1) continue;
    Eigen::Isometry3d base_pose;
    if (!base_truth.at(t, base_pose) || !reference.at(t, q_ref)) continue;
    while (state_k + 1 < js.stamp.size() && js.stamp[state_k + 1] <= t) ++state_k;
    for (int i = 0; i < chain->dof(); ++i) {
      const int r = from_reference[static_cast<size_t>(i)];
      q[i] = r >= 0 ? q_ref[static_cast<size_t>(r)] : js.q[state_k][measured_column[static_cast<size_t>(i)]];
    }
    const Eigen::Isometry3d want = chain->fk(q);
    const Eigen::Isometry3d got = base_pose.inverse() * ee_truth.pose[k];
    const Eigen::Vector3d d = got.translation() - want.translation();
    position_errors.push_back(d.norm());
    rotation_errors.push_back(kinematics::angle_distance(want, got) * kRadToDeg);
    out.ee_t.push_back(Time::from_us(t).seconds_since(Time::from_us(log_start)));
    out.ee_position_error.push_back(d.norm());
    out.ee_rotation_error.push_back(rotation_errors.back());
    motion_t.push_back(t);
    motion_xyz.push_back(got.translation());
  }
  if (position_errors.size() == 0) {
    out.ee_problem = "no ground truth of " + out.tip_link + " and " + out.base_link + " within the span compared";
    return out;
  }
  out.ee_position_m = compute_stats(std::move(position_errors));
  out.ee_rotation_deg = compute_stats(std::move(rotation_errors));
  out.oscillation = oscillation(motion_t, motion_xyz, kSpectrumStepUs, options.oscillation_cutoff_hz);
  return out;
}

}  // namespace driftlab::analyzers
