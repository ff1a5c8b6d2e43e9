#include "estimator/drone_estimator_module.h"

#include <algorithm>
#include <cmath>

#include "core/config.h"
#include "core/time.h"
#include "driftlab/barometer_t.hpp"
#include "driftlab/estimator_status_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "runtime/module_input.h"

namespace driftlab::estimator {
namespace {

constexpr const char* kInputNames[4] = {"imu", "gnss", "baro", "mag"};

const config::Table<DroneEkfNoise>& drone_noise_table() {
  using N = DroneEkfNoise;
  using config::above;
  const auto r = above(0, 1e4);
  static const auto t =
      config::Table<N>()
          .number("gyro_noise", &N::gyro, r, "rad/s per sqrt(Hz)", "gyro white noise, as process noise on attitude")
          .number("accel_noise", &N::accel, r, "m/s^2 per sqrt(Hz)", "accelerometer white noise, on velocity")
          .number("gyro_bias_walk", &N::gyro_bias_walk, r, "rad/s^2 per sqrt(Hz)", "gyro bias random walk")
          .number("accel_bias_walk", &N::accel_bias_walk, r, "m/s^3 per sqrt(Hz)", "accelerometer bias random walk")
          .number("baro_offset_walk", &N::baro_offset_walk, r, "m/s per sqrt(Hz)", "barometer offset random walk")
          .number("gnss_position_noise", &N::gnss_position, r, "m", "GNSS horizontal position, when the fix gives none")
          .number("gnss_height_noise", &N::gnss_height, r, "m", "GNSS height, when the fix gives none")
          .number("gnss_velocity_noise", &N::gnss_velocity, r, "m/s", "GNSS velocity per axis, when the fix gives none")
          .number("baro_noise", &N::baro, r, "m", "barometric altitude, when the reading gives no variance")
          .number("heading_noise", &N::heading, r, "rad", "magnetometer heading")
          .number("gate", &N::gate, above(0, 1e3), "", "innovation test: outliers beyond this many standard deviations")
          .number("reset_s", &N::reset_s, above(0, 1e4), "s",
                  "a sensor all outliers this long resets the state to it (GNSS: position, velocity; baro: offset)");
  return t;
}

}  // namespace

const config::Table<DroneEstimatorConfig>& drone_estimator_config_table() {
  using C = DroneEstimatorConfig;
  using config::between;
  using config::Text;
  static const auto t =
      config::Table<C>()
          .text("imu_channel", &C::imu_channel, "driftlab.imu_t", Text::kNonEmpty)
          .text("gnss_channel", &C::gnss_channel, "driftlab.gnss_t", Text::kNonEmpty)
          .text("baro_channel", &C::baro_channel, "driftlab.barometer_t", Text::kNonEmpty)
          .text("mag_channel", &C::mag_channel, "driftlab.magnetometer_t", Text::kNonEmpty)
          .text("output_channel", &C::output_channel, "driftlab.odometry_t estimates out", Text::kNonEmpty)
          .text("status_channel", &C::status_channel, "driftlab.estimator_status_t out", Text::kNonEmpty)
          .number("window_s", &C::window_s, between(0, 60), "s", "late measurements are re-applied this far back")
          .number("max_age_s", &C::max_age_s, between(0, 3600), "s", "older than this against the bus's clock: stale")
          .number("max_future_s", &C::max_future_s, between(0, 3600), "s",
                  "further ahead of the bus's clock than this: from the future")
          .number("status_rate", &C::status_rate, between(0.01, 1000), "Hz", "status messages")
          .number("align_s", &C::align_s, between(0, 60), "s",
                  "the start: IMU and magnetometer averaged this long with the vehicle still (tilt and heading)")
          .number("declination", &C::declination, between(-M_PI, M_PI), "rad", "magnetic north east of true north")
          .include(&C::noise, drone_noise_table());
  return t;
}

Result<std::unique_ptr<Module>> make_drone_estimator(const YAML::Node& config, const std::string& origin) {
  auto c = drone_estimator_config_table().parse(config::Value(config, origin, "drone_estimator"));
  if (!c) return c.error();
  return std::unique_ptr<Module>(new DroneEstimatorModule(std::move(*c)));
}

DroneEstimatorModule::DroneEstimatorModule(DroneEstimatorConfig config)
    : c_(std::move(config)), ekf_(DroneEkf(c_.noise, c_.declination, 0), c_.window_s) {}

Status DroneEstimatorModule::start(Bus& bus) {
  bus.subscribe(c_.imu_channel, [this, &bus](const BusMessage& m) {
    driftlab::imu_t s;
    if (!decode_message(m, s)) return void(++undecodable_);
    if (!non_finite_.finite(m)) return;
    ImuSample x;
    x.gyro = Eigen::Vector3d(s.angular_velocity.x, s.angular_velocity.y, s.angular_velocity.z);
    x.accel = Eigen::Vector3d(s.linear_acceleration.x, s.linear_acceleration.y, s.linear_acceleration.z);
    add(bus, kImu, Time::from_us(s.header.utime), x);
  });
  bus.subscribe(c_.gnss_channel, [this, &bus](const BusMessage& m) {
    driftlab::gnss_t g;
    if (!decode_message(m, g)) return void(++undecodable_);
    if (g.fix_type < 3) return void(++no_fix_);
    if (!non_finite_.finite(m)) return;
    // The first fix is the local frame's origin for the whole run: a fix off the globe must not become it.
    if (!(std::abs(g.latitude_deg) <= 90) || !(std::abs(g.longitude_deg) <= 180)) {
      return non_finite_.count(m.channel, "a fix off the globe (latitude " + config::format_number(g.latitude_deg) +
                                              ", longitude " + config::format_number(g.longitude_deg) + ")");
    }
    if (!non_finite_.plausible(m.channel, "altitude_m", g.altitude_m)) return;
    if (!frame_) frame_.emplace(geo::LatLonAlt{g.latitude_deg, g.longitude_deg, g.altitude_m});
    const geo::Enu e = frame_->to_local({g.latitude_deg, g.longitude_deg, g.altitude_m});
    GnssFix f;
    f.position = Eigen::Vector3d(e.east, e.north, e.up);
    f.velocity = Eigen::Vector3d(g.velocity.x, g.velocity.y, g.velocity.z);
    f.eph = g.eph_m;
    f.epv = g.epv_m;
    f.speed_accuracy = g.speed_accuracy_m_s;
    add(bus, kGnss, Time::from_us(g.header.utime), f);
  });
  bus.subscribe(c_.baro_channel, [this, &bus](const BusMessage& m) {
    driftlab::barometer_t b;
    if (!decode_message(m, b)) return void(++undecodable_);
    if (!non_finite_.finite(m)) return;
    if (!(b.pressure_pa > 0)) return void(++undecodable_);
    BaroAltitude a{geo::altitude_of(b.pressure_pa), 0};
    // The pressure's noise as height: through the slope of the standard atmosphere at this pressure.
    if (b.pressure_variance > 0) {
      a.std = std::sqrt(b.pressure_variance) *
              std::abs(geo::altitude_of(b.pressure_pa - 0.5) - geo::altitude_of(b.pressure_pa + 0.5));
    }
    add(bus, kBaro, Time::from_us(b.header.utime), a);
  });
  bus.subscribe(c_.mag_channel, [this, &bus](const BusMessage& m) {
    driftlab::magnetometer_t s;
    if (!decode_message(m, s)) return void(++undecodable_);
    if (!non_finite_.finite(m)) return;
    add(bus, kMag, Time::from_us(s.header.utime),
        MagField{Eigen::Vector3d(s.magnetic_field.x, s.magnetic_field.y, s.magnetic_field.z)});
  });
  bus.every(Duration::periods_rounded(c_.status_rate), [this, &bus] { publish_status(bus); });
  return {};
}

void DroneEstimatorModule::try_init(Time stamp) {
  const Alignment& a = align_;
  if (a.imu == 0 || a.mag == 0 || a.last.seconds_since(a.first) < c_.align_s) return;
  if (!last_fix_ || !last_baro_ || !frame_) return;
  ImuSample imu;
  imu.accel = a.accel / static_cast<double>(a.imu);
  imu.gyro = a.gyro / static_cast<double>(a.imu);
  DroneEkf e(c_.noise, c_.declination, frame_->origin().altitude_m);
  e.init(stamp, imu, MagField{a.field / static_cast<double>(a.mag)}, *last_fix_, *last_baro_);
  ekf_.reset(e);
}

void DroneEstimatorModule::add(Bus& bus, Input kind, Time stamp, const DroneMeasurement& m) {
  InputCounts& n = inputs_[kind];
  ++n.received;
  // In doubles: a hostile stamp at either end of int64_t must not overflow the difference.
  const double age = bus.now().seconds_since(stamp);
  if (age > c_.max_age_s) return void(++n.stale);
  if (-age > c_.max_future_s) return void(++n.future);
  if (!ekf_.filter().initialized()) {
    ++n.before_init;
    switch (kind) {
      case kImu: {
        // A reading far from gravity (the vehicle moving, or settling on its legs) starts the average again.
        const ImuSample& s = std::get<ImuSample>(m);
        if (std::abs(s.accel.norm() - 9.81) > 2) {
          align_ = {};
          break;
        }
        if (align_.imu == 0) align_.first = stamp;
        align_.last = std::max(align_.last, stamp);
        align_.accel += s.accel;
        align_.gyro += s.gyro;
        ++align_.imu;
        break;
      }
      case kGnss: last_fix_ = std::get<GnssFix>(m); break;
      case kBaro: last_baro_ = std::get<BaroAltitude>(m); break;
      case kMag:
        align_.field += std::get<MagField>(m).field;
        ++align_.mag;
        break;
    }
    try_init(stamp);
    return;
  }
  const Time before = ekf_.filter().time();
  if (!ekf_.add(stamp, m)) return void(++n.late);
  if (kind == kImu && ekf_.filter().time() > before) publish_estimate(bus);
}

void DroneEstimatorModule::publish_estimate(Bus& bus) {
  const DroneEkf& f = ekf_.filter();
  driftlab::odometry_t o{};
  o.header.seq = odom_seq_++;
  o.header.utime = f.time().us();
  o.header.frame_id = "odom";
  o.child_frame_id = "base_link";
  o.position = {f.position().x(), f.position().y(), f.position().z()};
  const Eigen::Quaterniond& q = f.attitude();
  o.orientation = {q.w(), q.x(), q.y(), q.z()};
  const Eigen::Vector3d vb = q.inverse() * f.velocity();
  o.linear_velocity = {vb.x(), vb.y(), vb.z()};
  const Eigen::Vector3d w = f.angular_velocity();
  o.angular_velocity = {w.x(), w.y(), w.z()};
  const DroneEkf::Cov& P = f.covariance();
  for (int i = 0; i < 3; ++i) {
    const size_t d = static_cast<size_t>(i) * 7;  // the diagonal of a row-major 6 x 6
    o.pose_covariance[d] = P(DroneEkf::kP + i, DroneEkf::kP + i);
    o.pose_covariance[d + 21] = P(DroneEkf::kTheta + i, DroneEkf::kTheta + i);
    o.twist_covariance[d] = P(DroneEkf::kV + i, DroneEkf::kV + i);
  }
  bus.publish_message(c_.output_channel, o);
}

void DroneEstimatorModule::publish_status(Bus& bus) {
  const DroneEkf& f = ekf_.filter();
  driftlab::estimator_status_t s{};
  s.header.seq = status_seq_++;
  s.header.utime = bus.now().us();
  s.header.frame_id = "";
  s.attitude_valid = f.initialized();
  s.position_valid = f.initialized() && f.time().seconds_since(f.last_position_fix()) < 1.0;
  const DroneEkf::Cov& P = f.covariance();
  s.position_std_m = f.initialized() ? std::sqrt(std::max(P(0, 0), P(1, 1))) : 0;
  s.attitude_std_rad = f.initialized() ? std::sqrt(P.diagonal().segment<3>(DroneEkf::kTheta).maxCoeff()) : 0;
  s.filter_lag_s = f.initialized() ? bus.now().seconds_since(f.time()) : 0;
  s.ninputs = 4;
  for (int i = 0; i < 4; ++i) {
    s.input.push_back(kInputNames[i]);
    s.fused.push_back(f.counts().fused[i]);
    s.stale.push_back(inputs_[i].stale);
    s.future.push_back(inputs_[i].future);
    s.late.push_back(inputs_[i].late);
    s.outliers.push_back(f.counts().outliers[i]);
  }
  bus.publish_message(c_.status_channel, s);
}

void DroneEstimatorModule::finish(Bus& bus) { publish_status(bus); }

ModuleCounters DroneEstimatorModule::counters() const {
  ModuleCounters c;
  int64_t rejected = 0;
  for (int i = 0; i < 4; ++i) {
    const InputCounts& n = inputs_[i];
    rejected += n.stale + n.future + n.late;
    c.metrics.push_back({std::string(kInputNames[i]) + "_stale", static_cast<double>(n.stale)});
    c.metrics.push_back({std::string(kInputNames[i]) + "_future", static_cast<double>(n.future)});
    c.metrics.push_back({std::string(kInputNames[i]) + "_late", static_cast<double>(n.late)});
    const int64_t bad = n.stale + n.future + n.late;
    if (n.received > 0 && bad * 10 > n.received) {
      c.warnings.push_back("drone_estimator: " + std::to_string(bad) + " of " + std::to_string(n.received) + " " +
                           kInputNames[i] + " measurements rejected (" + std::to_string(n.stale) + " stale, " +
                           std::to_string(n.future) + " from the future, " + std::to_string(n.late) +
                           " late): is that sensor stamped on another clock?");
    }
  }
  c.metrics.push_back({"gnss_resets", static_cast<double>(ekf_.filter().counts().resets[kGnss])});
  c.metrics.push_back({"baro_resets", static_cast<double>(ekf_.filter().counts().resets[kBaro])});
  const int64_t refused = ekf_.counters().refused;
  c.dropped = rejected + undecodable_ + refused + non_finite_.dropped();
  c.metrics.push_back({"refused_by_filter", static_cast<double>(refused)});
  if (refused > 0) {
    c.warnings.push_back("drone_estimator: " + std::to_string(refused) +
                         " measurements refused: NaN or infinite values");
  }
  if (auto w = non_finite_.warning("drone_estimator")) c.warnings.push_back(*w);
  if (!ekf_.filter().initialized()) {
    c.warnings.push_back("drone_estimator: never initialised (needs imu, gnss with a 3D fix, baro and mag)");
  }
  return c;
}

}  // namespace driftlab::estimator
