#include "sim/internal/ground_loop.h"

#include <cmath>

#include "driftlab/velocity_command_t.hpp"
#include "lcmtypes/planar.h"

namespace driftlab::sim {

/// The proximity ring's rays, evenly around the robot.
constexpr int kProximityRays = 36;

GroundLoop::GroundLoop(const Scenario& sc, Robot& robot, const RayCaster& caster, Output& out, WheelOdometry& odometry,
                       bool odometry_sensor, double odom_rate)
    : sc_(sc),
      robot_(robot),
      caster_(caster),
      out_(out),
      odometry_(odometry),
      odometry_sensor_(odometry_sensor),
      odom_rate_(odom_rate),
      pursuit_(sc.route, sc.controller.pursuit),
      stream_(out.add_stream(sc.controller.channel)) {
  avoid_.radius = sc.controller.footprint_radius;
}

void GroundLoop::advance_odometry(int64_t t_us) {
  if (odometry_sensor_ || t_us < due_us(n_odom_, odom_rate_)) return;
  ++n_odom_;
  odometry_.update(robot_, 1.0 / odom_rate_);
}

Eigen::Vector2d GroundLoop::odometry_position() const {
  const double c0 = std::cos(sc_.start.z()), s0 = std::sin(sc_.start.z());
  return {sc_.start.x() + c0 * odometry_.x() - s0 * odometry_.y(),
          sc_.start.y() + s0 * odometry_.x() + c0 * odometry_.y()};
}

void GroundLoop::control(int64_t t_us, int64_t now, double dt, bool hold) {
  if (t_us < due_us(n_cmd_, sc_.controller.rate)) return;
  ++n_cmd_;
  // The route is followed by the odometry (started at the robot's start pose).
  const Eigen::Vector2d at = odometry_position();
  controller::Command cmd =
      pursuit_.update(Pose2{at.x(), at.y(), sc_.start.z() + odometry_.yaw()}, 1.0 / sc_.controller.rate);
  // The robot's proximity ring (a bumper-height range-sensor ring) feeds the reactive safety layer.
  const Eigen::Isometry3d base = robot_.link_pose(robot_.base_link());
  const Eigen::Vector3d ring_origin = base * Eigen::Vector3d(0, 0, 0.05);
  proximity_.clear();
  for (int i = 0; i < kProximityRays; ++i) {
    const double a = 2 * M_PI * i / kProximityRays;
    const Eigen::Vector3d local(std::cos(a), std::sin(a), 0);
    const double d = caster_.range(ring_origin, base.rotation() * local, 1.0);
    if (std::isfinite(d)) proximity_.push_back({local.x() * d, local.y() * d});
  }
  cmd = controller::avoid_obstacles(cmd, proximity_, avoid_);
  if (hold) cmd = {};
  const double r = robot_.wheel_radius(), b = robot_.wheel_separation();
  robot_.set_wheel_rates((cmd.linear - cmd.angular * b / 2) / r, (cmd.linear + cmd.angular * b / 2) / r, dt);
  driftlab::velocity_command_t m{};
  m.header.frame_id = robot_.base_link();
  m.linear = {cmd.linear, 0, 0};
  m.angular = {0, 0, cmd.angular};
  out_.publish(stream_, m, now, now);
}

}  // namespace driftlab::sim
