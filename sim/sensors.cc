#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <limits>

#include "core/geo.h"
#include "core/time.h"
#include "driftlab/barometer_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/image_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/planar.h"
#include "sim/camera_render.h"
#include "sim/internal/sensors.h"
#include "sim/raycaster.h"

namespace driftlab::sim {
namespace {

driftlab::vector3_t vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
driftlab::quaternion_t quat(const Eigen::Quaterniond& q) { return {q.w(), q.x(), q.y(), q.z()}; }
driftlab::quaternion_t yaw_quat(double yaw) { return {std::cos(yaw / 2), 0, 0, std::sin(yaw / 2)}; }

/// Samples at `rate` Hz: due() is true once per period, on the first step at or after each due time.
class Periodic : public Sensor {
 protected:
  Periodic(const SensorConfig& c, Output& out) : config_(c), stream_(out.add_stream(c.channel)) {}
  bool due(const SensorContext& ctx) {
    if (ctx.now_utime - ctx.start_utime < due_us(n_, config_.rate)) return false;
    ++n_;
    return true;
  }
  const std::string& link(const Robot& robot) const { return config_.link.empty() ? robot.base_link() : config_.link; }
  SensorConfig config_;
  int stream_;
  int64_t n_ = 0;
};

class GroundTruth final : public Periodic {
 public:
  GroundTruth(const SensorConfig& c, Output& out) : Periodic(c, out) {}
  void step(SensorContext& ctx) override {
    if (!due(ctx)) return;
    const Eigen::Isometry3d pose = ctx.robot.link_pose(link(ctx.robot));
    driftlab::pose_t m{};
    m.header.frame_id = "world";
    m.child_frame_id = link(ctx.robot);
    m.position = vec(pose.translation());
    m.orientation = quat(Eigen::Quaterniond(pose.rotation()));
    ctx.out.publish(stream_, m, ctx.now_utime, ctx.now_utime);
  }
};

class JointStates final : public Periodic {
 public:
  JointStates(const SensorConfig& c, Output& out) : Periodic(c, out) {}
  void step(SensorContext& ctx) override {
    if (!due(ctx)) return;
    driftlab::joint_state_t m{};
    m.header.frame_id = ctx.robot.base_link();
    for (const JointReading& j : ctx.robot.joints()) {
      m.name.push_back(j.name);
      m.position.push_back(j.position);
      m.velocity.push_back(j.velocity);
      m.effort.push_back(j.effort);
    }
    m.njoints = static_cast<int32_t>(m.name.size());
    ctx.out.publish(stream_, m, ctx.now_utime, ctx.now_utime);
  }
};

class Imu final : public Periodic {
 public:
  Imu(const SensorConfig& c, Output& out, uint64_t seed) : Periodic(c, out), rng_(seed) {
    std::normal_distribution<double> n(0, 1);
    for (int i = 0; i < 3; ++i) {
      gyro_bias_[i] = c.imu.gyro_bias * n(rng_);
      accel_bias_[i] = c.imu.accel_bias * n(rng_);
    }
  }
  void step(SensorContext& ctx) override {
    if (!due(ctx)) return;
    const ImuParams& p = config_.imu;
    const std::string& l = link(ctx.robot);
    const Eigen::Isometry3d pose = ctx.robot.link_pose(l);
    const Eigen::Vector3d v = ctx.robot.link_linear_velocity(l);
    // The accelerometer measures the mean acceleration over its sample period (the physics' contact forces
    // make instantaneous accelerations spiky), plus the reaction to gravity.
    Eigen::Vector3d a = Eigen::Vector3d::Zero();
    if (have_prev_) a = (v - prev_v_) / (Time::from_us(ctx.now_utime) - Time::from_us(prev_utime_)).seconds();
    prev_v_ = v;
    prev_utime_ = ctx.now_utime;
    have_prev_ = true;
    const Eigen::Matrix3d rt = pose.rotation().transpose();
    const Eigen::Vector3d gyro_true = rt * ctx.robot.link_angular_velocity(l);
    const Eigen::Vector3d accel_true = rt * (a + Eigen::Vector3d(0, 0, 9.81));
    // Discrete white noise and bias random walk from the continuous densities (Kalibr's model).
    const double dt = 1.0 / config_.rate;
    const double sg = p.gyro_noise_density / std::sqrt(dt), sa = p.accel_noise_density / std::sqrt(dt);
    const double wg = p.gyro_random_walk * std::sqrt(dt), wa = p.accel_random_walk * std::sqrt(dt);
    std::normal_distribution<double> n(0, 1);
    Eigen::Vector3d gyro, accel;
    for (int i = 0; i < 3; ++i) {
      gyro_bias_[i] += wg * n(rng_);
      accel_bias_[i] += wa * n(rng_);
      gyro[i] = gyro_true[i] + gyro_bias_[i] + sg * n(rng_);
      accel[i] = accel_true[i] + accel_bias_[i] + sa * n(rng_);
    }
    driftlab::imu_t m{};
    m.header.frame_id = l;
    m.orientation = {1, 0, 0, 0};
    m.orientation_covariance[0] = -1;  // not provided
    m.angular_velocity = vec(gyro);
    m.linear_acceleration = vec(accel);
    for (int i = 0; i < 3; ++i) {
      m.angular_velocity_covariance[4 * i] = sg * sg;
      m.linear_acceleration_covariance[4 * i] = sa * sa;
    }
    ctx.out.publish(stream_, m, ctx.now_utime, ctx.now_utime);
  }

