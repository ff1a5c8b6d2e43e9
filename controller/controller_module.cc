#include "controller/controller_module.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/config.h"
#include "core/time.h"
#include "driftlab/command_comparison_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "driftlab/velocity_command_t.hpp"
#include "lcmtypes/planar.h"
#include "runtime/module_input.h"

namespace driftlab::controller {
namespace {

constexpr int kSectors = 36;        // the obstacle layer sees the scan as a ring of sectors, like a bumper ring
constexpr double kObstacleRange = 1.0;  // [m]

/// The logged value in force at time t (zero-order hold); false before the first.
bool held_at(const std::vector<CommandSample>& s, int64_t t, size_t& hint, CommandSample& out) {
  if (s.empty() || t < s.front().utime) return false;
  if (hint >= s.size() || s[hint].utime > t) hint = 0;
  while (hint + 1 < s.size() && s[hint + 1].utime <= t) ++hint;
  out = s[hint];
  return true;
}

}  // namespace

const config::Table<ControllerConfig>& controller_config_table() {
  using C = ControllerConfig;
  using config::Text;
  static const auto t =
      config::Table<C>()
          .describe(
              "Without `route`, or with `scenario`, the route, start, rate, footprint_radius, the follower's keys "
              "(lookahead ... stuck_timeout) and logged_channel default to the scenario's (the default scenario "
              "when neither is given), and the keys given here override them; the defaults shown are those without "
              "a scenario.")
          .text("scenario", &C::scenario,
                "a simulator scenario to take the defaults from (relative to the config file)")
          .shown_default("the default scenario, without `route`")
          .custom<std::vector<Point2>>(
              "route", &C::route, "list of [x, y]", "m", "at least 2 points", "the route to follow, in the world frame",
              read_route,
              [](const std::vector<Point2>& r) { return std::to_string(r.size()) + " points"; })
          .shown_default("the scenario's")
          .numbers("start", &C::start, {&Pose2::x, &Pose2::y, &Pose2::yaw}, config::between(-1e6, 1e6), "m, m, rad",
                   "where the estimate's frame starts in the world: x, y, yaw")
          .number("rate", &C::rate, config::between(0.1, 1000), "Hz", "ticks of the follower, on the bus's clock")
          .include(&C::pursuit, pure_pursuit_table())
          .text("estimate_channel", &C::estimate_channel,
                "driftlab.odometry_t or pose_t to follow (e.g. EKF_ODOM, SLAM_POSE)", Text::kNonEmpty)
          .flag("estimate_in_world", &C::estimate_in_world, "the estimate is in the world frame already")
          .text("scan_channel", &C::scan_channel, "driftlab.laser_scan_t for the obstacle layer; \"\" for none")
          .number("footprint_radius", &C::footprint_radius, config::above(0, 100), "m",
                  "the robot's footprint, for the obstacle layer")
          .text("command_channel", &C::command_channel, "driftlab.velocity_command_t out", Text::kNonEmpty)
          .text("logged_channel", &C::logged_channel, "the logged commands to compare with; \"\" for none")
          .text("comparison_channel", &C::comparison_channel, "driftlab.command_comparison_t out, at the end")
          .number("max_delay_s", &C::max_delay_s, config::between(0, 10), "s",
                  "the delay between recomputed and logged commands is searched over +-max_delay_s");
  return t;
}

Result<ControllerConfig> parse_controller_config(const YAML::Node& node, const std::string& origin,
                                                 ControllerConfig base) {
  auto c = controller_config_table().parse(config::Value(node, origin, "controller"), std::move(base));
  if (!c) return c.error();
  if (c->route.size() < 2) {
    return Error{origin + ": controller: no route (give controller.route, or controller.scenario with a route)"};
  }
  return c;
}

std::optional<CommandComparison> compare_commands(const std::vector<CommandSample>& recomputed,
                                                  const std::vector<CommandSample>& logged, double max_delay_s) {
  CommandComparison out;
  if (recomputed.empty() || logged.empty()) return std::nullopt;
  auto rmse_at = [&](int64_t lag, CommandComparison* fill) {
    double se_l = 0, se_a = 0, max_l = 0, max_a = 0;
    int32_t n = 0;
    size_t hint = 0;
    CommandSample held;
    for (const CommandSample& r : recomputed) {
      int64_t at = 0;  // saturated: log times at the end of int64_t (a hostile log) must not overflow
      if (__builtin_add_overflow(r.utime, lag, &at)) at = lag > 0 ? INT64_MAX : INT64_MIN;
      if (!held_at(logged, at, hint, held)) continue;
      const double dl = r.linear - held.linear, da = r.angular - held.angular;
      se_l += dl * dl;
      se_a += da * da;
      max_l = std::max(max_l, std::abs(dl));
      max_a = std::max(max_a, std::abs(da));
      ++n;
    }
    if (fill != nullptr && n > 0) {
      fill->matched = n;
      fill->linear_rmse = std::sqrt(se_l / n);
      fill->angular_rmse = std::sqrt(se_a / n);
      fill->linear_max_abs = max_l;
      fill->angular_max_abs = max_a;
    }
    return n > 0 ? std::sqrt(se_a / n) : INFINITY;
  };
  out.angular_rmse_at_delay = rmse_at(0, &out);  // INFINITY: nothing compared at this lag
  const auto steps = static_cast<int64_t>(std::floor(max_delay_s / 0.01));
  for (int64_t k = -steps; k <= steps; ++k) {
    const double e = rmse_at(k * 10000, nullptr);
    if (e < out.angular_rmse_at_delay - 1e-12) {
      out.angular_rmse_at_delay = e;
      out.delay_s = static_cast<double>(k) * 0.01;
    }
  }
  // No lag compared a single command (the recomputed ones all before the first logged one, or farther from them
  // than the search reaches): there is no comparison, and no number to give.
  if (std::isinf(out.angular_rmse_at_delay)) return std::nullopt;
  return out;
}

ControllerModule::ControllerModule(ControllerConfig config)
    : c_(std::move(config)), pursuit_(c_.route, c_.pursuit) {}

Status ControllerModule::start(Bus& bus) {
  bus.subscribe(c_.estimate_channel, [this](const BusMessage& m) {
    Pose2 p;
    driftlab::odometry_t o;
    driftlab::pose_t pose;
    if (decode_message(m, o)) {
      p = {o.position.x, o.position.y, yaw_of(o.orientation)};
    } else if (decode_message(m, pose)) {
      p = {pose.position.x, pose.position.y, yaw_of(pose.orientation)};
    } else {
      ++undecodable_;
      return;
    }
    if (!non_finite_.finite(m)) return;
    if (!c_.estimate_in_world) {  // the estimate's frame starts at the robot's start pose
      const double c = std::cos(c_.start.yaw), s = std::sin(c_.start.yaw);
      p = {c_.start.x + c * p.x - s * p.y, c_.start.y + s * p.x + c * p.y, c_.start.yaw + p.yaw};
    }
    // Finite fields can still give a NaN pose (a quaternion of huge numbers has no yaw).
    if (!std::isfinite(p.yaw)) return non_finite_.count(m.channel, "the yaw of orientation = nan");
    if (!non_finite_.plausible(m.channel, "position.x", p.x) || !non_finite_.plausible(m.channel, "position.y", p.y)) {
      return;
    }
    estimate_ = p;
  });
  if (!c_.scan_channel.empty()) {
    bus.subscribe(c_.scan_channel, [this](const BusMessage& m) {
      driftlab::laser_scan_t scan;
      if (!decode_message(m, scan)) return void(++undecodable_);
      if (!non_finite_.finite(m)) return;
      // The nearest return per sector within reach, in the scan's frame (taken as the base's: the obstacle layer
      // only needs directions and distances to within the laser's offset).
      double nearest[kSectors];
      std::fill(std::begin(nearest), std::end(nearest), INFINITY);
      for (int i = 0; i < scan.nranges; ++i) {
        const float r = scan.ranges[static_cast<size_t>(i)];
        if (!(r >= scan.range_min && r <= scan.range_max) || r > kObstacleRange) continue;
        // Wrapped first: a huge angle would overflow the sector index.
        const double a = std::remainder(scan.angle_min + i * static_cast<double>(scan.angle_increment), 2 * M_PI);
        if (!std::isfinite(a)) continue;
        int k = static_cast<int>(std::floor((a + M_PI) / (2 * M_PI) * kSectors)) % kSectors;
        if (k < 0) k += kSectors;
        nearest[k] = std::min(nearest[k], static_cast<double>(r));
      }
      obstacles_.clear();
      for (int k = 0; k < kSectors; ++k) {
        if (!std::isfinite(nearest[k])) continue;
        const double a = -M_PI + (k + 0.5) * 2 * M_PI / kSectors;
        obstacles_.push_back({nearest[k] * std::cos(a), nearest[k] * std::sin(a)});
      }
    });
  }
  if (!c_.logged_channel.empty()) {
    bus.subscribe(c_.logged_channel, [this](const BusMessage& m) {
      driftlab::velocity_command_t cmd;
      if (!decode_message(m, cmd)) return void(++undecodable_);
      if (!non_finite_.finite(m) || !non_finite_.plausible(m.channel, "linear.x", cmd.linear.x) ||
          !non_finite_.plausible(m.channel, "angular.z", cmd.angular.z)) {
        return;  // a command of 1e300 would make the comparison's RMSE infinite
      }
      logged_.push_back({m.time.us(), cmd.linear.x, cmd.angular.z});
    });
  }
  bus.every(Duration::periods_rounded(c_.rate), [this, &bus] { tick(bus); });
  return {};
}

void ControllerModule::tick(Bus& bus) {
  if (!estimate_) return;  // nothing to follow yet
  Command cmd = pursuit_.update(*estimate_, 1.0 / c_.rate);
  AvoidOptions avoid;
  avoid.radius = c_.footprint_radius;
  cmd = avoid_obstacles(cmd, obstacles_, avoid);
  driftlab::velocity_command_t m{};
  m.header.seq = seq_++;
  m.header.utime = bus.now().us();
  m.header.frame_id = "base_link";
  m.linear = {cmd.linear, 0, 0};
  m.angular = {0, 0, cmd.angular};
  bus.publish_message(c_.command_channel, m);
  recomputed_.push_back({bus.now().us(), cmd.linear, cmd.angular});
}

void ControllerModule::finish(Bus& bus) {
  finished_ = true;
  if (c_.logged_channel.empty() || logged_.empty() || recomputed_.empty()) return;
  std::stable_sort(logged_.begin(), logged_.end(),
                   [](const CommandSample& a, const CommandSample& b) { return a.utime < b.utime; });
  comparison_ = compare_commands(recomputed_, logged_, c_.max_delay_s);
  if (!comparison_) return;  // said in counters()
  driftlab::command_comparison_t r{};
  r.header.utime = bus.now().us();
  r.recomputed_channel = c_.command_channel;
  r.logged_channel = c_.logged_channel;
  r.matched = comparison_->matched;
  r.linear_rmse = comparison_->linear_rmse;
  r.angular_rmse = comparison_->angular_rmse;
  r.linear_max_abs = comparison_->linear_max_abs;
  r.angular_max_abs = comparison_->angular_max_abs;
  r.delay_s = comparison_->delay_s;
  r.angular_rmse_at_delay = comparison_->angular_rmse_at_delay;
  bus.publish_message(c_.comparison_channel, r);
}

ModuleCounters ControllerModule::counters() const {
  ModuleCounters c;
  c.dropped = undecodable_ + non_finite_.dropped();
  if (comparison_) {
    c.metrics = {{"compared_commands", comparison_->matched},
                 {"linear_rmse_m_s", comparison_->linear_rmse},
                 {"angular_rmse_rad_s", comparison_->angular_rmse},
                 {"angular_max_abs_rad_s", comparison_->angular_max_abs},
                 {"delay_s", comparison_->delay_s},
                 {"angular_rmse_at_delay_rad_s", comparison_->angular_rmse_at_delay}};
  }
  if (recomputed_.empty()) {
    c.warnings.push_back("controller: no driftlab.odometry_t or pose_t on " + c_.estimate_channel +
                         ": no commands computed");
  } else if (!c_.logged_channel.empty() && logged_.empty()) {
    c.warnings.push_back("controller: no driftlab.velocity_command_t on " + c_.logged_channel +
                         ": nothing to compare the commands with");
  } else if (!c_.logged_channel.empty() && finished_ && !comparison_) {
    c.warnings.push_back("controller: no recomputed command falls within " + config::format_number(c_.max_delay_s) +
                         " s of a logged one on " + c_.logged_channel + ": the commands were not compared");
  }
  if (undecodable_ > 0) {
    c.warnings.push_back("controller: " + std::to_string(undecodable_) + " messages of the wrong type ignored");
  }
  if (auto w = non_finite_.warning("controller")) c.warnings.push_back(*w);
  return c;
}

Result<std::unique_ptr<Module>> make_controller(const YAML::Node& config, const std::string& origin,
                                                ControllerConfig base) {
  auto c = parse_controller_config(config, origin, std::move(base));
  if (!c) return c.error();
  return std::unique_ptr<Module>(new ControllerModule(std::move(*c)));
}

}  // namespace driftlab::controller
