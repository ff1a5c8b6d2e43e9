#include "controller/arm_commander.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/config.h"
#include "core/time.h"

namespace driftlab::controller {
namespace {

/// Minimum-jerk progress from 0 to 1 over u in [0, 1].
double min_jerk(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * u * (10 - 15 * u + 6 * u * u);
}

Status read_waypoints(const config::Value& v, std::vector<ArmWaypoint>& out) {
  if (!v.node().IsSequence() || v.node().size() == 0) {
    return v.error("must be a list of [x, y, z, yaw, move_s, dwell_s]");
  }
  std::vector<ArmWaypoint> w;
  for (std::size_t i = 0; i < v.node().size(); ++i) {
    auto n = v[i].numbers(6, config::between(-1e3, 1e3), "m, m, m, rad, s, s");
    if (!n) return n.error();
    const std::vector<double>& x = *n;
    if (!(x[4] > 0) || x[5] < 0) return v[i].error("move_s must be positive and dwell_s not negative");
    w.push_back({{x[0], x[1], x[2]}, x[3], x[4], x[5]});
  }
  out = std::move(w);
  return {};
}

}  // namespace

Eigen::Matrix3d gripper_down(double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

const config::Table<ArmCommanderOptions>& arm_commander_table() {
  using O = ArmCommanderOptions;
  using config::between;
  static const auto t =
      config::Table<O>()
          .number("rate", &O::rate, config::above(0, 1000), "Hz", "commands per second")
          .integer("horizon", &O::horizon, between(1, 1000), "", "points per command, a period apart")
          .number("feedback_gain", &O::feedback_gain, between(0, 2), "",
                  "share of the error between plan and measured joints added to each command")
          .text("base_link", &O::base_link, "the frame of the waypoints", config::Text::kNonEmpty)
          .text("tip_link", &O::tip_link, "the link placed at the waypoints", config::Text::kNonEmpty)
          .custom<std::vector<double>>(
              "home", &O::home, "list of numbers", "rad", "-10..10 each",
              "joint positions at the start, in chain order",
              [](const config::Value& v, std::vector<double>& out) -> Status {
                if (!v.node().IsSequence()) return v.error("must be a list of joint positions");
                auto n = v.numbers(v.node().size(), config::between(-10, 10), "rad");
                if (!n) return n.error();
                out = std::move(*n);
                return {};
              },
              [](const std::vector<double>& q) { return std::to_string(q.size()) + " positions"; })
          .custom<std::vector<ArmWaypoint>>(
              "waypoints", &O::waypoints, "list of [x, y, z, yaw, move_s, dwell_s]", "m, rad, s", "at least 1",
              "the pick-and-place cycle in the base link's frame, gripper down", read_waypoints,
              [](const std::vector<ArmWaypoint>& w) { return std::to_string(w.size()) + " waypoints"; });
  return t;
}

ArmCommander::ArmCommander(kinematics::ArmChain chain, ArmCommanderOptions options)
    : chain_(std::move(chain)), o_(std::move(options)) {}

Result<ArmCommander> ArmCommander::create(kinematics::ArmChain chain, ArmCommanderOptions options) {
  if (static_cast<int>(options.home.size()) != chain.dof()) {
    return Error{"arm commander: home has " + std::to_string(options.home.size()) + " joint positions, the chain " +
                 std::to_string(chain.dof())};
  }
  for (int i = 0; i < chain.dof(); ++i) {
    const kinematics::JointLimits& l = chain.limits()[static_cast<size_t>(i)];
    const double q = options.home[static_cast<size_t>(i)];
    if (l.has_position && (q < l.lower || q > l.upper)) {
      return Error{"arm commander: home position of joint '" + chain.joint_names()[static_cast<size_t>(i)] +
                   "' is outside its limits"};
    }
  }
  if (options.waypoints.empty()) return Error{"arm commander: no waypoints"};
  ArmCommander c(std::move(chain), std::move(options));
  c.start_pose_ = c.chain_.fk(Eigen::Map<const Eigen::VectorXd>(c.o_.home.data(), c.chain_.dof()));
  double t = 0;
  for (const ArmWaypoint& w : c.o_.waypoints) {
    c.leg_start_.push_back(t);
    t += w.move_s + w.dwell_s;
  }
  c.cycle_s_ = t;
  // Every waypoint must be reachable: solve the first cycle now, so a bad plan is an error before the run.
  const int64_t steps = static_cast<int64_t>(std::ceil(c.cycle_s_ * c.o_.rate)) + 1;
  for (int64_t k = 0; k <= steps; ++k) c.joints_at(k);
  if (c.ik_failures_ > 0) {
    for (size_t i = 0; i < c.o_.waypoints.size(); ++i) {
      const ArmWaypoint& w = c.o_.waypoints[i];
      Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
      target.linear() = gripper_down(w.yaw);
      target.translation() = w.position;
      const auto r = c.chain_.ik(target, Eigen::Map<const Eigen::VectorXd>(c.o_.home.data(), c.chain_.dof()));
      if (!r.converged || r.position_error > 1e-3) {
        char why[200];
        std::snprintf(why, sizeof(why), "arm commander: waypoint %zu (%.3f, %.3f, %.3f) is out of the arm's reach",
                      i + 1, w.position.x(), w.position.y(), w.position.z());
        return Error{why};
      }
    }
    return Error{"arm commander: the path between the waypoints leaves the arm's reach"};
  }
  return c;
}

Eigen::Isometry3d ArmCommander::plan(double s) const {
  // The first move starts from home's pose; then each leg from the waypoint before (the last one before the first).
  const size_t n = o_.waypoints.size();
  const bool first_cycle = s < cycle_s_;
  s = std::fmod(std::max(0.0, s), cycle_s_);
  size_t leg = static_cast<size_t>(std::upper_bound(leg_start_.begin(), leg_start_.end(), s) - leg_start_.begin()) - 1;
  const ArmWaypoint& to = o_.waypoints[leg];
  Eigen::Isometry3d from_pose = start_pose_;
  if (leg > 0 || !first_cycle) {
    const ArmWaypoint& from = o_.waypoints[(leg + n - 1) % n];
    from_pose.linear() = gripper_down(from.yaw);
    from_pose.translation() = from.position;
  }
  const double u = min_jerk((s - leg_start_[leg]) / to.move_s);
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translation() = from_pose.translation() + u * (to.position - from_pose.translation());
  const Eigen::Quaterniond qa(from_pose.rotation()), qb(gripper_down(to.yaw));
  out.linear() = qa.slerp(u, qb).toRotationMatrix();
  return out;
}

const Eigen::VectorXd& ArmCommander::joints_at(int64_t k) {
  if (auto it = solved_.find(k); it != solved_.end()) return it->second;
  // Seeded by the step before (solved first when missing), so the solution follows the arm's branch.
  Eigen::VectorXd seed =
      k > 0 ? Eigen::VectorXd(joints_at(k - 1)) : Eigen::Map<const Eigen::VectorXd>(o_.home.data(), chain_.dof());
  Eigen::VectorXd q = seed;
  if (k > 0) {
    const kinematics::IkResult r = chain_.ik(plan(static_cast<double>(k) / o_.rate), seed);
    if (r.converged) {
      q = r.q;
    } else {
      ++ik_failures_;  // keep the previous solution: the arm waits rather than jumps
    }
  }
  // Keep a window of steps behind the newest (commands look back one step).
  while (!solved_.empty() && solved_.begin()->first < k - 4 * int64_t{o_.horizon}) solved_.erase(solved_.begin());
  return solved_.emplace(k, std::move(q)).first->second;
}

driftlab::joint_trajectory_t ArmCommander::command(int64_t t, const std::optional<Eigen::VectorXd>& measured) {
  if (!start_) start_ = t;
  const double period = 1.0 / o_.rate;
  const auto k = static_cast<int64_t>(std::llround(seconds_between(*start_, t) * o_.rate));
  const int n = chain_.dof();
  Eigen::VectorXd correction = Eigen::VectorXd::Zero(n);
  if (measured && measured->size() == n) correction = o_.feedback_gain * (joints_at(k) - *measured);
  driftlab::joint_trajectory_t m{};
  m.header.frame_id = o_.base_link;
  m.njoints = n;
  m.joint_names = chain_.joint_names();
  m.npoints = o_.horizon;
  for (int i = 1; i <= o_.horizon; ++i) {
    const Eigen::VectorXd before = joints_at(k + i - 1), here = joints_at(k + i), after = joints_at(k + i + 1);
    const Eigen::VectorXd q = here + correction;
    const Eigen::VectorXd v = (after - before) / (2 * period);
    driftlab::joint_trajectory_point_t p{};
    p.time_from_start_us = Duration::from_seconds_rounded(i * period).us();
    p.npositions = n;
    p.positions.assign(q.data(), q.data() + n);
    p.nvelocities = n;
    p.velocities.assign(v.data(), v.data() + n);
    m.points.push_back(std::move(p));
  }
  return m;
}

}  // namespace driftlab::controller
