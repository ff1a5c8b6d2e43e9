// The controller module: the simulator's path follower (PurePursuit, with the reactive obstacle layer fed from the
// lidar) run behind the Bus. On replay it recomputes the commands from the logged estimates, ticking at its rate on
// the bus's clock with whatever estimate has arrived by then, as the robot's controller did, and at the end reports
// how its commands differ from the logged ones and with what delay (driftlab.command_comparison_t).
// Thread-safety: a module is called from its bus's thread only.
#pragma once

#include <yaml-cpp/yaml.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "controller/pure_pursuit.h"
#include "core/result.h"
#include "runtime/bus.h"
#include "runtime/module_input.h"

namespace driftlab::controller {

struct ControllerConfig {
  std::string scenario;                      ///< a simulator scenario the defaults come from (modules/registry.h)
  std::vector<Point2> route;                 ///< in the world frame [m]; required
  Pose2 start;                               ///< the robot's start in the world: maps odometry into the world
  PurePursuitOptions pursuit;
  double rate = 20;                          ///< [Hz]
  std::string estimate_channel = "ODOM";     ///< driftlab.odometry_t or pose_t: the pose the controller follows
  bool estimate_in_world = false;            ///< the estimate is already in the world frame (no start offset)
  std::string scan_channel = "SCAN";         ///< driftlab.laser_scan_t for obstacle avoidance; "" for none
  double footprint_radius = 0.2;             ///< [m]
  std::string command_channel = "CMD_REPLAY";
  std::string logged_channel = "CMD";        ///< the logged commands to compare with; "" for none
  std::string comparison_channel = "CMD_COMPARISON";
  double max_delay_s = 0.5;                  ///< delay search range of the comparison [s]
};

/// The keys of the `controller:` map of a replay config, with units, ranges and defaults (core/config.h); the
/// follower's keys are pure_pursuit_table()'s.
const config::Table<ControllerConfig>& controller_config_table();

/// Reads the `controller:` map of a replay config. `base` supplies defaults (e.g. from a simulator scenario). Errors
/// name the file, line and key.
Result<ControllerConfig> parse_controller_config(const YAML::Node& node, const std::string& origin,
                                                 ControllerConfig base = {});

/// The comparison of two command series (sorted by time [us]).
struct CommandSample {
  int64_t utime = 0;
  double linear = 0, angular = 0;
};
struct CommandComparison {
  int32_t matched = 0;
  double linear_rmse = 0, angular_rmse = 0, linear_max_abs = 0, angular_max_abs = 0;
  double delay_s = 0, angular_rmse_at_delay = 0;
};
/// Compares recomputed commands with the logged ones, each logged command held until the next (a zero-order hold,
/// as the base does), over lags 0..±max_delay_s in 10 ms steps; nullopt when no lag compares any command.
std::optional<CommandComparison> compare_commands(const std::vector<CommandSample>& recomputed,
                                                  const std::vector<CommandSample>& logged, double max_delay_s);

class ControllerModule final : public Module {
 public:
  explicit ControllerModule(ControllerConfig config);
  std::string name() const override { return "controller"; }
  Status start(Bus& bus) override;
  void finish(Bus& bus) override;
  ModuleCounters counters() const override;
  const std::optional<CommandComparison>& comparison() const { return comparison_; }

 private:
  void tick(Bus& bus);
  ControllerConfig c_;
  PurePursuit pursuit_;
  std::optional<Pose2> estimate_;
  std::vector<Point2> obstacles_;
  int64_t seq_ = 0, undecodable_ = 0;
  NonFiniteInputs non_finite_;
  std::vector<CommandSample> recomputed_, logged_;
  std::optional<CommandComparison> comparison_;
  bool finished_ = false;
};

Result<std::unique_ptr<Module>> make_controller(const YAML::Node& config, const std::string& origin,
                                                ControllerConfig base = {});

}  // namespace driftlab::controller
