#include "controller/joint_trajectory.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/config.h"
#include "core/time.h"

namespace driftlab::controller {
namespace {

/// Cubic Hermite interpolation between (q0, v0) at 0 and (q1, v1) at h, at s in [0, h] [s]: position and velocity.
void hermite(const Eigen::VectorXd& q0, const Eigen::VectorXd& v0, const Eigen::VectorXd& q1, const Eigen::VectorXd& v1,
             double h, double s, Eigen::VectorXd& q, Eigen::VectorXd& v) {
  const double u = s / h, u2 = u * u, u3 = u2 * u;
  const double h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
  const double d00 = (6 * u2 - 6 * u) / h, d10 = 3 * u2 - 4 * u + 1, d01 = (-6 * u2 + 6 * u) / h, d11 = 3 * u2 - 2 * u;
  q = h00 * q0 + h10 * h * v0 + h01 * q1 + h11 * h * v1;
  v = d00 * q0 + d10 * v0 + d01 * q1 + d11 * v1;
}

}  // namespace

const config::Table<JointTrajectoryOptions>& joint_trajectory_table() {
  using O = JointTrajectoryOptions;
  using config::between;
  static const auto t =
      config::Table<O>()
          .choice("start", &O::start, {"arrival", "stamp"},
                  "when a trajectory's time starts: when it arrives, or at its header stamp (then one that ends "
                  "before it arrives is rejected as stale)")
          .number("kp", &O::kp, between(0, 1e4), "1/s", "position gain: velocity command per position error")
          .number("ki", &O::ki, between(0, 1e6), "1/s^2", "integral gain on the position error")
          .number("ff_velocity_scale", &O::ff_velocity_scale, between(0, 2), "",
                  "share of the trajectory's velocity fed forward")
          .number("path_tolerance", &O::path_tolerance, between(0, 10), "rad",
                  "a position error beyond this during a trajectory aborts it; 0: no check")
          .number("goal_tolerance", &O::goal_tolerance, config::above(0, 10), "rad",
                  "position error allowed at the trajectory's end")
          .number("goal_time", &O::goal_time, between(0, 60), "s",
                  "time after the last point to come within goal_tolerance")
          .number("state_rate", &O::state_rate, config::above(0, 1e4), "Hz",
                  "driftlab.joint_trajectory_state_t per second");
  return t;
}

JointTrajectoryController::JointTrajectoryController(std::vector<std::string> joints,
                                                     std::vector<kinematics::JointLimits> limits,
                                                     JointTrajectoryOptions options)
    : joints_(std::move(joints)), limits_(std::move(limits)), o_(std::move(options)) {
  const auto n = static_cast<Eigen::Index>(joints_.size());
  desired_q_ = Eigen::VectorXd::Zero(n);
  desired_v_ = Eigen::VectorXd::Zero(n);
  integral_ = Eigen::VectorXd::Zero(n);
}

driftlab::joint_trajectory_result_t JointTrajectoryController::result(const Active& a, int64_t now,
                                                                      const std::string& status,
                                                                      const std::string& joint, double error,
                                                                      const std::string& message) {
  driftlab::joint_trajectory_result_t r{};
  r.header.seq = result_seq_++;
  r.header.utime = now;
  r.trajectory_seq = a.seq;
  r.trajectory_utime = a.stamp;
  r.status = status;
  r.joint = joint;
  r.error = error;
  r.message = message;
  return r;
}

std::optional<driftlab::joint_trajectory_result_t> JointTrajectoryController::receive(
    const driftlab::joint_trajectory_t& msg, Time at) {
  const int64_t now = at.us();  // the points' times are summed with overflow checks, on the counts
  ++counts_.received;
  Active a;
  a.seq = msg.header.seq;
  a.stamp = msg.header.utime;
  auto invalid = [&](const std::string& why) {
    ++counts_.invalid;
    return result(a, now, "invalid", "", 0, why);
  };
  const size_t n = joints_.size();
  // The trajectory's joints, in any order, must be ours.
  std::vector<int> column(n, -1);
  if (msg.njoints != static_cast<int32_t>(msg.joint_names.size())) return invalid("njoints does not match");
  for (size_t i = 0; i < msg.joint_names.size(); ++i) {
    const auto it = std::find(joints_.begin(), joints_.end(), msg.joint_names[i]);
    if (it == joints_.end()) return invalid("unknown joint '" + msg.joint_names[i] + "'");
    column[static_cast<size_t>(it - joints_.begin())] = static_cast<int>(i);
  }
  for (size_t j = 0; j < n; ++j) {
    if (column[j] < 0) return invalid("joint '" + joints_[j] + "' is missing");
  }
  if (msg.points.empty()) return invalid("no points");
  const int64_t start = o_.start == "stamp" ? msg.header.utime : now;
  int64_t previous = -1;
  for (const auto& p : msg.points) {
    if (p.positions.size() != static_cast<size_t>(msg.njoints) ||
        (!p.velocities.empty() && p.velocities.size() != static_cast<size_t>(msg.njoints))) {
      return invalid("a point's positions or velocities do not match the joints");
    }
    if (p.time_from_start_us <= previous) return invalid("point times must increase");
    previous = p.time_from_start_us;
    Point pt;
    // A stamp near the end of int64_t (a clock gone wrong) would wrap the point into the past.
    if (__builtin_add_overflow(start, p.time_from_start_us, &pt.t))
      return invalid("a point's time is past the clock's end");
    pt.q.resize(static_cast<Eigen::Index>(n));
    pt.v = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
    pt.has_v = !p.velocities.empty();
    for (size_t j = 0; j < n; ++j) {
      const auto c = static_cast<size_t>(column[j]);
      const kinematics::JointLimits& l = limits_[j];
      double q = p.positions[c];
      if (!std::isfinite(q) || (pt.has_v && !std::isfinite(p.velocities[c]))) return invalid("a value is not finite");
      if (l.has_position) q = std::clamp(q, l.lower, l.upper);  // never command past a limit
      pt.q[static_cast<Eigen::Index>(j)] = q;
      if (pt.has_v) pt.v[static_cast<Eigen::Index>(j)] = p.velocities[c];
    }
    a.points.push_back(std::move(pt));
  }
  if (a.points.back().t < now) {
    ++counts_.stale;
    char why[160];
    const double late = seconds_between(a.points.back().t, now);
    std::snprintf(why, sizeof(why), "stale: the trajectory ended %.3f s before it arrived", late);
    return result(a, now, "stale", "", late, why);
  }
  // It starts from where the controller wants the joints now (ros2_control with open_loop_control: the reference
  // stays continuous), unless its first point is already past.
  if (initialised_) {
    Point from;
    from.t = now;
    from.q = desired_q_;
    from.v = desired_v_;
    from.has_v = a.points.front().has_v;
    if (a.points.front().t > now) a.points.insert(a.points.begin(), std::move(from));
  }
  if (active_) ++counts_.preempted;
  active_ = std::move(a);
  return std::nullopt;
}

void JointTrajectoryController::sample(int64_t now) {
  const std::vector<Point>& p = active_->points;
  if (now <= p.front().t) {
    desired_q_ = p.front().q;
    desired_v_ = p.front().t == now ? p.front().v : Eigen::VectorXd::Zero(desired_q_.size());
    return;
  }
  if (now >= p.back().t) {
    desired_q_ = p.back().q;
    desired_v_.setZero();
    return;
  }
  const auto next = std::upper_bound(p.begin(), p.end(), now, [](int64_t t, const Point& x) { return t < x.t; });
  const Point& b = *next;
  const Point& a = *(next - 1);
  const double h = seconds_between(a.t, b.t), s = seconds_between(a.t, now);
  if (a.has_v && b.has_v) {
    hermite(a.q, a.v, b.q, b.v, h, s, desired_q_, desired_v_);
  } else {
    desired_q_ = a.q + (b.q - a.q) * (s / h);
    desired_v_ = (b.q - a.q) / h;
  }
}

std::optional<driftlab::joint_trajectory_result_t> JointTrajectoryController::update(Time at,
                                                                                     const Eigen::VectorXd& position,
                                                                                     Eigen::VectorXd& command) {
  const int64_t now = at.us();
  std::optional<driftlab::joint_trajectory_result_t> out;
  const double dt = initialised_ ? seconds_between(last_update_, now) : 0;
  if (!initialised_) {  // hold where the joints are
    desired_q_ = position;
    desired_v_.setZero();
    initialised_ = true;
    if (active_ && active_->points.front().t > now) {
      Point from{now, position, Eigen::VectorXd::Zero(position.size()), active_->points.front().has_v};
      active_->points.insert(active_->points.begin(), std::move(from));
    }
  }
  last_update_ = now;
  if (active_) {
    sample(now);
    const Eigen::VectorXd error = desired_q_ - position;
    Eigen::Index worst = 0;
    const double worst_error = error.cwiseAbs().maxCoeff(&worst);
    const int64_t end = active_->points.back().t;
    const std::string& joint = joints_[static_cast<size_t>(worst)];
    char why[200];
    if (now <= end && o_.path_tolerance > 0 && worst_error > o_.path_tolerance) {
      std::snprintf(why, sizeof(why), "aborted: joint %s is %.4f rad off its path (tolerance %.4f rad)", joint.c_str(),
                    error[worst], o_.path_tolerance);
      out = result(*active_, now, "path_tolerance_violated", joint, error[worst], why);
      ++counts_.aborted;
      active_.reset();
      desired_q_ = position;  // hold where it is, as ros2_control does on an abort
      desired_v_.setZero();
    } else if (now >= end && worst_error <= o_.goal_tolerance) {
      out = result(*active_, now, "succeeded", "", error[worst], "succeeded");
      ++counts_.succeeded;
      active_.reset();
    } else if (us_after(end, now) > static_cast<uint64_t>(Duration::from_seconds_rounded(o_.goal_time).us())) {
      std::snprintf(why, sizeof(why),
                    "aborted: joint %s is %.4f rad from its goal %.3f s after the end (tolerance %.4f)", joint.c_str(),
                    error[worst], o_.goal_time, o_.goal_tolerance);
      out = result(*active_, now, "goal_tolerance_violated", joint, error[worst], why);
      ++counts_.aborted;
      active_.reset();
    }
  }
  const Eigen::VectorXd error = desired_q_ - position;
  integral_ += error * dt;
  command = o_.ff_velocity_scale * desired_v_ + o_.kp * error + o_.ki * integral_;
  for (Eigen::Index j = 0; j < command.size(); ++j) {
    const double limit = limits_[static_cast<size_t>(j)].velocity;
    if (limit > 0 && std::abs(command[j]) > limit) {
      command[j] = std::copysign(limit, command[j]);
      integral_[j] -= error[j] * dt;  // no wind-up while saturated
    }
  }
  return out;
}

}  // namespace driftlab::controller
