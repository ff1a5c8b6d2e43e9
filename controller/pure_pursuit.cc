#include "controller/pure_pursuit.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/config.h"

namespace driftlab::controller {
const config::Table<PurePursuitOptions>& pure_pursuit_table() {
  using O = PurePursuitOptions;
  using config::above;
  static const auto t =
      config::Table<O>()
          .number("lookahead", &O::lookahead, above(0, 100), "m", "distance to the carrot point along the route")
          .number("speed", &O::speed, above(0, 100), "m/s", "cruise speed")
          .number("max_angular", &O::max_angular, above(0, 100), "rad/s", "yaw-rate limit")
          .number("max_accel", &O::max_accel, above(0, 1000), "m/s^2", "forward acceleration limit")
          .number("max_decel", &O::max_decel, above(0, 1000), "m/s^2", "forward deceleration limit")
          .number("max_angular_accel", &O::max_angular_accel, above(0, 1000), "rad/s^2",
                  "yaw acceleration limit (abrupt turns make wheels slip)")
          .number("turn_in_place", &O::turn_in_place, above(0, 10), "rad",
                  "heading error beyond which the base turns on the spot (pi or more: never)")
          .number("goal_tolerance", &O::goal_tolerance, above(0, 1000), "m",
                  "distance at which an open route's last point counts as reached")
          .flag("loop", &O::loop, "the route closes on itself and is driven again and again")
          .number("stuck_timeout", &O::stuck_timeout, above(0, 1e5), "s",
                  "no progress along the route for this long: skip ahead by 2 lookaheads");
  return t;
}

Status read_route(const config::Value& v, std::vector<Point2>& route) {
  if (!v.node().IsSequence() || v.node().size() < 2) return v.error("must be a list of at least two [x, y] points");
  std::vector<Point2> out;
  double length = 0;
  for (std::size_t i = 0; i < v.node().size(); ++i) {
    const config::Value point = v[i];
    if (!point.node().IsSequence() || point.node().size() != 2) return point.error("must be a point [x, y]");
    auto xy = point.numbers(2, config::between(-1e6, 1e6), "m");
    if (!xy) return xy.error();
    out.push_back({(*xy)[0], (*xy)[1]});
    if (i > 0) length += std::hypot(out[i].x - out[i - 1].x, out[i].y - out[i - 1].y);
  }
  if (!(length > 0)) return v.error("has no length (its points are all the same)");
  route = std::move(out);
  return {};
}

PurePursuit::PurePursuit(std::vector<Point2> route, PurePursuitOptions options)
    : route_(std::move(route)), opt_(options) {
  if (route_.size() < 2) throw std::invalid_argument("a route needs at least two points");
  arc_.push_back(0);
  const std::size_t legs = opt_.loop ? route_.size() : route_.size() - 1;
  for (std::size_t i = 0; i < legs; ++i) {
    const Point2& a = route_[i];
    const Point2& b = route_[(i + 1) % route_.size()];
    arc_.push_back(arc_.back() + std::hypot(b.x - a.x, b.y - a.y));
  }
  if (arc_.back() <= 0) throw std::invalid_argument("a route needs two distinct points");
}

Point2 PurePursuit::point_at(double s) const {
  const double total = arc_.back();
  s = opt_.loop ? s - total * std::floor(s / total) : std::clamp(s, 0.0, total);
  const auto it = std::upper_bound(arc_.begin(), arc_.end(), s);
  const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(it - arc_.begin()), arc_.size() - 1) - 1;
  const Point2& a = route_[i];
  const Point2& b = route_[(i + 1) % route_.size()];
  const double len = arc_[i + 1] - arc_[i];
  const double u = len > 0 ? (s - arc_[i]) / len : 0;
  return {a.x + u * (b.x - a.x), a.y + u * (b.y - a.y)};
}

