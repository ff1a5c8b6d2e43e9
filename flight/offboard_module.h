// The offboard script: what the field report's MAVROS script did, as a module behind the Bus. It streams position
// setpoints at `stream_rate` from the moment it knows where the vehicle is, asks for offboard mode and arming once
// the stream has run for `warmup_s` (and asks again every `retry_s` while the vehicle is not in offboard, as the
// MAVROS offboard example does), then flies its mission: a climb to `takeoff_altitude` at `climb_speed`, a hover,
// the waypoints in order at `cruise_speed` (the setpoint moves along each leg with a feed-forward velocity, speeding
// up and slowing down at `acceleration` as a trajectory generator does, and dwells at its end) and a landing command;
// it stops when the vehicle has disarmed. Until the mission starts it streams where the vehicle is; waypoints are
// relative to where the vehicle stood when the mission started (x, y [m] in the estimate's frame, z [m] above it). Its
// clock is the bus's: the progress along the mission is time-driven, as a simple script's is, whether or not the
// vehicle follows. Thread-safety: a module is called from its bus's thread only.
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/result.h"
#include "runtime/bus.h"
#include "runtime/module_input.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::flight {

struct MissionOptions {
  double stream_rate = 20;      ///< setpoints per second [Hz]
  double warmup_s = 2;          ///< setpoints streamed before asking for offboard and arming [s]
  double retry_s = 1;           ///< how often a refused or lost offboard mode (or arming) is asked for again [s]
  double takeoff_altitude = 2;  ///< [m] above the start
  double climb_speed = 1;       ///< [m/s]
  double hover_s = 5;           ///< hover at the top of the climb [s]
  std::vector<Eigen::Vector3d> waypoints = {{4, 0, 2}, {4, 4, 2}, {0, 4, 2}, {0, 0, 2}};  ///< relative to the start [m]
  double cruise_speed = 1;                                                                ///< [m/s]
  double acceleration = 1;  ///< along a leg, speeding up and slowing down [m/s^2]
  double dwell_s = 2;                                                                     ///< at each waypoint [s]
  bool land = true;  ///< land at the end (else hover at the last waypoint)
};

/// The keys of a mission (core/config.h).
const config::Table<MissionOptions>& mission_options_table();

struct OffboardConfig {
  std::string estimate_channel = "VEHICLE_ODOM";       ///< driftlab.odometry_t: where the vehicle is
  std::string status_channel = "VEHICLE_STATUS";       ///< driftlab.vehicle_status_t: armed, mode
  std::string setpoint_channel = "SETPOINT_REPLAY";    ///< driftlab.trajectory_setpoint_t out
  std::string command_channel = "VEHICLE_CMD_REPLAY";  ///< driftlab.vehicle_command_t out
  MissionOptions mission;
};

/// The keys of the `offboard:` map of a replay config.
const config::Table<OffboardConfig>& offboard_config_table();
Result<std::unique_ptr<Module>> make_offboard(const YAML::Node& config, const std::string& origin);

class OffboardModule final : public Module {
 public:
  explicit OffboardModule(OffboardConfig config);
  std::string name() const override { return "offboard"; }
  Status start(Bus& bus) override;
  ModuleCounters counters() const override;

  enum class Phase { kWaiting, kWarmup, kEngaging, kMission, kLanding, kDone };
  Phase phase() const { return phase_; }

 private:
  struct Leg {
    Eigen::Vector3d from, to;
    double speed, dwell_s;
  };
  void tick(Bus& bus);
  void send(Bus& bus, const std::string& command);
  OffboardConfig c_;
  std::vector<Leg> legs_;
  Phase phase_ = Phase::kWaiting;
  std::optional<Eigen::Vector3d> position_;
  double yaw_ = 0, home_yaw_ = 0;
  bool armed_ = false, was_armed_ = false;
  std::string mode_;
  Eigen::Vector3d home_ = Eigen::Vector3d::Zero();
  int64_t phase_since_ = 0, mission_start_ = 0;
  std::optional<int64_t> last_request_;  ///< none: ask at once
  int64_t setpoint_seq_ = 0, command_seq_ = 0, setpoints_ = 0, commands_ = 0, undecodable_ = 0;
  NonFiniteInputs non_finite_;
};

}  // namespace driftlab::flight