 private:
  std::mt19937_64 rng_;
  Eigen::Vector3d gyro_bias_, accel_bias_, prev_v_ = Eigen::Vector3d::Zero();
  int64_t prev_utime_ = 0;
  bool have_prev_ = false;
};

/// The world's magnetic field in its east-north-up frame [T].
Eigen::Vector3d field_world(const GeoConfig& g) {
  const double h = g.field * std::cos(g.inclination);
  return {h * std::sin(g.declination), h * std::cos(g.declination), -g.field * std::sin(g.inclination)};
}

class Barometer final : public Periodic {
 public:
  Barometer(const SensorConfig& c, Output& out, uint64_t seed, const GeoConfig& geo)
      : Periodic(c, out), rng_(seed), geo_(geo), offset_(c.barometer.offset) {}
  void step(SensorContext& ctx) override {
    if (!due(ctx)) return;
    const BarometerParams& p = config_.barometer;
    std::normal_distribution<double> n(0, 1);
    offset_ += p.offset_walk * std::sqrt(1.0 / config_.rate) * n(rng_);
    const double z = ctx.robot.link_pose(link(ctx.robot)).translation().z();
    driftlab::barometer_t m{};
    m.header.frame_id = link(ctx.robot);
    m.pressure_pa = geo::pressure_at(geo_.altitude + z) + offset_ + p.noise * n(rng_);
    m.temperature_c = p.temperature;
    m.pressure_variance = p.noise * p.noise;
    ctx.out.publish(stream_, m, ctx.now_utime, ctx.now_utime);
  }

 private:
  std::mt19937_64 rng_;
  GeoConfig geo_;
  double offset_;
};

class Gnss final : public Periodic {
 public:
  Gnss(const SensorConfig& c, Output& out, uint64_t seed, const GeoConfig& geo)
      : Periodic(c, out), rng_(seed), frame_({geo.latitude, geo.longitude, geo.altitude}) {}
  void step(SensorContext& ctx) override {
    if (!due(ctx)) return;
    const GnssParams& p = config_.gnss;
    std::normal_distribution<double> n(0, 1);
    // The wander: a first-order Gauss-Markov process of the given standard deviation, exact in discrete time, from
    // its stationary distribution; then white noise.
    const Eigen::Vector3d drift(p.horizontal_drift, p.horizontal_drift, p.vertical_drift);
    const Eigen::Vector3d white(p.horizontal_noise, p.horizontal_noise, p.vertical_noise);
    const double a = p.correlation_time > 0 ? std::exp(-1.0 / config_.rate / p.correlation_time) : 0.0;
    Eigen::Vector3d pos = ctx.robot.link_pose(link(ctx.robot)).translation();
    for (int i = 0; i < 3; ++i) {
      drift_[i] = n_ == 1 ? drift[i] * n(rng_) : a * drift_[i] + std::sqrt(1 - a * a) * drift[i] * n(rng_);
      pos[i] += drift_[i] + white[i] * n(rng_);
    }
    const std::string& l = link(ctx.robot);
    const Eigen::Vector3d vel = ctx.robot.link_linear_velocity(l);
    const geo::LatLonAlt g = frame_.to_global({pos.x(), pos.y(), pos.z()});
    driftlab::gnss_t m{};
    m.header.frame_id = l;
    m.fix_type = 3;
    m.satellites = p.satellites;
    m.latitude_deg = g.latitude_deg;
    m.longitude_deg = g.longitude_deg;
    m.altitude_m = g.altitude_m;
    m.eph_m = std::hypot(p.horizontal_noise, p.horizontal_drift);
    m.epv_m = std::hypot(p.vertical_noise, p.vertical_drift);
    m.velocity = {vel.x() + p.velocity_noise * n(rng_), vel.y() + p.velocity_noise * n(rng_),
                  vel.z() + p.velocity_noise * n(rng_)};
    m.speed_accuracy_m_s = p.velocity_noise;
    ctx.out.publish(stream_, m, ctx.now_utime, ctx.now_utime);
  }