Command PurePursuit::update(const Pose2& pose, double dt) {
  if (finished_) return {};
  // Advance progress to the closest route point within a window ahead (never backwards), so a route that
  // passes near itself is followed in order.
  const double total = arc_.back();
  const double window = 2 * opt_.lookahead + 1.0;
  double best_s = progress_, best_d = INFINITY;
  const std::size_t n = arc_.size() - 1;
  for (std::size_t k = 0; k < n; ++k) {
    const double base = total * std::floor(progress_ / total);
    for (double wrap : {0.0, total}) {
      const double s0 = base + wrap + arc_[k], s1 = base + wrap + arc_[k + 1];
      if (s1 < progress_ || s0 > progress_ + window) continue;
      if (!opt_.loop && wrap > 0) continue;
      const Point2& a = route_[k];
      const Point2& b = route_[(k + 1) % route_.size()];
      const double dx = b.x - a.x, dy = b.y - a.y, len2 = dx * dx + dy * dy;
      double u = len2 > 0 ? ((pose.x - a.x) * dx + (pose.y - a.y) * dy) / len2 : 0;
      u = std::clamp(u, 0.0, 1.0);
      double s = s0 + u * (s1 - s0);
      if (s < progress_) s = progress_;
      if (s > progress_ + window) s = progress_ + window;
      const Point2 p = point_at(s);
      const double d = std::hypot(pose.x - p.x, pose.y - p.y);
      if (d < best_d) {
        best_d = d;
        best_s = s;
      }
    }
  }
  progress_ = std::max(progress_, best_s);
  cross_track_ = best_d;
  // Recovery: when the estimate makes no progress (an obstacle the estimate does not know about), give up on
  // this part of the route and aim further ahead, as a navigation stack would replan around it.
  if (progress_ > progress_mark_ + 0.1) {
    progress_mark_ = progress_;
    stuck_for_ = 0;
  } else if ((stuck_for_ += dt) > opt_.stuck_timeout) {
    progress_ += 2 * opt_.lookahead;
    if (!opt_.loop) progress_ = std::min(progress_, total);
    progress_mark_ = progress_;
    stuck_for_ = 0;
    ++skips_;
  }
  laps_ = opt_.loop ? static_cast<std::size_t>(progress_ / total) : 0;

  if (!opt_.loop && progress_ >= total - 1e-9) {
    const Point2& end = route_.back();
    if (std::hypot(end.x - pose.x, end.y - pose.y) < opt_.goal_tolerance) {
      finished_ = true;
      last_linear_ = last_angular_ = 0;
      return {};
    }
  }
  const Point2 carrot = point_at(progress_ + opt_.lookahead);
  const double dx = carrot.x - pose.x, dy = carrot.y - pose.y;
  const double heading_error = wrap_angle(std::atan2(dy, dx) - pose.yaw);
  const double dist = std::hypot(dx, dy);
  Command cmd;
  if (std::abs(heading_error) > opt_.turn_in_place) {
    cmd.angular = std::copysign(opt_.max_angular, heading_error);
  } else {
    // Pure pursuit: the arc through the carrot has curvature 2 sin(alpha) / L.
    const double curvature = dist > 1e-6 ? 2 * std::sin(heading_error) / dist : 0;
    double v = opt_.speed;
    if (!opt_.loop) v = std::min(v, std::max(0.1, total - progress_));  // slow down into the goal
    // Keep the yaw rate within its limit by slowing down in tight turns.
    if (std::abs(curvature * v) > opt_.max_angular) v = opt_.max_angular / std::abs(curvature);
    cmd.linear = v;
    cmd.angular = curvature * v;
  }
  if (dt > 0) {
    // Acceleration limits: abrupt changes make the wheels slip, which the odometry cannot see.
    cmd.linear = std::clamp(cmd.linear, last_linear_ - opt_.max_decel * dt, last_linear_ + opt_.max_accel * dt);
    const double da = opt_.max_angular_accel * dt;
    cmd.angular = std::clamp(cmd.angular, last_angular_ - da, last_angular_ + da);
  }
  last_linear_ = cmd.linear;
  last_angular_ = cmd.angular;
  return cmd;
}

Command avoid_obstacles(Command cmd, const std::vector<Point2>& points, const AvoidOptions& o) {
  double push_y = 0, front_clearance = INFINITY;
  for (const Point2& p : points) {
    const double d = std::hypot(p.x, p.y);
    const double gap = d - o.radius;
    if (gap >= o.margin || d < 1e-9) continue;
    const double ux = p.x / d, uy = p.y / d;
    const double w = (o.margin - gap) / o.margin;  // 0 at the margin, 1 at the body
    // Obstacles ahead of the axle (moving forward) or beside it push sideways, away from them.
    if (ux > -0.2) push_y -= w * uy;
    if (ux > 0.3 && std::abs(p.y) < o.radius + 0.05) front_clearance = std::min(front_clearance, p.x - o.radius);
  }
  const double wanted = cmd.linear;
  if (cmd.linear > 0 && std::isfinite(front_clearance)) {
    cmd.linear *= std::clamp((front_clearance - o.stop) / (o.margin - o.stop), 0.0, 1.0);
  }
  if (cmd.linear > 0) cmd.angular += o.gain * push_y;
  if (wanted > 0 && cmd.linear < 0.1 * wanted) {
    // Blocked ahead: turn on the spot, away from the obstacles (or the way the follower wanted to turn).
    const double side = push_y != 0 ? push_y : (cmd.angular != 0 ? cmd.angular : 1.0);
    cmd.angular = std::copysign(std::max(0.6, std::abs(cmd.angular)), side);
  }
  return cmd;
}

}  // namespace driftlab::controller
