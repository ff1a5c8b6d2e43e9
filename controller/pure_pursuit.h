// Pure-pursuit path following for a differential-drive base: steers towards the point one lookahead distance
// ahead on the route, from whatever pose estimate it is given (in the simulator: the robot's own noisy wheel
// odometry, so odometry drift shows up in the ground truth, as on a real robot).
// Thread-safety: one PurePursuit per thread; it keeps its progress along the route.
#pragma once

#include <cstddef>
#include <vector>

#include "core/result.h"
#include "lcmtypes/planar.h"

namespace driftlab::config {
template <class T>
class Table;
class Value;
}  // namespace driftlab::config

namespace driftlab::controller {

struct Point2 {
  double x = 0, y = 0;  ///< [m]
};

struct Command {
  double linear = 0;   ///< forward speed [m/s]
  double angular = 0;  ///< yaw rate [rad/s], counter-clockwise
};

struct PurePursuitOptions {
  double lookahead = 0.8;       ///< distance to the carrot point along the route [m]
  double speed = 0.6;           ///< cruise speed [m/s]
  double max_angular = 1.2;     ///< yaw-rate limit [rad/s]
  double max_accel = 1.0;       ///< forward acceleration limit [m/s^2]
  double max_decel = 2.0;       ///< forward deceleration limit [m/s^2]
  double max_angular_accel = 3.0;  ///< yaw acceleration limit [rad/s^2] (abrupt turns make wheels slip)
  double turn_in_place = 1.2;   ///< heading error beyond which the base turns on the spot [rad]
  double goal_tolerance = 0.3;  ///< distance at which an open route's last point counts as reached [m]
  bool loop = true;             ///< the route closes on itself and is driven again and again
  double stuck_timeout = 8.0;   ///< no progress along the route for this long: skip ahead by 2 lookaheads [s]
};

/// The follower's keys (lookahead, speed, ...; core/config.h): the one key set wherever they are read, in the
/// simulator's scenario (`controller:`) and in the controller module's config.
const config::Table<PurePursuitOptions>& pure_pursuit_table();

/// Reads a route: a list of at least two [x, y] points in the world frame [m], not all the same.
Status read_route(const config::Value& value, std::vector<Point2>& route);

/// A reactive safety layer (like Nav2's collision monitor): slows down for obstacles ahead and steers away
/// from obstacles close to the body, so a robot whose odometry has drifted grazes past door frames instead of
/// driving into them.
struct AvoidOptions {
  double radius = 0.2;    ///< the robot's footprint radius [m]
  double margin = 0.35;   ///< obstacles within this distance of the footprint push the robot away [m]
  double stop = 0.05;     ///< forward motion stops when an obstacle ahead is this close to the footprint [m]
  double gain = 2.0;      ///< yaw rate per unit of lateral push [rad/s]
};

/// Adjusts `cmd` for obstacle points given in the robot's frame (x forward, y left) [m], e.g. the returns
/// of a range-sensor ring.
Command avoid_obstacles(Command cmd, const std::vector<Point2>& points, const AvoidOptions& options);

class PurePursuit {
 public:
  /// route: at least two points. Throws std::invalid_argument otherwise (callers validate configs first).
  PurePursuit(std::vector<Point2> route, PurePursuitOptions options);

  /// The command for the pose estimate `pose` at time step `dt` [s] since the previous call (for the
  /// acceleration limit). Progress along the route only moves forward, so a loop that passes near itself is
  /// followed in order.
  Command update(const Pose2& pose, double dt);

  /// An open route's end was reached (always false on a loop).
  bool finished() const { return finished_; }
  /// Completed laps of a looped route.
  std::size_t laps() const { return laps_; }
  /// Distance from the last pose to the route [m] (cross-track error against the estimate).
  double cross_track() const { return cross_track_; }
  /// How often the follower skipped ahead after being stuck.
  std::size_t skips() const { return skips_; }

 private:
  Point2 point_at(double s) const;  ///< the route point at arc length s (wrapped on a loop) [m]

  std::vector<Point2> route_;
  std::vector<double> arc_;  ///< arc length at each vertex; arc_.back() is the total (incl. the closing leg on a loop)
  PurePursuitOptions opt_;
  double progress_ = 0;  ///< arc length of the closest route point found so far [m], unwrapped
  double last_linear_ = 0;
  double last_angular_ = 0;
  double cross_track_ = 0;
  std::size_t laps_ = 0;
  std::size_t skips_ = 0;
  double stuck_for_ = 0;       ///< time without progress [s]
  double progress_mark_ = 0;   ///< progress when stuck_for_ was last reset [m]
  bool finished_ = false;
};

}  // namespace driftlab::controller