 private:
  std::mt19937_64 rng_;
  geo::LocalFrame frame_;
  Eigen::Vector3d drift_ = Eigen::Vector3d::Zero();  // the wander [m]
};

class Magnetometer final : public Periodic {
 public:
  Magnetometer(const SensorConfig& c, Output& out, uint64_t seed, const GeoConfig& geo)
      : Periodic(c, out), rng_(seed), field_(field_world(geo)) {}
  void step(SensorContext& ctx) override {
    if (!due(ctx)) return;
    const double s = config_.magnetometer.noise;
    std::normal_distribution<double> n(0, 1);
    const Eigen::Vector3d b = ctx.robot.link_pose(link(ctx.robot)).rotation().transpose() * field_;
    driftlab::magnetometer_t m{};
    m.header.frame_id = link(ctx.robot);
    m.magnetic_field = {b.x() + s * n(rng_), b.y() + s * n(rng_), b.z() + s * n(rng_)};
    for (size_t i = 0; i < 3; ++i) m.magnetic_field_covariance[4 * i] = s * s;
    ctx.out.publish(stream_, m, ctx.now_utime, ctx.now_utime);
  }

 private:
  std::mt19937_64 rng_;
  Eigen::Vector3d field_;
};

class Odometry final : public Periodic {
 public:
  Odometry(const SensorConfig& c, Output& out, WheelOdometry& odom)
      : Periodic(c, out), odom_(odom), tf_stream_(c.odometry.tf_channel.empty() ? -1 : out.add_stream(c.odometry.tf_channel)) {}
  void step(SensorContext& ctx) override {
    if (!due(ctx)) return;
    odom_.update(ctx.robot, 1.0 / config_.rate);
    driftlab::odometry_t m{};
    m.header.frame_id = config_.odometry.frame;
    m.child_frame_id = ctx.robot.base_link();
    m.position = {odom_.x(), odom_.y(), 0};
    m.orientation = yaw_quat(odom_.yaw());
    m.linear_velocity = {odom_.linear(), 0, 0};
    m.angular_velocity = {0, 0, odom_.angular()};
    m.pose_covariance[0] = m.pose_covariance[7] = odom_.var_xy();
    m.pose_covariance[14] = m.pose_covariance[21] = m.pose_covariance[28] = 1e-6;  // planar: z, roll, pitch held
    m.pose_covariance[35] = odom_.var_yaw();
    for (int i = 0; i < 6; ++i) m.twist_covariance[7 * i] = 1e-4;
    ctx.out.publish(stream_, m, ctx.now_utime, ctx.now_utime);
    if (tf_stream_ >= 0) {
      driftlab::tf_t tf{};
      tf.header.frame_id = config_.odometry.frame;
      driftlab::transform_t t{};
      t.header.utime = m.header.utime;
      t.header.frame_id = config_.odometry.frame;
      t.child_frame_id = ctx.robot.base_link();
      t.translation = m.position;
      t.rotation = m.orientation;
      tf.transforms.push_back(t);
      tf.ntransforms = 1;
      ctx.out.publish(tf_stream_, tf, ctx.now_utime, ctx.now_utime);
    }
  }

