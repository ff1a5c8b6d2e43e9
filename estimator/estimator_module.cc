#include "estimator/estimator_module.h"

#include <cmath>
#include <cstdint>

#include "core/config.h"
#include "core/time.h"
#include "driftlab/imu_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "lcmtypes/planar.h"
#include "runtime/module_input.h"

namespace driftlab::estimator {
namespace {

/// The filter's noises, as keys of the estimator's map.
const config::Table<EkfNoise>& ekf_noise_table() {
  using N = EkfNoise;
  using config::above;
  static const auto t =
      config::Table<N>()
          .number("accel_noise", &N::accel, above(0, 1e4), "m/s^2 per sqrt(s)",
                  "linear acceleration, as process noise on the speed")
          .number("angular_accel_noise", &N::angular_accel, above(0, 1e4), "rad/s^2 per sqrt(s)",
                  "angular acceleration, as process noise on the yaw rate")
          .number("gyro_bias_walk", &N::gyro_bias_walk, above(0, 1e4), "rad/s per sqrt(s)", "gyro bias random walk")
          .number("gyro_noise", &N::gyro, above(0, 1e4), "rad/s",
                  "gyro white noise per sample, when the message gives no covariance")
          .number("odom_v_noise", &N::odom_v, above(0, 1e4), "m/s",
                  "odometry forward speed, when the message gives no covariance")
          .number("odom_w_noise", &N::odom_w, above(0, 1e4), "rad/s",
                  "odometry yaw rate, when the message gives no covariance")
          .number("pose_xy_noise", &N::pose_xy, above(0, 1e4), "m",
                  "absolute pose position, when the message gives no covariance")
          .number("pose_yaw_noise", &N::pose_yaw, above(0, 1e4), "rad",
                  "absolute pose yaw, when the message gives no covariance")
          .number("initial_bias", &N::initial_bias, above(0, 1e4), "rad/s", "initial gyro bias uncertainty");
  return t;
}

}  // namespace

const config::Table<EstimatorConfig>& estimator_config_table() {
  using C = EstimatorConfig;
  static const auto t =
      config::Table<C>()
          .text("imu_channel", &C::imu_channel, "driftlab.imu_t (gyro z); \"\" to ignore")
          .text("odom_channel", &C::odom_channel, "driftlab.odometry_t: its twist; the first pose initialises")
          .text("pose_channel", &C::pose_channel, "driftlab.pose_t absolute poses (SLAM); \"\" to ignore")
          .text("output_channel", &C::output_channel, "driftlab.odometry_t estimates out")
          .text("frame_id", &C::frame_id, "output frame; \"\": the odometry's frame, or map with poses")
          .text("child_frame_id", &C::child_frame_id, "the body frame of the output")
          .number("window_s", &C::window_s, config::between(0, 60), "s",
                  "how far back late measurements are re-applied; 0: reject every late one")
          .number("publish_rate", &C::publish_rate, config::between(0.1, 1000), "Hz", "output rate, in stamp time")
          .include(&C::noise, ekf_noise_table())
          .check([](const config::Value& v, C& c) -> Status {
            if (c.odom_channel.empty() && c.pose_channel.empty()) {
              return v.error("needs odom_channel or pose_channel to start from");
            }
            return {};
          });
  return t;
}

Result<EstimatorConfig> parse_estimator_config(const YAML::Node& node, const std::string& origin) {
  return estimator_config_table().parse(config::Value(node, origin, "estimator"));
}

EstimatorModule::EstimatorModule(EstimatorConfig config)
    : c_(std::move(config)), ekf_(c_.noise, c_.window_s) {}

Status EstimatorModule::start(Bus& bus) {
  if (!c_.imu_channel.empty()) {
    bus.subscribe(c_.imu_channel, [this, &bus](const BusMessage& m) {
      driftlab::imu_t imu;
      if (!decode_message(m, imu)) return void(++undecodable_);
      if (!non_finite_.finite(m)) return;
      ++imu_;
      const double var = imu.angular_velocity_covariance[0] > 0 ? imu.angular_velocity_covariance[8] : 0;
      add(bus, Time::from_us(imu.header.utime), GyroZ{imu.angular_velocity.z, var});
    });
  }
  if (!c_.odom_channel.empty()) {
    bus.subscribe(c_.odom_channel, [this, &bus](const BusMessage& m) {
      driftlab::odometry_t o;
      if (!decode_message(m, o)) return void(++undecodable_);
      if (!non_finite_.finite(m)) return;
      ++odom_;
      if (!ekf_.initialized() && (c_.pose_channel.empty() || poses_ == 0)) {
        if (!ekf_.init(Time::from_us(o.header.utime), {{o.position.x, o.position.y, yaw_of(o.orientation)}},
                       o.linear_velocity.x, o.angular_velocity.z)) {
          return void(++refused_init_);
        }
        if (frame_.empty()) frame_ = c_.frame_id.empty() ? o.header.frame_id : c_.frame_id;
        return;
      }
      // Twist covariance over (vx, vy, vz, wx, wy, wz): vx is [0], wz is [35]; 0 or -1: not given.
      add(bus, Time::from_us(o.header.utime),
          Twist{o.linear_velocity.x, o.angular_velocity.z, o.twist_covariance[0], o.twist_covariance[35]});
    });
  }
  if (!c_.pose_channel.empty()) {
    bus.subscribe(c_.pose_channel, [this, &bus](const BusMessage& m) {
      driftlab::pose_t p;
      if (!decode_message(m, p)) return void(++undecodable_);
      if (!non_finite_.finite(m)) return;
      ++poses_;
      const PoseFix pose{{p.position.x, p.position.y, yaw_of(p.orientation)},
                         std::max(p.covariance[0], p.covariance[7]),
                         p.covariance[35]};
      if (!ekf_.initialized()) {
        if (!ekf_.init(Time::from_us(p.header.utime), pose, 0, 0)) return void(++refused_init_);
        frame_ = c_.frame_id.empty() ? p.header.frame_id : c_.frame_id;
        return;
      }
      if (frame_ != p.header.frame_id && c_.frame_id.empty()) frame_ = p.header.frame_id;
      add(bus, Time::from_us(p.header.utime), pose);
    });
  }
  return {};
}

void EstimatorModule::add(Bus& bus, Time stamp, const Measurement& m) {
  if (!ekf_.initialized()) {
    ++before_init_;
    return;
  }
  ekf_.add(stamp, m);
  const int64_t t = ekf_.filter().time().us();
  if (next_publish_ == 0) next_publish_ = t;
  if (t >= next_publish_) {
    publish(bus);
    // The first multiple of the period after t, computed rather than stepped to (a stamp years ahead would take
    // billions of steps) and saturated at the end of int64_t (a hostile stamp must not overflow).
    const auto period = static_cast<uint64_t>(Duration::periods_rounded(c_.publish_rate).us());
    const uint64_t steps = us_after(next_publish_, t) / period + 1;
    int64_t next = 0;
    if (steps > static_cast<uint64_t>(INT64_MAX) / period ||
        __builtin_add_overflow(next_publish_, static_cast<int64_t>(steps * period), &next)) {
      next = INT64_MAX;
    }
    next_publish_ = next;
  }
}

void EstimatorModule::publish(Bus& bus) {
  const Ekf& f = ekf_.filter();
  const Ekf::State& x = f.state();
  const Ekf::Cov& P = f.covariance();
  driftlab::odometry_t o{};
  o.header.seq = seq_++;
  o.header.utime = f.time().us();
  o.header.frame_id = frame_;
  o.child_frame_id = c_.child_frame_id;
  o.position = {x(Ekf::kX), x(Ekf::kY), 0};
  o.orientation = yaw_quaternion(x(Ekf::kYaw));
  // Pose covariance over (x, y, z, roll, pitch, yaw), twist over (vx, vy, vz, wx, wy, wz).
  const int pose_index[3] = {0, 1, 5};
  const int state_index[3] = {Ekf::kX, Ekf::kY, Ekf::kYaw};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) o.pose_covariance[pose_index[i] * 6 + pose_index[j]] = P(state_index[i], state_index[j]);
  }
  o.linear_velocity = {x(Ekf::kV), 0, 0};
  o.angular_velocity = {0, 0, x(Ekf::kW)};
  o.twist_covariance[0] = P(Ekf::kV, Ekf::kV);
  o.twist_covariance[5] = o.twist_covariance[30] = P(Ekf::kV, Ekf::kW);
  o.twist_covariance[35] = P(Ekf::kW, Ekf::kW);
  bus.publish_message(c_.output_channel, o);
}

