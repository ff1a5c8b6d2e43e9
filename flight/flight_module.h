// The flight stack behind the Bus: the commander (commander.h), PX4's control cascade (control.h) and the mixer
// (vehicle.h). It flies on the estimate it is given (driftlab.odometry_t, the drone estimator's output): the
// attitude and rate controllers run on every estimate (the estimator publishes one per IMU sample: the rate loop
// runs at the IMU rate, as PX4's does on every gyro sample) and publish motor commands; the position controller
// and the commander tick at `position_rate` on the bus's clock. Setpoints (driftlab.trajectory_setpoint_t) and
// commands (driftlab.vehicle_command_t) come from an offboard script; the state goes out as
// driftlab.vehicle_status_t at `status_rate` and whenever it changes.
// The simulator runs this module on board, closed loop on its physics; replay runs it on a log and compares its
// motor commands with the logged ones.
// Thread-safety: a module is called from its bus's thread only.
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/result.h"
#include "flight/commander.h"
#include "flight/control.h"
#include "flight/vehicle.h"
#include "runtime/bus.h"
#include "runtime/module_input.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::flight {

/// What tunes the flight stack, apart from where its messages go (the scenario's `flight:` and the module's keys).
struct FlightOptions {
  VehicleModel vehicle;
  ControlOptions control;
  CommanderOptions commander;
  double position_rate = 50;  ///< position controller and commander ticks [Hz]
  double status_rate = 5;     ///< vehicle status messages [Hz]
};
const config::Table<FlightOptions>& flight_options_table();

struct FlightConfig {
  std::string estimate_channel = "VEHICLE_ODOM_REPLAY";  ///< driftlab.odometry_t in
  std::string setpoint_channel = "SETPOINT";             ///< driftlab.trajectory_setpoint_t in
  std::string command_channel = "VEHICLE_CMD";           ///< driftlab.vehicle_command_t in
  std::string motor_channel = "MOTOR_CMD_REPLAY";        ///< driftlab.motor_command_t out
  std::string status_channel = "VEHICLE_STATUS_REPLAY";  ///< driftlab.vehicle_status_t out
  std::string logged_motor_channel = "MOTOR_CMD";        ///< the logged commands to compare with; "" for none
  FlightOptions options;
};
/// The keys of the `flight:` map of a replay config.
const config::Table<FlightConfig>& flight_config_table();
Result<std::unique_ptr<Module>> make_flight(const YAML::Node& config, const std::string& origin);

class FlightModule final : public Module {
 public:
  explicit FlightModule(FlightConfig config);
  std::string name() const override { return "flight"; }
  Status start(Bus& bus) override;
  void finish(Bus& bus) override;
  ModuleCounters counters() const override;
  const Commander& commander() const { return commander_; }

 private:
  struct Estimate {
    int64_t stamp = 0, arrival = 0;
    Eigen::Vector3d position = Eigen::Vector3d::Zero(), velocity = Eigen::Vector3d::Zero();  // local frame
    Eigen::Quaterniond attitude = Eigen::Quaterniond::Identity();
    Eigen::Vector3d rate = Eigen::Vector3d::Zero();  // body
  };
  struct Setpoint {
    Eigen::Vector3d position = Eigen::Vector3d::Zero(), velocity = Eigen::Vector3d::Zero(),
                    acceleration = Eigen::Vector3d::Zero();
    double yaw = 0;
  };
  struct Sample {
    int64_t utime;
    std::vector<double> control;
  };
  void on_estimate(Bus& bus);
  void position_tick(Bus& bus);
  void publish_motors(Bus& bus, bool armed, const std::vector<double>& control);
  void publish_status(Bus& bus);
  bool estimate_fresh(int64_t now) const;

  FlightConfig c_;
  Mixer mixer_;
  PositionControl position_;
  AttitudeControl attitude_;
  RateControl rate_;
  Commander commander_;
  std::optional<Estimate> estimate_;
  std::optional<Setpoint> setpoint_;
  std::optional<ThrustSetpoint> thrust_;  ///< none: motors idle
  Eigen::Vector3d hold_ = Eigen::Vector3d::Zero();
  double hold_yaw_ = 0;
  int64_t seen_events_ = -1;
  std::optional<int64_t> last_rate_stamp_, last_position_tick_;
  double thrust_ratio_ = 0;
  int saturated_[3] = {0, 0, 0};
  int64_t motor_seq_ = 0, status_seq_ = 0, undecodable_ = 0, motor_commands_ = 0;
  NonFiniteInputs non_finite_;
  std::vector<Sample> recomputed_, logged_;
  double motor_rmse_ = 0;
  int64_t compared_ = 0;
};

}  // namespace driftlab::flight