 private:
  WheelOdometry& odom_;
  int tf_stream_;
};

class Camera final : public Periodic {
 public:
  Camera(const SensorConfig& c, Output& out) : Periodic(c, out) {
    model_.width = c.camera.width;
    model_.height = c.camera.height;
    model_.hfov = c.camera.hfov;
    model_.max_range = c.camera.max_range;
    if (c.camera.encoding == "jpeg") {
      params_ = {cv::IMWRITE_JPEG_QUALITY, c.camera.quality};
    } else {
      params_ = {cv::IMWRITE_PNG_COMPRESSION, 1};
    }
  }
  void step(SensorContext& ctx) override {
    if (!due(ctx)) return;
    render_camera(ctx.caster, model_, ctx.robot.link_pose(link(ctx.robot)), image_);
    driftlab::image_t m{};
    m.header.frame_id = link(ctx.robot);
    m.width = image_.cols;
    m.height = image_.rows;
    m.encoding = config_.camera.encoding;
    cv::imencode(config_.camera.encoding == "jpeg" ? ".jpg" : ".png", image_, m.data, params_);
    m.size = static_cast<int32_t>(m.data.size());
    ctx.out.publish(stream_, m, ctx.now_utime, ctx.now_utime);
  }

 private:
  CameraModel model_;
  std::vector<int> params_;
  cv::Mat image_;
};

/// A spinning sensor: one revolution per period, its `units` (beams or columns) measured one after the other
/// through it, each from the pose at its physics step, so motion during the revolution distorts the data as on a
/// real lidar. Stamped at the first unit, published when the last is in.
class Spinning : public Periodic {
 public:
  void step(SensorContext& ctx) override {
    while (true) {
      if (unit_ < 0) {
        if (!due(ctx)) return;
        start_ = ctx.start_utime + due_us(n_ - 1, config_.rate);
        unit_ = 0;
      }
      const Eigen::Isometry3d pose = ctx.robot.link_pose(link(ctx.robot));
      for (; unit_ < units_ && unit_time(unit_) <= ctx.now_utime; ++unit_) {
        measure(ctx, pose, unit_, Duration::from_us(unit_time(unit_) - start_).seconds());
      }
      if (unit_ < units_) return;
      publish(ctx, start_);
      unit_ = -1;
    }
  }

 protected:
  Spinning(const SensorConfig& c, Output& out, uint64_t seed, int units, double unit_dt_s)
      : Periodic(c, out), rng_(seed), units_(units), unit_dt_s_(unit_dt_s) {}
  /// Measures unit i from `pose`, offset_s after the stamp.
  virtual void measure(SensorContext& ctx, const Eigen::Isometry3d& pose, int i, double offset_s) = 0;
  virtual void publish(SensorContext& ctx, int64_t stamp) = 0;
  /// A range with Gaussian noise, or NaN when there is no return within [range_min, range_max].
  double noisy_range(SensorContext& ctx, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double range_min,
                     double range_max, double noise) {
    double r = ctx.range(origin, dir, range_max);
    if (std::isfinite(r)) r += noise * unit_normal_(rng_);
    return std::isfinite(r) && r >= range_min && r <= range_max ? r : NAN;
  }

