// The drone in the simulator's loop (a scenario's `drone:`): the flight stack runs on board as modules on a module
// host (runtime/module_host.h) whose clock is the simulation's; every message they read arrives through the
// output's fault path as the log sees it, and every message they publish goes out the same way. The motor commands
// that arrive set the rotors' speed setpoints; the motor model spins the rotors, and their thrust and drag torque,
// the airframe's linear drag and gravity move the Bullet body. A TF broadcaster puts the estimate on TF as
// odom -> base link, a robot state publisher the spinning rotors as base link -> rotor links. Internal to sim/.
// Thread-safety: belongs to the simulation's thread.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/clock_correction.h"
#include "core/result.h"
#include "driftlab/tf_t.hpp"
#include "flight/vehicle.h"
#include "runtime/module_host.h"
#include "sim/internal/output.h"
#include "sim/robot.h"
#include "sim/scenario.h"

namespace driftlab::sim {

class DroneLoop {
 public:
  /// Checks the drone against its URDF (a multirotor; the flight stack's vehicle, when given, has as many rotors)
  /// and makes the on-board modules. Errors name the scenario file or the URDF's element.
  static Result<std::unique_ptr<DroneLoop>> create(const Scenario& scenario, Robot& robot);
  ~DroneLoop();

  /// The channels the drone publishes (faults may name them).
  std::vector<std::string> channels() const;
  /// The vehicle model the flight stack flies with.
  const flight::VehicleModel& vehicle() const { return vehicle_; }

  /// Registers the streams on `out`, listens to the arrivals of every channel a module reads and of the motor
  /// commands, and starts the modules; `clocks` corrects the stamps of what the modules receive (closed-loop
  /// replay). Errors are the modules' start() errors.
  Status attach(
      Output& out, const ClockCorrections& clocks = {},
      std::function<int64_t(int64_t)> wall_clock = [](int64_t t) { return t; });
  /// After the output is flushed up to now [us]: the modules' timers due at now, then the rotors and the forces on
  /// the airframe for the next physics step of dt [s]; the rotor states and transforms that fall due.
  void control(int64_t now, double dt);
  /// world -> odom (where the vehicle stood: its estimator's local frame) for the static TF message.
  void add_static(driftlab::tf_t& tf, int64_t now) const;
  /// At the end of the run (now [us]): the modules' finish() and last statistics; after it nothing more is
  /// delivered to them.
  Status finish(int64_t now);

  /// One line each, for the simulator's summary: how the flight went and what the estimator rejected.
  std::vector<std::string> summary() const;

 private:
  DroneLoop(const Scenario& sc, Robot& robot, flight::VehicleModel vehicle);
  void deliver(const std::string& channel, int64_t utime, std::span<const uint8_t> bytes);
  void on_motor_command(std::span<const uint8_t> bytes);
  void on_estimate(int64_t arrival, std::span<const uint8_t> bytes);
  int stream(std::string_view channel);

  DroneConfig c_;
  int64_t start_utime_;
  Eigen::Vector3d start_;
  Robot& robot_;
  const MultirotorSpec& spec_;
  flight::VehicleModel vehicle_;
  runtime::ModuleHost host_;       // the flight stack's, on the simulation's clock
  runtime::ModuleHost wall_host_;  // the offboard script's when it is on the wall clock (offboard_clock: wall)
  bool offboard_on_wall_ = false;
  std::function<int64_t(int64_t)> wall_clock_;  // the wall time [us] of a simulated time
  int64_t sim_now_ = 0;                         // the simulated time being handled [us]
  std::vector<Module*> modules_;                // owned by the host
  Output* out_ = nullptr;
  std::map<std::string, int, std::less<>> streams_;
  ClockCorrections clocks_;
  bool running_ = false;
  Status failure_;  // the first error of the host (a module's), reported at finish()

  std::vector<double> control_;  // the last motor command [0..1]
  bool armed_ = false;
  std::vector<double> speed_, angle_;  // per rotor [rad/s], [rad] about the rotor joint's axis
  std::vector<int> rotor_joint_;       // with rotor bodies: the hinge's index in robot.joints()
  int rotor_stream_ = -1, rotor_tf_stream_ = -1, tf_stream_ = -1;
  int64_t n_rotor_ = 0, n_rotor_tf_ = 0, next_tf_ = 0;
  int64_t motor_commands_ = 0, bad_motor_commands_ = 0;
  double top_ = 0;  // highest the vehicle flew above its start [m]
  int64_t airborne_us_ = 0;
};

}  // namespace driftlab::sim
