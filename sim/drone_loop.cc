#include "sim/internal/drone_loop.h"

#include <algorithm>
#include <cmath>
#include <regex>

#include "core/time.h"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/motor_command_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "estimator/drone_estimator_module.h"
#include "flight/flight_module.h"
#include "flight/offboard_module.h"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"
#include "sim/internal/sensors.h"

namespace driftlab::sim {
namespace {

driftlab::transform_t transform(const std::string& parent, const std::string& child, const Eigen::Vector3d& t,
                                const Eigen::Quaterniond& q, int64_t utime) {
  driftlab::transform_t out{};
  out.header.utime = utime;
  out.header.frame_id = parent;
  out.child_frame_id = child;
  out.translation = {t.x(), t.y(), t.z()};
  out.rotation = {q.w(), q.x(), q.y(), q.z()};
  return out;
}

/// The flight stack's model of the vehicle from what the URDF and the motor model say: PX4's airframe parameters
/// as a careful integrator would set them.
flight::VehicleModel vehicle_of(const MultirotorSpec& spec, const MotorModel& motors) {
  flight::VehicleModel v;
  v.mass = spec.mass;
  v.inertia = spec.inertia.diagonal();
  v.rotors.clear();
  for (const RotorSpec& r : spec.rotors) {
    v.rotors.push_back({r.position.x() - spec.com.x(), r.position.y() - spec.com.y(), r.direction});
  }
  v.max_rotor_thrust = motors.thrust_coefficient * motors.max_speed * motors.max_speed;
  v.moment_ratio = motors.moment_ratio;
  return v;
}

runtime::HostOptions host_options(const DroneConfig& c) {
  runtime::HostOptions o;
  o.clock = runtime::HostClock::kVirtual;
  o.loopback = false;  // what a module publishes goes out through the fault path and comes back as it arrives
  o.stats_period_s = 1;
  o.stats_channel = c.stats_channel;
  return o;
}

}  // namespace

DroneLoop::DroneLoop(const Scenario& sc, Robot& robot, flight::VehicleModel vehicle)
    : c_(sc.drone),
      start_utime_(sc.start_utime),
      start_(robot.link_pose(robot.base_link()).translation()),
      robot_(robot),
      spec_(*robot.multirotor()),
      vehicle_(std::move(vehicle)),
      host_(host_options(sc.drone)),
      wall_host_(host_options(sc.drone)),
      offboard_on_wall_(sc.drone.offboard_clock == "wall") {
  const std::size_t n = spec_.rotors.size();
  speed_.assign(n, 0.0);
  angle_.assign(n, 0.0);
  if (c_.rotor_bodies) {
    for (const RotorSpec& r : spec_.rotors) rotor_joint_.push_back(robot.joint_index(r.joint));
  }
}

DroneLoop::~DroneLoop() = default;

Result<std::unique_ptr<DroneLoop>> DroneLoop::create(const Scenario& sc, Robot& robot) {
  const MultirotorSpec* spec = robot.multirotor();
  if (spec == nullptr) return Error{sc.path + ": drone: robot '" + robot.name() + "' is not a multirotor"};
  DroneConfig c = sc.drone;
  flight::VehicleModel vehicle = c.vehicle_given ? c.flight.options.vehicle : vehicle_of(*spec, c.motors);
  if (vehicle.rotors.size() != spec->rotors.size()) {
    return Error{sc.path + ": drone.flight.vehicle has " + std::to_string(vehicle.rotors.size()) +
                 " rotors, the URDF (" + sc.urdf_path + ") " + std::to_string(spec->rotors.size())};
  }
  Scenario with = sc;
  with.drone.flight.options.vehicle = vehicle;
  if (!c.declination_given) with.drone.estimator.declination = sc.geo.declination;
  auto loop = std::unique_ptr<DroneLoop>(new DroneLoop(with, robot, vehicle));
  auto estimator = std::make_unique<estimator::DroneEstimatorModule>(with.drone.estimator);
  auto flight = std::make_unique<flight::FlightModule>(with.drone.flight);
  auto offboard = std::make_unique<flight::OffboardModule>(with.drone.offboard);
  loop->modules_ = {estimator.get(), flight.get(), offboard.get()};
  loop->host_.add_module(std::move(estimator));
  loop->host_.add_module(std::move(flight));
  (loop->offboard_on_wall_ ? loop->wall_host_ : loop->host_).add_module(std::move(offboard));
  return loop;
}

std::vector<std::string> DroneLoop::channels() const {
  return {c_.estimator.output_channel,
          c_.estimator.status_channel,
          c_.flight.motor_channel,
          c_.flight.status_channel,
          c_.offboard.setpoint_channel,
          c_.offboard.command_channel,
          c_.stats_channel,
          c_.rotor_channel,
          c_.tf_channel,
          c_.rotor_tf_channel};
}

int DroneLoop::stream(std::string_view channel) {
  auto it = streams_.find(channel);
  if (it == streams_.end()) it = streams_.emplace(std::string(channel), out_->add_stream(std::string(channel))).first;
  return it->second;
}

Status DroneLoop::attach(Output& out, const ClockCorrections& clocks, std::function<int64_t(int64_t)> wall_clock) {
  out_ = &out;
  clocks_ = clocks;
  wall_clock_ = std::move(wall_clock);
  for (const std::string& channel : channels()) {
    if (!out.has_stream(channel)) stream(channel);
  }
  rotor_stream_ = stream(c_.rotor_channel);
  rotor_tf_stream_ = stream(c_.rotor_tf_channel);
  tf_stream_ = stream(c_.tf_channel);
  host_.set_outlet([this](const BusMessage& m) {
    const int64_t t = m.time.us();
    out_->publish_encoded(stream(m.channel), m.data, t, t);
  });
  // What a wall-clock script publishes carries its wall stamps, and leaves at the simulated time being handled.
  wall_host_.set_outlet(
      [this](const BusMessage& m) { out_->publish_encoded(stream(m.channel), m.data, sim_now_, sim_now_); });
  if (Status s = host_.start(); !s) return s;
  if (Status s = wall_host_.start(); !s) return s;
  running_ = true;
  // Every channel a module reads, the motor commands and the estimate (for TF) are taken as they arrive.
  std::vector<std::regex> subscribed;
  for (const std::string& pattern : host_.subscriptions()) subscribed.emplace_back(pattern);
  for (const std::string& pattern : wall_host_.subscriptions()) subscribed.emplace_back(pattern);
  for (const std::string& channel : out.channels()) {
    const bool read = std::any_of(subscribed.begin(), subscribed.end(),
                                  [&](const std::regex& r) { return std::regex_match(channel, r); });
    const bool motors = channel == c_.flight.motor_channel, estimate = channel == c_.estimator.output_channel;
    if (!read && !motors && !estimate) continue;
    out.on_arrival(channel, [this, channel, read, motors, estimate](int64_t utime, std::span<const uint8_t> bytes) {
      if (motors) on_motor_command(bytes);
      if (estimate) on_estimate(utime, bytes);
      if (read) deliver(channel, utime, bytes);
    });
  }
  return {};
}

void DroneLoop::deliver(const std::string& channel, int64_t utime, std::span<const uint8_t> bytes) {
  if (!running_) return;
  sim_now_ = utime;
  std::vector<uint8_t> corrected;
  if (auto c = clocks_.find(channel); c != clocks_.end()) {
    corrected.assign(bytes.begin(), bytes.end());
    lcmtypes::map_stamps(corrected, utime,
                         [&](int64_t stamp) { return corrected_stamp(c->second, stamp, start_utime_); });
    bytes = corrected;
  }
  Status s = host_.advance(Time::from_us(utime));
  if (s) s = host_.deliver(channel, bytes);
  if (offboard_on_wall_) {
    if (s) s = wall_host_.advance(Time::from_us(wall_clock_(utime)));
    if (s) s = wall_host_.deliver(channel, bytes);
  }
  if (!s && failure_) failure_ = s;
}

void DroneLoop::on_motor_command(std::span<const uint8_t> bytes) {
  driftlab::motor_command_t m;
  if (!lcmtypes::decode(bytes, m) || m.control.size() != speed_.size()) return void(++bad_motor_commands_);
  ++motor_commands_;
  armed_ = m.armed;
  control_ = m.control;
}

void DroneLoop::on_estimate(int64_t arrival, std::span<const uint8_t> bytes) {
  if (arrival < next_tf_) return;
  driftlab::odometry_t o;
  if (!lcmtypes::decode(bytes, o)) return;
  next_tf_ = arrival + Duration::periods_rounded(c_.tf_rate).us();
  driftlab::tf_t tf{};
  tf.header.frame_id = o.header.frame_id;
  const Eigen::Quaterniond q(o.orientation.w, o.orientation.x, o.orientation.y, o.orientation.z);
  tf.transforms.push_back(transform(o.header.frame_id, o.child_frame_id,
                                    Eigen::Vector3d(o.position.x, o.position.y, o.position.z), q, o.header.utime));
  tf.ntransforms = 1;
  out_->publish(tf_stream_, tf, o.header.utime, arrival);
}

void DroneLoop::control(int64_t now, double dt) {
  if (running_) {
    sim_now_ = now;
    Status s = host_.advance(Time::from_us(now));
    if (s && offboard_on_wall_) s = wall_host_.advance(Time::from_us(wall_clock_(now)));
    if (!s && failure_) failure_ = s;
  }
  const MotorModel& m = c_.motors;
  const std::string& base = robot_.base_link();
  const Eigen::Isometry3d pose = robot_.link_pose(base);
  double drag_torque = 0;  // about the body's z [N*m]
  for (std::size_t i = 0; i < speed_.size(); ++i) {
    const RotorSpec& r = spec_.rotors[i];
    const double c =
        armed_ && i < control_.size() && std::isfinite(control_[i]) ? std::clamp(control_[i], 0.0, 1.0) : 0;
    const double target = m.max_speed * std::sqrt(c);
    const double tau = target > speed_[i] ? m.time_constant_up : m.time_constant_down;
    speed_[i] += (target - speed_[i]) * (1 - std::exp(-dt / tau));
    const double thrust = m.thrust_coefficient * speed_[i] * speed_[i];
    // A rotor spinning counter-clockwise seen from above (+z) turns the body clockwise with its drag.
    drag_torque -= r.direction * m.moment_ratio * thrust;
    const Eigen::Vector3d force = pose.rotation() * Eigen::Vector3d(0, 0, thrust);
    if (c_.rotor_bodies) {
      robot_.apply_force(r.link, force, robot_.link_pose(r.link).translation());
      robot_.set_joint_rate(rotor_joint_[i], speed_[i], 10.0, dt);
    } else {
      robot_.apply_force(base, force, pose * r.position);
      angle_[i] += speed_[i] * dt;
    }
  }
  robot_.apply_torque(base, pose.rotation() * Eigen::Vector3d(0, 0, drag_torque));
  robot_.apply_force(base, -c_.drag * robot_.link_linear_velocity(base), pose * spec_.com);

  const double height = pose.translation().z() - start_.z();
  top_ = std::max(top_, height);
  if (height > 0.05) airborne_us_ += Duration::from_seconds_rounded(dt).us();

  const int64_t t = now - start_utime_;
  if (c_.rotor_bodies) {
    const std::vector<JointReading> joints = robot_.joints();
    for (std::size_t i = 0; i < angle_.size(); ++i)
      angle_[i] = joints[static_cast<std::size_t>(rotor_joint_[i])].position;
  }
  if (t >= due_us(n_rotor_, c_.rotor_rate)) {
    ++n_rotor_;
    driftlab::joint_state_t js{};
    js.header.frame_id = base;
    for (std::size_t i = 0; i < speed_.size(); ++i) {
      js.name.push_back(spec_.rotors[i].joint);
      js.position.push_back(angle_[i]);
      js.velocity.push_back(speed_[i]);
      js.effort.push_back(m.moment_ratio * m.thrust_coefficient * speed_[i] * speed_[i]);
    }
    js.njoints = static_cast<int32_t>(js.name.size());
    out_->publish(rotor_stream_, js, now, now);
  }
  if (t >= due_us(n_rotor_tf_, c_.tf_rate)) {
    ++n_rotor_tf_;
    driftlab::tf_t tf{};
    tf.header.frame_id = base;
    for (std::size_t i = 0; i < speed_.size(); ++i) {
      const RotorSpec& r = spec_.rotors[i];
      const Eigen::Quaterniond q(Eigen::AngleAxisd(angle_[i], Eigen::Vector3d(0, 0, r.direction)));
      tf.transforms.push_back(transform(base, r.link, r.position, q, now));
    }
    tf.ntransforms = static_cast<int32_t>(tf.transforms.size());
    out_->publish(rotor_tf_stream_, tf, now, now);
  }
}

void DroneLoop::add_static(driftlab::tf_t& tf, int64_t now) const {
  tf.transforms.push_back(transform("world", "odom", start_, Eigen::Quaterniond::Identity(), now));
  tf.ntransforms = static_cast<int32_t>(tf.transforms.size());
}

Status DroneLoop::finish(int64_t now) {
  if (!running_) return failure_;
  sim_now_ = now;
  Status s = host_.advance(Time::from_us(now));
  if (s) s = host_.finish();
  if (s && offboard_on_wall_) s = wall_host_.advance(Time::from_us(wall_clock_(now)));
  if (s && offboard_on_wall_) s = wall_host_.finish();
  running_ = false;
  if (!s) return s;
  return failure_;
}

std::vector<std::string> DroneLoop::summary() const {
  const auto* estimator = static_cast<const estimator::DroneEstimatorModule*>(modules_[0]);
  const auto* flight = static_cast<const flight::FlightModule*>(modules_[1]);
  const auto* offboard = static_cast<const flight::OffboardModule*>(modules_[2]);
  std::vector<std::string> out;
  char line[256];
  std::snprintf(line, sizeof line, "drone: flew %.1f s, up to %.2f m above its start; mission %s; %s, %s",
                Duration::from_us(airborne_us_).seconds(), top_,
                offboard->phase() == flight::OffboardModule::Phase::kDone ? "done" : "not done",
                flight->commander().armed() ? "armed" : "disarmed", flight->commander().reason().c_str());
  out.emplace_back(line);
  static constexpr const char* kNames[] = {"IMU", "GNSS", "baro", "mag"};
  for (int i = 0; i < 4; ++i) {
    const estimator::InputCounts& n = estimator->input(static_cast<estimator::DroneEstimatorModule::Input>(i));
    const int64_t rejected = n.stale + n.future + n.late;
    if (n.received == 0) continue;
    std::snprintf(line, sizeof line,
                  "estimator: %s: %lld of %lld rejected (%.1f%%: %lld stale, %lld from the future, %lld late)",
                  kNames[i], static_cast<long long>(rejected), static_cast<long long>(n.received),
                  100.0 * static_cast<double>(rejected) / static_cast<double>(n.received),
                  static_cast<long long>(n.stale), static_cast<long long>(n.future), static_cast<long long>(n.late));
    out.emplace_back(line);
  }
  if (bad_motor_commands_ > 0) {
    out.push_back("drone: " + std::to_string(bad_motor_commands_) + " motor commands not for this vehicle's " +
                  std::to_string(speed_.size()) + " rotors, ignored");
  }
  return out;
}

}  // namespace driftlab::sim