void EstimatorModule::finish(Bus& bus) {
  if (ekf_.initialized()) publish(bus);
}

ModuleCounters EstimatorModule::counters() const {
  ModuleCounters c;
  const DelayedEkf::Counters& k = ekf_.counters();
  c.dropped = k.rejected + k.refused + undecodable_ + non_finite_.dropped() + refused_init_;
  c.metrics = {{"applied_in_order", static_cast<double>(k.applied)},
               {"late_reapplied", static_cast<double>(k.reapplied)},
               {"late_rejected", static_cast<double>(k.rejected)},
               {"measurements_replayed", static_cast<double>(k.replays)},
               {"non_finite_dropped", static_cast<double>(non_finite_.dropped())},
               {"refused_by_filter", static_cast<double>(k.refused + refused_init_)}};
  if (!ekf_.initialized()) {
    c.warnings.push_back("estimator: no driftlab.odometry_t on " + (c_.odom_channel.empty() ? "-" : c_.odom_channel) +
                         " and no driftlab.pose_t on " + (c_.pose_channel.empty() ? "-" : c_.pose_channel) +
                         ": nothing estimated");
  }
  if (!c_.imu_channel.empty() && imu_ == 0 && ekf_.initialized()) {
    c.warnings.push_back("estimator: no driftlab.imu_t on " + c_.imu_channel + ": odometry and poses only");
  }
  if (undecodable_ > 0) {
    c.warnings.push_back("estimator: " + std::to_string(undecodable_) + " messages of the wrong type ignored");
  }
  if (auto w = non_finite_.warning("estimator")) c.warnings.push_back(*w);
  if (k.refused + refused_init_ > 0) {
    c.warnings.push_back("estimator: " + std::to_string(k.refused + refused_init_) +
                         " measurements refused: values so large the filter would overflow");
  }
  return c;
}

Result<std::unique_ptr<Module>> make_estimator(const YAML::Node& config, const std::string& origin) {
  auto c = parse_estimator_config(config, origin);
  if (!c) return c.error();
  return std::unique_ptr<Module>(new EstimatorModule(std::move(*c)));
}

}  // namespace driftlab::estimator