 private:
  int64_t unit_time(int i) const { return start_ + Duration::from_seconds_rounded(i * unit_dt_s_).us(); }
  std::mt19937_64 rng_;
  std::normal_distribution<double> unit_normal_{0, 1};
  int units_;
  double unit_dt_s_;
  int unit_ = -1;  // next unit of the revolution in progress; -1: none
  int64_t start_ = 0;
};

/// Beam times for a 2D lidar: one revolution per period, the beams covering the field of view's share of it.
double beam_dt(const SensorConfig& c) {
  return 1.0 / c.rate * std::min(1.0, c.lidar2d.fov / (2 * M_PI)) / c.lidar2d.beams;
}

/// A spinning 2D lidar (laser_scan_t).
class Lidar2d final : public Spinning {
 public:
  Lidar2d(const SensorConfig& c, Output& out, uint64_t seed)
      : Spinning(c, out, seed, c.lidar2d.beams, static_cast<float>(beam_dt(c))) {
    const Lidar2dParams& p = c.lidar2d;
    const double inc = p.beams > 1 ? p.fov / (p.fov >= 2 * M_PI - 1e-9 ? p.beams : p.beams - 1) : 0;
    msg_.angle_min = static_cast<float>(-p.fov / 2);
    msg_.angle_increment = static_cast<float>(inc);
    msg_.angle_max = static_cast<float>(-p.fov / 2 + inc * (p.beams - 1));
    msg_.time_increment = static_cast<float>(beam_dt(c));
    msg_.scan_time = static_cast<float>(1.0 / c.rate);
    msg_.range_min = static_cast<float>(p.range_min);
    msg_.range_max = static_cast<float>(p.range_max);
    msg_.nranges = p.beams;
    msg_.ranges.resize(static_cast<std::size_t>(p.beams));
    msg_.nintensities = 0;
  }

 private:
  void measure(SensorContext& ctx, const Eigen::Isometry3d& pose, int i, double) override {
    const Lidar2dParams& p = config_.lidar2d;
    const double a = msg_.angle_min + i * static_cast<double>(msg_.angle_increment);
    const Eigen::Vector3d dir = pose.rotation() * Eigen::Vector3d(std::cos(a), std::sin(a), 0);
    msg_.ranges[static_cast<std::size_t>(i)] =
        static_cast<float>(noisy_range(ctx, pose.translation(), dir, p.range_min, p.range_max, p.range_noise));
  }
  void publish(SensorContext& ctx, int64_t stamp) override {
    msg_.header.frame_id = link(ctx.robot);
    ctx.out.publish(stream_, msg_, stamp, ctx.now_utime);
  }
  driftlab::laser_scan_t msg_{};
};

/// A spinning multi-ring lidar: one column of rings per azimuth step; an organised cloud (height = rings,
/// width = columns) in the sensor frame with per-point time offsets.
class Lidar3d final : public Spinning {
 public:
  Lidar3d(const SensorConfig& c, Output& out, uint64_t seed)
      : Spinning(c, out, seed, c.lidar3d.columns, 1.0 / c.rate / c.lidar3d.columns) {
    const Lidar3dParams& p = c.lidar3d;
    const std::size_t n = static_cast<std::size_t>(p.rings) * static_cast<std::size_t>(p.columns);
    msg_.height = p.rings;
    msg_.width = p.columns;
    msg_.npoints = static_cast<int32_t>(n);
    msg_.x.resize(n);
    msg_.y.resize(n);
    msg_.z.resize(n);
    msg_.nintensities = 0;
    msg_.ntimes = static_cast<int32_t>(n);
    msg_.time_offsets.resize(n);
    for (int r = 0; r < p.rings; ++r) {
      const double e = p.rings > 1 ? p.vertical_min + r * (p.vertical_max - p.vertical_min) / (p.rings - 1) : p.vertical_min;
      ring_cos_.push_back(std::cos(e));
      ring_sin_.push_back(std::sin(e));
    }
  }

