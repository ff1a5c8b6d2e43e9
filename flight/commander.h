// The flight stack's commander (PX4's commander, navigator and land detector, reduced to what offboard flight
// needs): arming, the mode the vehicle flies in and the failsafes.
//   - "offboard" is accepted only while setpoints stream: at least `offboard_min_rate` per second over the last
//     second, the last one no older than `offboard_timeout_s` (PX4 refuses the switch otherwise);
//   - in offboard, no setpoint for `offboard_timeout_s` (COM_OF_LOSS_T) is an offboard loss: the vehicle falls back
//     to `offboard_loss_action` (hold or land; COM_OBL_RC_ACT) and stays there until commanded again; a hold
//     failsafe turns into a landing after `failsafe_land_after_s`;
//   - arming needs a fresh estimate and the vehicle on the ground; disarming needs it on the ground;
//   - the land detector: landed after `land_detect_s` of thrust below 70% of hover with the vehicle still; airborne
//     once the controllers ask for more than hover thrust; landed after flying (or in land mode) for
//     `disarm_after_landing_s` disarms (COM_DISARM_LAND).
// Times are the flight stack's clock, any Time (differences are taken in doubles). Thread-safety: plain values;
// one thread.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <string>

#include "core/time.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::flight {

struct CommanderOptions {
  double offboard_timeout_s = 0.5;            ///< [s]
  double offboard_min_rate = 2;               ///< setpoints per second needed to enter offboard [Hz]
  std::string offboard_loss_action = "hold";  ///< hold or land
  double failsafe_land_after_s = 10;          ///< a hold failsafe lands after this long [s]; 0: never
  double land_speed = 0.7;                    ///< descent speed in land mode [m/s]
  double land_detect_s = 1.0;                 ///< [s]
  double disarm_after_landing_s = 2.0;        ///< [s]; 0: never
  double estimate_timeout_s = 0.5;            ///< an estimate older than this is none [s]
};

/// The keys of the commander options (core/config.h).
const config::Table<CommanderOptions>& commander_options_table();

enum class Mode { kHold, kOffboard, kLand };
const char* mode_name(Mode m);

class Commander {
 public:
  explicit Commander(const CommanderOptions& o) : o_(o) {}

  /// A setpoint arrived at now.
  void on_setpoint(Time now);
  /// A command ("arm", "disarm", "offboard", "land", "hold"); estimate_ok: a fresh estimate exists. False, with
  /// reason() saying why, when refused.
  bool command(const std::string& command, Time now, bool estimate_ok);
  /// The periodic check at now: offboard loss, failsafe landing, the land detector, auto-disarm.
  /// thrust_ratio: the collective thrust demanded over hover thrust; speed: the estimate's [m/s].
  void update(Time now, double thrust_ratio, double vertical_speed, double horizontal_speed);

  bool armed() const { return armed_; }
  bool landed() const { return landed_; }
  Mode mode() const { return mode_; }
  const std::string& reason() const { return reason_; }
  int offboard_losses() const { return losses_; }
  /// Time since the last setpoint [s]; -1 when none came.
  double setpoint_age(Time now) const;
  /// Counts mode and arming changes and refusals, so the caller knows when to say so (and to latch a hold point).
  int64_t events() const { return events_; }

 private:
  void set(Mode m, const std::string& why, Time now);
  CommanderOptions o_;
  bool armed_ = false, landed_ = true, flew_ = false;
  Mode mode_ = Mode::kHold;
  bool failsafe_ = false;
  Time mode_since_, landed_since_;
  std::optional<Time> low_since_;  ///< since when thrust has been low with the vehicle still
  std::deque<Time> setpoints_;     ///< arrivals within the last second
  std::optional<Time> last_setpoint_;
  std::string reason_;
  int losses_ = 0;
  int64_t events_ = 0;
};

}  // namespace driftlab::flight
