#include "flight/flight_module.h"

#include <algorithm>
#include <cmath>

#include "core/config.h"
#include "core/time.h"
#include "driftlab/motor_command_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/trajectory_setpoint_t.hpp"
#include "driftlab/vehicle_command_t.hpp"
#include "driftlab/vehicle_status_t.hpp"
#include "runtime/module_input.h"

namespace driftlab::flight {
namespace {

constexpr double kGravity = 9.81;  // [m/s^2]

/// A vector field's components' names, as NonFiniteInputs reports them.
struct Fields {
  const char* x;
  const char* y;
  const char* z;
};

/// Whether a vector's components are all plausible (lcmtypes/validate.h), counting the input when not. The names
/// are literals: estimates arrive at hundreds of Hz, and nothing is built per input.
bool plausible(NonFiniteInputs& n, std::string_view channel, const Fields& f, const driftlab::vector3_t& v) {
  return n.plausible(channel, f.x, v.x) && n.plausible(channel, f.y, v.y) && n.plausible(channel, f.z, v.z);
}

}  // namespace

const config::Table<FlightOptions>& flight_options_table() {
  using F = FlightOptions;
  static const auto t =
      config::Table<F>()
          .section("vehicle", &F::vehicle, vehicle_model_table(), "the vehicle the controllers fly (mass, rotors)")
          .section("control", &F::control, control_options_table(), "the cascade's gains and limits")
          .section("commander", &F::commander, commander_options_table(), "offboard rules and failsafes")
          .number("position_rate", &F::position_rate, config::between(1, 1000), "Hz",
                  "position controller and commander ticks, on the bus's clock")
          .number("status_rate", &F::status_rate, config::between(0.1, 1000), "Hz", "vehicle status messages");
  return t;
}

const config::Table<FlightConfig>& flight_config_table() {
  using C = FlightConfig;
  using config::Text;
  static const auto t =
      config::Table<C>()
          .text("estimate_channel", &C::estimate_channel, "driftlab.odometry_t to fly on (the drone estimator's)",
                Text::kNonEmpty)
          .text("setpoint_channel", &C::setpoint_channel, "driftlab.trajectory_setpoint_t in", Text::kNonEmpty)
          .text("command_channel", &C::command_channel, "driftlab.vehicle_command_t in", Text::kNonEmpty)
          .text("motor_channel", &C::motor_channel, "driftlab.motor_command_t out", Text::kNonEmpty)
          .text("status_channel", &C::status_channel, "driftlab.vehicle_status_t out", Text::kNonEmpty)
          .text("logged_motor_channel", &C::logged_motor_channel,
                "the logged driftlab.motor_command_t to compare with; \"\" for none")
          .include(&C::options, flight_options_table());
  return t;
}

Result<std::unique_ptr<Module>> make_flight(const YAML::Node& config, const std::string& origin) {
  auto c = flight_config_table().parse(config::Value(config, origin, "flight"));
  if (!c) return c.error();
  return std::unique_ptr<Module>(new FlightModule(std::move(*c)));
}

FlightModule::FlightModule(FlightConfig config)
    : c_(std::move(config)),
      mixer_(c_.options.vehicle),
      position_(c_.options.control, static_cast<double>(c_.options.vehicle.rotors.size()) *
                                        c_.options.vehicle.max_rotor_thrust / c_.options.vehicle.mass),
      attitude_(c_.options.control),
      rate_(c_.options.control),
      commander_(c_.options.commander) {}

Status FlightModule::start(Bus& bus) {
  bus.subscribe(c_.estimate_channel, [this, &bus](const BusMessage& m) {
    driftlab::odometry_t o;
    if (!decode_message(m, o)) return void(++undecodable_);
    // A NaN, a position past any plausible one or an orientation that is no rotation (its norm off 1 by more than
    // 1%, eval's rule for poses) would fly the vehicle into NaN: the estimate is dropped, and counted.
    if (!non_finite_.finite(m) ||
        !plausible(non_finite_, m.channel, {"position.x", "position.y", "position.z"}, o.position) ||
        !plausible(non_finite_, m.channel, {"linear_velocity.x", "linear_velocity.y", "linear_velocity.z"},
                   o.linear_velocity) ||
        !plausible(non_finite_, m.channel, {"angular_velocity.x", "angular_velocity.y", "angular_velocity.z"},
                   o.angular_velocity)) {
      return;
    }
    if (!unit_norm(o.orientation.w, o.orientation.x, o.orientation.y, o.orientation.z)) {
      return non_finite_.count(m.channel, "orientation is no rotation (its norm is not 1)");
    }
    Estimate e;
    e.stamp = o.header.utime;
    e.arrival = bus.now().us();
    e.position = Eigen::Vector3d(o.position.x, o.position.y, o.position.z);
    e.attitude = Eigen::Quaterniond(o.orientation.w, o.orientation.x, o.orientation.y, o.orientation.z).normalized();
    // odometry_t's velocities are in the body (child) frame; the controllers want the local frame's.
    e.velocity = e.attitude * Eigen::Vector3d(o.linear_velocity.x, o.linear_velocity.y, o.linear_velocity.z);
    e.rate = Eigen::Vector3d(o.angular_velocity.x, o.angular_velocity.y, o.angular_velocity.z);
    estimate_ = e;
    on_estimate(bus);
  });
  bus.subscribe(c_.setpoint_channel, [this, &bus](const BusMessage& m) {
    driftlab::trajectory_setpoint_t s;
    if (!decode_message(m, s)) return void(++undecodable_);
    if (!non_finite_.finite(m) ||
        !plausible(non_finite_, m.channel, {"position.x", "position.y", "position.z"}, s.position) ||
        !plausible(non_finite_, m.channel, {"velocity.x", "velocity.y", "velocity.z"}, s.velocity) ||
        !plausible(non_finite_, m.channel, {"acceleration.x", "acceleration.y", "acceleration.z"}, s.acceleration) ||
        !non_finite_.plausible(m.channel, "yaw", s.yaw)) {
      return;  // neither followed nor counted as a setpoint that keeps offboard alive
    }
    setpoint_ = Setpoint{Eigen::Vector3d(s.position.x, s.position.y, s.position.z),
                         Eigen::Vector3d(s.velocity.x, s.velocity.y, s.velocity.z),
                         Eigen::Vector3d(s.acceleration.x, s.acceleration.y, s.acceleration.z), s.yaw};
    commander_.on_setpoint(bus.now());
  });
  bus.subscribe(c_.command_channel, [this, &bus](const BusMessage& m) {
    driftlab::vehicle_command_t c;
    if (!decode_message(m, c)) return void(++undecodable_);
    commander_.command(c.command, bus.now(), estimate_fresh(bus.now().us()));
    position_tick(bus);  // act on it (and say so) now, not at the next tick
  });
  if (!c_.logged_motor_channel.empty()) {
    bus.subscribe(c_.logged_motor_channel, [this](const BusMessage& m) {
      driftlab::motor_command_t c;
      if (!decode_message(m, c)) return void(++undecodable_);
      if (!non_finite_.finite(m)) return;
      logged_.push_back({c.header.utime, c.armed ? c.control : std::vector<double>(c.control.size(), 0.0)});
    });
  }
  bus.every(Duration::periods_rounded(c_.options.position_rate), [this, &bus] { position_tick(bus); });
  bus.every(Duration::periods_rounded(c_.options.status_rate), [this, &bus] { publish_status(bus); });
  return {};
}

bool FlightModule::estimate_fresh(int64_t now) const {
  return estimate_ && seconds_between(estimate_->arrival, now) <= c_.options.commander.estimate_timeout_s;
}

void FlightModule::position_tick(Bus& bus) {
  const int64_t now = bus.now().us();
  const double dt = last_position_tick_ ? std::clamp(seconds_between(*last_position_tick_, now), 0.0, 0.1)
                                        : 1 / c_.options.position_rate;
  last_position_tick_ = now;
  const bool fresh = estimate_fresh(now);
  const Eigen::Vector3d v = fresh ? estimate_->velocity : Eigen::Vector3d::Zero();
  commander_.update(Time::from_us(now), thrust_ratio_, v.z(), v.head<2>().norm());
  const bool changed = commander_.events() != seen_events_;
  if (changed && fresh) {  // a new mode holds (or lands from) where the vehicle is now
    hold_ = estimate_->position;
    hold_yaw_ = std::atan2((estimate_->attitude * Eigen::Vector3d::UnitX()).y(),
                           (estimate_->attitude * Eigen::Vector3d::UnitX()).x());
  }
  if (!commander_.armed()) {
    thrust_.reset();
    position_.reset();
    rate_.reset();
    thrust_ratio_ = 0;
  } else if (!fresh) {
    // No estimate: PX4 descends blind, level, a little below hover thrust.
    thrust_ = ThrustSetpoint{Eigen::Vector3d(0, 0, 0.9 * kGravity), hold_yaw_};
  } else if (commander_.mode() == Mode::kOffboard && setpoint_) {
    thrust_ = position_.update(setpoint_->position, setpoint_->velocity, setpoint_->yaw, estimate_->position,
                               estimate_->velocity, dt, setpoint_->acceleration);
  } else if (commander_.mode() == Mode::kLand) {
    thrust_ = position_.update_velocity_z(hold_, -c_.options.commander.land_speed, hold_yaw_, estimate_->position,
                                          estimate_->velocity, dt);
  } else {
    thrust_ = position_.update(hold_, Eigen::Vector3d::Zero(), hold_yaw_, estimate_->position, estimate_->velocity, dt);
  }
  if (thrust_) thrust_ratio_ = thrust_->acceleration.z() / kGravity;
  if (changed) {
    seen_events_ = commander_.events();
    publish_status(bus);
  }
}

void FlightModule::on_estimate(Bus& bus) {
  const Estimate& e = *estimate_;
  const double dt = last_rate_stamp_ ? std::clamp(seconds_between(*last_rate_stamp_, e.stamp), 0.0, 0.05) : 0.0;
  last_rate_stamp_ = e.stamp;
  if (!commander_.armed() || !thrust_) {
    publish_motors(bus, false, std::vector<double>(c_.options.vehicle.rotors.size(), 0.0));
    return;
  }
  const Eigen::Quaterniond q_sp = attitude_for(thrust_->acceleration, thrust_->yaw);
  const Eigen::Vector3d rate_sp = attitude_.update(e.attitude, q_sp);
  const Eigen::Vector3d alpha = rate_.update(rate_sp, e.rate, dt, saturated_);
  // The collective thrust is the demanded specific force along the body z the vehicle has now (PX4's projection).
  const double collective =
      std::max(0.0, thrust_->acceleration.dot(e.attitude * Eigen::Vector3d::UnitZ())) * c_.options.vehicle.mass;
  const Mix mix = mixer_.mix(collective, c_.options.vehicle.inertia.cwiseProduct(alpha));
  std::copy(std::begin(mix.saturated), std::end(mix.saturated), saturated_);
  publish_motors(bus, true, mix.control);
}

void FlightModule::publish_motors(Bus& bus, bool armed, const std::vector<double>& control) {
  driftlab::motor_command_t m{};
  m.header.seq = motor_seq_++;
  m.header.utime = bus.now().us();
  m.header.frame_id = "base_link";
  m.armed = armed;
  m.nmotors = static_cast<int32_t>(control.size());
  m.control = control;
  bus.publish_message(c_.motor_channel, m);
  ++motor_commands_;
  if (!c_.logged_motor_channel.empty())
    recomputed_.push_back({m.header.utime, armed ? control : std::vector<double>(control.size(), 0.0)});
}

void FlightModule::publish_status(Bus& bus) {
  const int64_t now = bus.now().us();
  driftlab::vehicle_status_t s{};
  s.header.seq = status_seq_++;
  s.header.utime = now;
  s.header.frame_id = "";
  s.armed = commander_.armed();
  s.landed = commander_.landed();
  s.mode = mode_name(commander_.mode());
  s.reason = commander_.reason();
  s.offboard_losses = commander_.offboard_losses();
  s.setpoint_age_s = commander_.setpoint_age(Time::from_us(now));
  bus.publish_message(c_.status_channel, s);
}

void FlightModule::finish(Bus& bus) {
  // The recomputed commands against the logged ones in force at the same time (zero-order hold).
  double sum = 0;
  std::size_t j = 0;
  compared_ = 0;
  for (const Sample& r : recomputed_) {
    while (j + 1 < logged_.size() && logged_[j + 1].utime <= r.utime) ++j;
    if (logged_.empty() || logged_[j].utime > r.utime || logged_[j].control.size() != r.control.size()) continue;
    for (std::size_t k = 0; k < r.control.size(); ++k) sum += std::pow(r.control[k] - logged_[j].control[k], 2);
    compared_ += static_cast<int64_t>(r.control.size());
  }
  motor_rmse_ = compared_ > 0 ? std::sqrt(sum / static_cast<double>(compared_)) : 0;
}

ModuleCounters FlightModule::counters() const {
  ModuleCounters c;
  c.dropped = undecodable_ + non_finite_.dropped();
  c.metrics = {{"motor_commands", static_cast<double>(motor_commands_)},
               {"offboard_losses", static_cast<double>(commander_.offboard_losses())}};
  if (compared_ > 0) c.metrics.push_back({"motor_rmse", motor_rmse_});
  if (!estimate_) {
    c.warnings.push_back("flight: no driftlab.odometry_t on " + c_.estimate_channel + ": nothing flown");
  }
  if (commander_.offboard_losses() > 0) {
    c.warnings.push_back("flight: offboard lost " + std::to_string(commander_.offboard_losses()) +
                         " times (setpoints stopped for more than " +
                         config::format_number(c_.options.commander.offboard_timeout_s) + " s)");
  }
  if (undecodable_ > 0)
    c.warnings.push_back("flight: " + std::to_string(undecodable_) + " messages of the wrong type ignored");
  if (auto w = non_finite_.warning("flight")) c.warnings.push_back(*w);
  return c;
}

}  // namespace driftlab::flight
