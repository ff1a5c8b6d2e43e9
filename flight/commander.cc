#include "flight/commander.h"

#include <cmath>
#include <cstdio>

#include "core/config.h"
#include "core/time.h"

namespace driftlab::flight {
namespace {

std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f s", s);
  return buf;
}

/// Drops the arrivals more than a second before now.
void forget_older_than_a_second(std::deque<Time>& arrivals, Time now) {
  while (!arrivals.empty() && now.seconds_since(arrivals.front()) > 1.0) arrivals.pop_front();
}

}  // namespace

const config::Table<CommanderOptions>& commander_options_table() {
  using C = CommanderOptions;
  using config::above;
  using config::between;
  static const auto t =
      config::Table<C>()
          .number("offboard_timeout_s", &C::offboard_timeout_s, above(0, 60), "s",
                  "no setpoint for this long in offboard is an offboard loss (COM_OF_LOSS_T)")
          .number("offboard_min_rate", &C::offboard_min_rate, above(0, 1000), "Hz",
                  "setpoints per second, over the last second, needed to enter offboard")
          .choice("offboard_loss_action", &C::offboard_loss_action, {"hold", "land"},
                  "what an offboard loss falls back to (COM_OBL_RC_ACT)")
          .number("failsafe_land_after_s", &C::failsafe_land_after_s, between(0, 1e5), "s",
                  "a hold failsafe turns into a landing after this long; 0: never")
          .number("land_speed", &C::land_speed, above(0, 10), "m/s", "descent speed in land mode (MPC_LAND_SPEED)")
          .number("land_detect_s", &C::land_detect_s, above(0, 60), "s",
                  "low thrust and no motion for this long is landed")
          .number("disarm_after_landing_s", &C::disarm_after_landing_s, between(0, 1e5), "s",
                  "landed for this long disarms (COM_DISARM_LAND); 0: never")
          .number("estimate_timeout_s", &C::estimate_timeout_s, above(0, 60), "s",
                  "arming and flying need an estimate this fresh");
  return t;
}

const char* mode_name(Mode m) {
  switch (m) {
    case Mode::kHold: return "hold";
    case Mode::kOffboard: return "offboard";
    case Mode::kLand: return "land";
  }
  return "?";
}

void Commander::set(Mode m, const std::string& why, Time now) {
  mode_ = m;
  mode_since_ = now;
  reason_ = why;
  ++events_;
}

void Commander::on_setpoint(Time now) {
  last_setpoint_ = now;
  setpoints_.push_back(now);
  forget_older_than_a_second(setpoints_, now);
}

double Commander::setpoint_age(Time now) const { return last_setpoint_ ? now.seconds_since(*last_setpoint_) : -1.0; }

bool Commander::command(const std::string& c, Time now, bool estimate_ok) {
  auto refuse = [&](const std::string& why) {
    reason_ = c + " refused: " + why;
    ++events_;
    return false;
  };
  if (c == "arm") {
    if (armed_) return true;
    if (!estimate_ok) return refuse("no fresh estimate");
    if (!landed_) return refuse("not on the ground");
    armed_ = true;
    flew_ = false;
    landed_since_ = now;
    reason_ = "armed";
    ++events_;
    return true;
  }
  if (c == "disarm") {
    if (!armed_) return true;
    if (!landed_) return refuse("in the air");
    armed_ = false;
    reason_ = "disarmed";
    ++events_;
    return true;
  }
  if (c == "offboard") {
    forget_older_than_a_second(setpoints_, now);
    const double age = setpoint_age(now);
    if (age < 0 || age > o_.offboard_timeout_s || static_cast<double>(setpoints_.size()) < o_.offboard_min_rate) {
      return refuse("setpoints must stream first (" + std::to_string(setpoints_.size()) +
                    " in the last second; at least " + config::format_number(o_.offboard_min_rate) + " per second)");
    }
    if (mode_ != Mode::kOffboard) set(Mode::kOffboard, "offboard: setpoints streaming", now);
    failsafe_ = false;
    return true;
  }
  if (c == "land") {
    if (!armed_) return refuse("not armed");
    if (mode_ != Mode::kLand) set(Mode::kLand, "land: commanded", now);
    failsafe_ = false;
    return true;
  }
  if (c == "hold") {
    if (mode_ != Mode::kHold) set(Mode::kHold, "hold: commanded", now);
    failsafe_ = false;
    return true;
  }
  return refuse("unknown command");
}

void Commander::update(Time now, double thrust_ratio, double vertical_speed, double horizontal_speed) {
  // Offboard loss.
  if (mode_ == Mode::kOffboard && armed_) {
    const double age = setpoint_age(now);
    if (age < 0 || age > o_.offboard_timeout_s) {
      ++losses_;
      failsafe_ = true;
      set(o_.offboard_loss_action == "land" ? Mode::kLand : Mode::kHold,
          "offboard lost: no setpoint for " + seconds(age < 0 ? 0 : age) + " (timeout " +
              seconds(o_.offboard_timeout_s) + "): " + o_.offboard_loss_action,
          now);
    }
  }
  if (failsafe_ && mode_ == Mode::kHold && o_.failsafe_land_after_s > 0 &&
      now.seconds_since(mode_since_) > o_.failsafe_land_after_s) {
    set(Mode::kLand, "failsafe: held " + seconds(o_.failsafe_land_after_s) + " without offboard: land", now);
  }

  // The land detector.
  if (!armed_) {
    landed_ = true;
    low_since_.reset();
    return;
  }
  if (landed_) {
    if (thrust_ratio > 1.05 || vertical_speed > 0.3) {
      landed_ = false;
      flew_ = true;
      low_since_.reset();
    }
  } else {
    const bool still = std::abs(vertical_speed) < 0.2 && horizontal_speed < 0.5;
    if (thrust_ratio < 0.7 && still) {
      if (!low_since_) low_since_ = now;
      if (now.seconds_since(*low_since_) >= o_.land_detect_s) {
        landed_ = true;
        landed_since_ = now;
        ++events_;
      }
    } else {
      low_since_.reset();
    }
  }
  // Auto-disarm once landed after a flight (or in land mode).
  if (landed_ && (flew_ || mode_ == Mode::kLand) && o_.disarm_after_landing_s > 0 &&
      now.seconds_since(landed_since_) >= o_.disarm_after_landing_s) {
    armed_ = false;
    reason_ = "disarmed: landed";
    ++events_;
  }
}

}  // namespace driftlab::flight
