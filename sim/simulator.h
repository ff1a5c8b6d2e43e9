// Runs a scenario: steps the Bullet world at a fixed rate, drives the robot with the pure-pursuit controller from
// its own wheel odometry, samples every sensor at its rate with its noise model, applies the scenario's faults
// (faults/faults.h) and writes every stream to a log in arrival order, with ground truth and the fault manifest.
// Deterministic: the same scenario gives a byte-identical log. Never reads the wall clock.
// Thread-safety: simulate() uses only the calling thread; run one per thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/clock_correction.h"
#include "core/result.h"
#include "core/time.h"
#include "sim/scenario.h"

namespace driftlab::sim {

enum class RayBackend {
  kGrid,    ///< sim/raycaster.h: a 2D grid over the world, exact for its boxes and cylinders (default)
  kBullet,  ///< Bullet's generic closest-hit ray test (the baseline in benchmarks)
};

/// Corrections applied where the simulation's messages are received on board (by the drone's modules, by the
/// arm's controller), not to what the log records: what `driftlab replay --closed-loop` asks of a run again.
struct ReceiveCorrections {
  ClockCorrections clocks;  ///< per channel: its stamps corrected as `driftlab replay --restamp` corrects them
  /// Per command channel (the arm's): each command starts when it arrived less this (the measured delay), as
  /// if stamped then, and the controller honours the stamps.
  std::map<std::string, Duration> retime;
};

struct SimOptions {
  std::string out;  ///< log path; written as OUT.partial and renamed when complete
  ReceiveCorrections corrections;
  std::string version;  ///< of the program, for the log's SIMULATION message
  /// Also called for every message in arrival order (e.g. to publish it live): channel, arrival time
  /// [us, true clock], encoded bytes.
  std::function<void(const std::string&, int64_t, std::span<const uint8_t>)> on_message;
  /// Polled every step: when it becomes true the run stops and the log of what was simulated so far is closed.
  const std::atomic<bool>* stop = nullptr;
  /// Called about every simulated second: (simulated, total) [s].
  std::function<void(double, double)> progress;
};

/// The fault manifest written beside a simulation's log: OUT without its .lcm, then .faults.json.
std::string faults_json_path(const std::string& log);

struct SimReport {
  double simulated_s = 0;  ///< [s]
  bool interrupted = false;
  std::map<std::string, int64_t> messages;  ///< events written per channel
  std::string faults_json;                  ///< the manifest beside the log (OUT.faults.json)
  double distance_m = 0;                    ///< true path length driven [m]
  std::size_t laps = 0;                     ///< completed laps of the route (by the controller's estimate)
  double odometry_error_m = 0;              ///< final distance between the odometry's and the true position [m]
  std::vector<std::string> notes;           ///< what else the run says of itself (a drone's flight), a line each
};

/// The scenario a log was simulated from, as it was run (its SIMULATION message: the scenario's text, its
/// duration, seed and replacement faults), for running it again. The world and URDF are read again from beside the
/// scenario's path. Errors: a log without the message ("not made by driftlab sim"), or the scenario's own.
Result<Scenario> scenario_of_log(const std::string& log);

/// A scenario ready to run: the world and the robot are built and every reference checked.
class Simulation {
 public:
  /// Builds the scenario's world and robot. Errors (bad input) name the file and the place: the URDF's line,
  /// link or joint, a sensor on a link the robot does not have, faults on a channel the scenario does not publish.
  static Result<std::unique_ptr<Simulation>> create(const Scenario& scenario, RayBackend rays = RayBackend::kGrid);
  ~Simulation();

  /// The channels the on-board software publishes (the drone's estimator, flight stack and offboard script, and
  /// what the simulator derives from them): a run makes them again from its inputs, so corrections of their
  /// stamps do not apply.
  std::vector<std::string> recomputed_channels() const;

  /// Runs to the scenario's duration (or until *options.stop), writing options.out and the fault manifest JSON
  /// beside it. Errors are the log's (a full disk); then no partial log is left behind. Call once.
  Result<SimReport> run(const SimOptions& options);

 private:
  struct Impl;
  explicit Simulation(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace driftlab::sim
