#include "flight/offboard_module.h"

#include <cmath>

#include "core/config.h"
#include "core/time.h"
#include "driftlab/odometry_t.hpp"
#include "driftlab/trajectory_setpoint_t.hpp"
#include "driftlab/vehicle_command_t.hpp"
#include "driftlab/vehicle_status_t.hpp"
#include "lcmtypes/planar.h"
#include "runtime/module_input.h"

namespace driftlab::flight {
namespace {

Status read_waypoints(const config::Value& v, std::vector<Eigen::Vector3d>& out) {
  if (!v.node().IsSequence()) return v.error("must be a list of [x, y, z] (relative to the start)");
  std::vector<Eigen::Vector3d> w;
  for (std::size_t i = 0; i < v.node().size(); ++i) {
    auto p = v[i].numbers(3, config::between(-1e5, 1e5), "m");
    if (!p) return p.error();
    if ((*p)[2] < 0) return v[i].error("z is the altitude above the start and must be >= 0");
    w.emplace_back((*p)[0], (*p)[1], (*p)[2]);
  }
  out = std::move(w);
  return {};
}

std::string show_waypoints(const std::vector<Eigen::Vector3d>& w) { return std::to_string(w.size()) + " points"; }

}  // namespace

const config::Table<MissionOptions>& mission_options_table() {
  using M = MissionOptions;
  using config::above;
  using config::between;
  static const auto t =
      config::Table<M>()
          .number("stream_rate", &M::stream_rate, between(0.1, 1000), "Hz", "setpoints per second")
          .number("warmup_s", &M::warmup_s, between(0, 1e4), "s",
                  "setpoints streamed before asking for offboard and arming")
          .number("retry_s", &M::retry_s, above(0, 1e4), "s",
                  "how often offboard mode (or arming) is asked for again while it is not granted")
          .number("takeoff_altitude", &M::takeoff_altitude, above(0, 1e4), "m", "climb to this height above the start")
          .number("climb_speed", &M::climb_speed, above(0, 100), "m/s", "how fast the setpoint climbs")
          .number("hover_s", &M::hover_s, between(0, 1e5), "s", "hover at the top of the climb")
          .custom<std::vector<Eigen::Vector3d>>("waypoints", &M::waypoints, "list of [x, y, z]", "m", "",
                                                "flown in order; x, y in the estimate's frame and z above the start, "
                                                "all relative to where the vehicle stood",
                                                read_waypoints, show_waypoints)
          .number("cruise_speed", &M::cruise_speed, above(0, 100), "m/s", "how fast the setpoint moves along a leg")
          .number("acceleration", &M::acceleration, above(0, 100), "m/s^2",
                  "how fast the setpoint speeds up and slows down along a leg (and the climb)")
          .number("dwell_s", &M::dwell_s, between(0, 1e5), "s", "the setpoint rests this long at each waypoint")
          .flag("land", &M::land, "land at the end (else hover at the last waypoint)");
  return t;
}

const config::Table<OffboardConfig>& offboard_config_table() {
  using C = OffboardConfig;
  using config::Text;
  static const auto t =
      config::Table<C>()
          .text("estimate_channel", &C::estimate_channel, "driftlab.odometry_t: where the vehicle is", Text::kNonEmpty)
          .text("status_channel", &C::status_channel, "driftlab.vehicle_status_t: armed and mode", Text::kNonEmpty)
          .text("setpoint_channel", &C::setpoint_channel, "driftlab.trajectory_setpoint_t out", Text::kNonEmpty)
          .text("command_channel", &C::command_channel, "driftlab.vehicle_command_t out", Text::kNonEmpty)
          .include(&C::mission, mission_options_table());
  return t;
}

Result<std::unique_ptr<Module>> make_offboard(const YAML::Node& config, const std::string& origin) {
  auto c = offboard_config_table().parse(config::Value(config, origin, "offboard"));
  if (!c) return c.error();
  return std::unique_ptr<Module>(new OffboardModule(std::move(*c)));
}

OffboardModule::OffboardModule(OffboardConfig config) : c_(std::move(config)) {}

Status OffboardModule::start(Bus& bus) {
  bus.subscribe(c_.estimate_channel, [this](const BusMessage& m) {
    driftlab::odometry_t o;
    if (!decode_message(m, o)) return void(++undecodable_);
    // The mission is laid out from the estimate: a NaN, a position past any plausible one or an orientation that
    // is no rotation would put every setpoint there. Dropped, and counted.
    if (!non_finite_.finite(m) || !non_finite_.plausible(m.channel, "position.x", o.position.x) ||
        !non_finite_.plausible(m.channel, "position.y", o.position.y) ||
        !non_finite_.plausible(m.channel, "position.z", o.position.z)) {
      return;
    }
    if (!unit_norm(o.orientation.w, o.orientation.x, o.orientation.y, o.orientation.z)) {
      return non_finite_.count(m.channel, "orientation is no rotation (its norm is not 1)");
    }
    position_ = Eigen::Vector3d(o.position.x, o.position.y, o.position.z);
    yaw_ = yaw_of(o.orientation);
  });
  bus.subscribe(c_.status_channel, [this](const BusMessage& m) {
    driftlab::vehicle_status_t s;
    if (!decode_message(m, s)) return void(++undecodable_);
    armed_ = s.armed;
    if (armed_) was_armed_ = true;
    mode_ = s.mode;
  });
  bus.every(Duration::periods_rounded(c_.mission.stream_rate), [this, &bus] { tick(bus); });
  return {};
}

void OffboardModule::send(Bus& bus, const std::string& command) {
  driftlab::vehicle_command_t m{};
  m.header.seq = command_seq_++;
  m.header.utime = bus.now().us();
  m.header.frame_id = "";
  m.command = command;
  bus.publish_message(c_.command_channel, m);
  last_request_ = bus.now().us();
  ++commands_;
}

void OffboardModule::tick(Bus& bus) {
  const int64_t now = bus.now().us();
  const MissionOptions& o = c_.mission;
  // In doubles: the bus's clock follows a log's times, which may start anywhere in int64_t.
  auto since = [&](int64_t t) { return seconds_between(t, now); };
  auto may_ask = [&] { return !last_request_ || since(*last_request_) >= o.retry_s; };
  if (phase_ == Phase::kWaiting) {
    if (!position_) return;
    phase_ = Phase::kWarmup;
    phase_since_ = now;
  }
  // Until the mission starts, the setpoint is where the vehicle is (as the MAVROS example streams its pose): the
  // estimate settles while the GNSS fixes average out, and the mission is laid out from where it stands at take-off.
  if (phase_ == Phase::kWarmup || phase_ == Phase::kEngaging) {
    home_ = *position_;
    home_yaw_ = yaw_;
  }
  if (phase_ == Phase::kWarmup && since(phase_since_) >= o.warmup_s) {
    phase_ = Phase::kEngaging;
    phase_since_ = now;
    last_request_.reset();  // ask at once
  }
  if (phase_ == Phase::kEngaging) {
    if (mode_ == "offboard" && armed_) {
      phase_ = Phase::kMission;
      mission_start_ = now;
      Eigen::Vector3d at = home_ + Eigen::Vector3d(0, 0, o.takeoff_altitude);
      legs_ = {{home_, at, o.climb_speed, o.hover_s}};
      for (const Eigen::Vector3d& w : o.waypoints) {
        const Eigen::Vector3d to = home_ + w;
        legs_.push_back({at, to, o.cruise_speed, o.dwell_s});
        at = to;
      }
    } else if (may_ask()) {
      send(bus, mode_ != "offboard" ? "offboard" : "arm");
    }
  }
  // Where the setpoint is: at the start until the mission runs, then along the legs by the time since.
  Eigen::Vector3d position = home_, velocity = Eigen::Vector3d::Zero(), acceleration = Eigen::Vector3d::Zero();
  bool finished = false;
  if (phase_ == Phase::kMission) {
    if (!armed_) {  // disarmed in flight (landed by a failsafe, or crashed): the script gives up
      phase_ = Phase::kDone;
      return;
    }
    double t = since(mission_start_);
    finished = true;
    for (const Leg& leg : legs_) {
      const Eigen::Vector3d d = leg.to - leg.from;
      // A trapezoidal speed profile (a triangle on a short leg): up to speed at `acceleration`, on, and down.
      const double length = d.norm(), a = o.acceleration;
      const double top = std::min(leg.speed, std::sqrt(a * length));
      const double ramp = top / a, cruise = length > 0 ? (length - top * ramp) / top : 0;
      const double move = 2 * ramp + cruise;
      if (t < move && length > 0) {
        double s = 0, v = 0, acc = 0;  // along the leg [m], [m/s], [m/s^2]
        if (t < ramp) {
          s = 0.5 * a * t * t, v = a * t, acc = a;
        } else if (t < ramp + cruise) {
          s = 0.5 * top * ramp + top * (t - ramp), v = top;
        } else {
          const double left = move - t;
          s = length - 0.5 * a * left * left, v = a * left, acc = -a;
        }
        position = leg.from + d * (s / length);
        velocity = d / length * v;
        acceleration = d / length * acc;
        finished = false;
        break;
      }
      t -= move;
      position = leg.to;
      if (t < leg.dwell_s) {
        finished = false;
        break;
      }
      t -= leg.dwell_s;
    }
    if (mode_ != "offboard" && mode_ != "land" && may_ask()) send(bus, "offboard");
  }
  if (phase_ == Phase::kMission && finished && o.land) {
    phase_ = Phase::kLanding;
    last_request_.reset();
  }
  if (phase_ == Phase::kLanding) {
    if (!armed_ && was_armed_) {
      phase_ = Phase::kDone;
    } else if (mode_ != "land" && may_ask()) {
      send(bus, "land");
    }
    return;
  }
  if (phase_ == Phase::kDone) return;
  driftlab::trajectory_setpoint_t sp{};
  sp.header.seq = setpoint_seq_++;
  sp.header.utime = now;
  sp.header.frame_id = "odom";
  sp.position = {position.x(), position.y(), position.z()};
  sp.velocity = {velocity.x(), velocity.y(), velocity.z()};
  sp.acceleration = {acceleration.x(), acceleration.y(), acceleration.z()};
  sp.yaw = home_yaw_;
  bus.publish_message(c_.setpoint_channel, sp);
  ++setpoints_;
}

ModuleCounters OffboardModule::counters() const {
  ModuleCounters c;
  c.dropped = undecodable_ + non_finite_.dropped();
  c.metrics = {{"setpoints", static_cast<double>(setpoints_)}, {"commands", static_cast<double>(commands_)}};
  if (!position_) {
    c.warnings.push_back("offboard: no driftlab.odometry_t on " + c_.estimate_channel + ": the mission never started");
  }
  if (undecodable_ > 0) {
    c.warnings.push_back("offboard: " + std::to_string(undecodable_) + " messages of the wrong type ignored");
  }
  if (auto w = non_finite_.warning("offboard")) c.warnings.push_back(*w);
  return c;
}

}  // namespace driftlab::flight
