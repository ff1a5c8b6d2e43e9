#include "sim/drone_config.h"

#include "core/config.h"

namespace driftlab::sim {

DroneConfig::DroneConfig() {
  // On board, the modules talk on the vehicle's own channels (on replay they default to *_REPLAY ones).
  estimator.output_channel = "VEHICLE_ODOM";
  estimator.status_channel = "ESTIMATOR_STATUS";
  flight.estimate_channel = "VEHICLE_ODOM";
  flight.setpoint_channel = "SETPOINT";
  flight.command_channel = "VEHICLE_CMD";
  flight.motor_channel = "MOTOR_CMD";
  flight.status_channel = "VEHICLE_STATUS";
  flight.logged_motor_channel = "";
  offboard.estimate_channel = "VEHICLE_ODOM";
  offboard.status_channel = "VEHICLE_STATUS";
  offboard.setpoint_channel = "SETPOINT";
  offboard.command_channel = "VEHICLE_CMD";
}

namespace {

const config::Table<MotorModel>& motor_table() {
  using M = MotorModel;
  using config::above;
  static const auto t =
      config::Table<M>()
          .number("thrust_coefficient", &M::thrust_coefficient, above(0, 1), "N/(rad/s)^2", "k_f: thrust = k_f w^2")
          .number("moment_ratio", &M::moment_ratio, config::between(0, 1), "m",
                  "drag torque per thrust, against the spin")
          .number("max_speed", &M::max_speed, above(0, 1e5), "rad/s", "the speed at a motor command of 1")
          .number("time_constant_up", &M::time_constant_up, above(0, 10), "s", "first-order lag when speeding up")
          .number("time_constant_down", &M::time_constant_down, above(0, 10), "s", "... and when slowing down");
  return t;
}

}  // namespace

const config::Table<DroneConfig>& drone_table() {
  using D = DroneConfig;
  using config::Text;
  static const auto t =
      config::Table<D>()
          .section("motors", &D::motors, motor_table(), "each rotor's motor and propeller")
          .number("drag", &D::drag, config::between(0, 1e3), "N/(m/s)", "linear drag on the airframe")
          .flag("rotor_bodies", &D::rotor_bodies,
                "each rotor a Bullet body on a hinge, as Gazebo builds it (slower; the benchmark's peer)")
          .text("rotor_channel", &D::rotor_channel, "driftlab.joint_state_t of the rotors (angle, speed, drag torque)",
                Text::kNonEmpty)
          .number("rotor_rate", &D::rotor_rate, config::above(0, 1e4), "Hz", "rotor states per second")
          .text("tf_channel", &D::tf_channel, "driftlab.tf_t of odom -> base link, from the estimate", Text::kNonEmpty)
          .text("rotor_tf_channel", &D::rotor_tf_channel, "driftlab.tf_t of base link -> rotor links", Text::kNonEmpty)
          .number("tf_rate", &D::tf_rate, config::above(0, 1e4), "Hz", "transforms per second on both")
          .text("stats_channel", &D::stats_channel, "driftlab.module_stats_t of the on-board modules", Text::kNonEmpty)
          .choice("offboard_clock", &D::offboard_clock, {"simulation", "wall"},
                  "the offboard script's clock: the simulation's, or the wall clock (a ROS node that trusts it; see "
                  "physics_cost)")
          .section("estimator", &D::estimator, estimator::drone_estimator_config_table(),
                   "the on-board estimator (the drone_estimator module's keys); declination: the geo's unless given")
          .section("flight", &D::flight, flight::flight_config_table(),
                   "the flight stack (the flight module's keys); vehicle: from the URDF and the motors unless given")
          .section("offboard", &D::offboard, flight::offboard_config_table(),
                   "the offboard script (the offboard module's keys): the mission")
          .check([](const config::Value& v, D& d) -> Status {
            d.vehicle_given = v["flight"]["vehicle"].given();
            d.declination_given = v["estimator"]["declination"].given();
            return {};
          });
  return t;
}

}  // namespace driftlab::sim