 private:
  void measure(SensorContext& ctx, const Eigen::Isometry3d& pose, int column, double offset_s) override {
    const Lidar3dParams& p = config_.lidar3d;
    const double az = -M_PI + 2 * M_PI * column / p.columns;
    const double ca = std::cos(az), sa = std::sin(az);
    for (int r = 0; r < p.rings; ++r) {
      const Eigen::Vector3d local(ring_cos_[r] * ca, ring_cos_[r] * sa, ring_sin_[r]);
      const double range =
          noisy_range(ctx, pose.translation(), pose.rotation() * local, p.range_min, p.range_max, p.range_noise);
      const std::size_t i = static_cast<std::size_t>(r) * static_cast<std::size_t>(p.columns) + static_cast<std::size_t>(column);
      msg_.x[i] = static_cast<float>(local.x() * range);
      msg_.y[i] = static_cast<float>(local.y() * range);
      msg_.z[i] = static_cast<float>(local.z() * range);
      msg_.time_offsets[i] = static_cast<float>(offset_s);
    }
  }
  void publish(SensorContext& ctx, int64_t stamp) override {
    msg_.header.frame_id = link(ctx.robot);
    ctx.out.publish(stream_, msg_, stamp, ctx.now_utime);
  }
  driftlab::point_cloud_t msg_{};
  std::vector<double> ring_cos_, ring_sin_;
};

}  // namespace

uint64_t stream_seed(uint64_t seed, const std::string& name) {
  // FNV-1a of the name mixed with the seed: stable across platforms and runs.
  uint64_t h = 1469598103934665603ULL;
  for (unsigned char c : name) h = (h ^ c) * 1099511628211ULL;
  return h ^ (seed * 0x9E3779B97F4A7C15ULL);
}

WheelOdometry::WheelOdometry(const OdometryParams& p, const Robot& robot, uint64_t seed)
    : p_(p), radius_(robot.wheel_radius()), separation_(robot.wheel_separation()), rng_(seed) {}

int64_t WheelOdometry::ticks(double angle) const {
  return static_cast<int64_t>(std::floor(angle / (2 * M_PI) * p_.ticks_per_rev));
}

void WheelOdometry::update(const Robot& robot, double dt) {
  std::normal_distribution<double> slip(0, p_.slip_noise);
  const double l = robot.left_wheel_angle(), r = robot.right_wheel_angle();
  meas_l_ += (l - true_l_) * (1 + slip(rng_));
  meas_r_ += (r - true_r_) * (1 + slip(rng_));
  true_l_ = l;
  true_r_ = r;
  const int64_t tl = ticks(meas_l_), tr = ticks(meas_r_);
  const double per_tick = 2 * M_PI / p_.ticks_per_rev;
  // The odometry believes the calibrated geometry, which is off by the configured errors.
  const double dl = static_cast<double>(tl - ticks_l_) * per_tick * radius_ * (1 + p_.left_radius_error);
  const double dr = static_cast<double>(tr - ticks_r_) * per_tick * radius_ * (1 + p_.right_radius_error);
  ticks_l_ = tl;
  ticks_r_ = tr;
  const double ds = 0.5 * (dl + dr), dyaw = (dr - dl) / (separation_ * (1 + p_.separation_error));
  x_ += ds * std::cos(yaw_ + dyaw / 2);
  y_ += ds * std::sin(yaw_ + dyaw / 2);
  yaw_ = wrap_angle(yaw_ + dyaw);
  v_ = dt > 0 ? ds / dt : 0;
  w_ = dt > 0 ? dyaw / dt : 0;
  // Uncertainty grows with the distance and the rotation driven (slip, quantisation).
  const double k = std::max(p_.slip_noise, 1e-3);
  var_xy_ += k * k * ds * ds + 1e-8;
  var_yaw_ += k * k * (dyaw * dyaw + ds * ds / (separation_ * separation_)) + 1e-10;
}

std::unique_ptr<Sensor> make_sensor(const SensorConfig& c, const Robot& robot, Output& out, uint64_t seed,
                                    WheelOdometry* odometry, const GeoConfig& geo) {
  const uint64_t s = stream_seed(seed, c.channel);
  switch (c.type) {
    case SensorType::kLidar2d: return std::make_unique<Lidar2d>(c, out, s);
    case SensorType::kLidar3d: return std::make_unique<Lidar3d>(c, out, s);
    case SensorType::kImu: return std::make_unique<Imu>(c, out, s);
    case SensorType::kOdometry: return std::make_unique<Odometry>(c, out, *odometry);
    case SensorType::kCamera: return std::make_unique<Camera>(c, out);
    case SensorType::kGroundTruth: return std::make_unique<GroundTruth>(c, out);
    case SensorType::kJointState: return std::make_unique<JointStates>(c, out);
    case SensorType::kBarometer: return std::make_unique<Barometer>(c, out, s, geo);
    case SensorType::kGnss: return std::make_unique<Gnss>(c, out, s, geo);
    case SensorType::kMagnetometer: return std::make_unique<Magnetometer>(c, out, s, geo);
  }
  return nullptr;
}

}  // namespace driftlab::sim
