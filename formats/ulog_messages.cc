#include "formats/ulog_messages.h"

#include <cmath>
#include <cstring>
#include <limits>

#include "driftlab/barometer_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "lcmtypes/encode.h"

namespace driftlab::formats {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// header.utime: when the sensor sampled (timestamp_sample) where the message says, else its timestamp.
int64_t sample_time(const UlogLayout& l, std::span<const uint8_t> p, uint64_t timestamp) {
  return ulog_utime(l.u64(p, "timestamp_sample").value_or(timestamp));
}

bool has(const UlogLayout& l, std::string_view name, uint32_t count = 0) {
  const UlogLayout::Field* f = l.find(name);
  return f && f->count == count && f->type != UlogType::kChar;
}

/// An imu_t of a PX4 IMU topic: no orientation (PX4's IMU topics carry none), stamped when sampled, in PX4's body
/// frame (forward, right, down); the caller sets its rates and accelerations.
imu_t bare_imu(const UlogLayout& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq) {
  imu_t m;
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  m.header.frame_id = "body_frd";
  m.orientation.w = 1;
  m.orientation.x = m.orientation.y = m.orientation.z = 0;
  for (int i = 0; i < 9; ++i) {
    m.orientation_covariance[i] = 0;
    m.angular_velocity_covariance[i] = 0;
    m.linear_acceleration_covariance[i] = 0;
  }
  m.orientation_covariance[0] = -1;  // not provided
  return m;
}

std::optional<UlogConverted> imu(const UlogLayout& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq) {
  if (!has(l, "gyro_rad", 3) || !has(l, "accelerometer_m_s2", 3)) return std::nullopt;
  // sensor_combined's timestamp is its gyro sample's time (the accelerometer's is timestamp +
  // accelerometer_timestamp_relative); it has no timestamp_sample.
  imu_t m = bare_imu(l, p, timestamp, seq);
  m.angular_velocity.x = l.number(p, "gyro_rad", 0);
  m.angular_velocity.y = l.number(p, "gyro_rad", 1);
  m.angular_velocity.z = l.number(p, "gyro_rad", 2);
  m.linear_acceleration.x = l.number(p, "accelerometer_m_s2", 0);
  m.linear_acceleration.y = l.number(p, "accelerometer_m_s2", 1);
  m.linear_acceleration.z = l.number(p, "accelerometer_m_s2", 2);
  return UlogConverted{"driftlab.imu_t", lcmtypes::encode(m)};
}

/// vehicle_imu (PX4 1.11 and later): one IMU's integrated rotation and velocity change over its interval; the mean
/// rate and specific force over the interval are the changes over their dt (NaN, not measured, for a dt of 0).
std::optional<UlogConverted> vehicle_imu(const UlogLayout& l, std::span<const uint8_t> p, uint64_t timestamp,
                                         int64_t seq) {
  if (!has(l, "delta_angle", 3) || !has(l, "delta_velocity", 3) || !has(l, "delta_angle_dt") ||
      !has(l, "delta_velocity_dt")) {
    return std::nullopt;
  }
  imu_t m = bare_imu(l, p, timestamp, seq);
  const double angle_dt = l.number(p, "delta_angle_dt") * 1e-6, velocity_dt = l.number(p, "delta_velocity_dt") * 1e-6;
  auto rate = [](double delta, double dt) { return dt > 0 ? delta / dt : kNaN; };
  m.angular_velocity.x = rate(l.number(p, "delta_angle", 0), angle_dt);
  m.angular_velocity.y = rate(l.number(p, "delta_angle", 1), angle_dt);
  m.angular_velocity.z = rate(l.number(p, "delta_angle", 2), angle_dt);
  m.linear_acceleration.x = rate(l.number(p, "delta_velocity", 0), velocity_dt);
  m.linear_acceleration.y = rate(l.number(p, "delta_velocity", 1), velocity_dt);
  m.linear_acceleration.z = rate(l.number(p, "delta_velocity", 2), velocity_dt);
  return UlogConverted{"driftlab.imu_t", lcmtypes::encode(m)};
}

/// sensor_baro: static pressure and temperature. PX4 1.12 and earlier log millibar, later Pascal: a pressure under
/// 2000 is millibar (2000 Pa is the air 27 km up; 2000 mbar no air a vehicle meets).
std::optional<UlogConverted> barometer(const UlogLayout& l, std::span<const uint8_t> p, uint64_t timestamp,
                                       int64_t seq) {
  if (!has(l, "pressure")) return std::nullopt;
  barometer_t m;
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  m.header.frame_id = "baro";
  const double pressure = l.number(p, "pressure");
  m.pressure_pa = std::abs(pressure) < 2000 ? pressure * 100 : pressure;
  m.temperature_c = has(l, "temperature") ? l.number(p, "temperature") : kNaN;
  m.pressure_variance = 0;  // not given
  return UlogConverted{"driftlab.barometer_t", lcmtypes::encode(m)};
}

/// sensor_mag (the sensor's frame: x, y, z) and vehicle_magnetometer (the body frame: magnetometer_ga), in gauss:
/// tesla are 1e-4 of them.
std::optional<UlogConverted> magnetometer(const UlogLayout& l, std::span<const uint8_t> p, uint64_t timestamp,
                                          int64_t seq) {
  magnetometer_t m;
  if (has(l, "magnetometer_ga", 3)) {
    m.header.frame_id = "body_frd";
    m.magnetic_field.x = l.number(p, "magnetometer_ga", 0) * 1e-4;
    m.magnetic_field.y = l.number(p, "magnetometer_ga", 1) * 1e-4;
    m.magnetic_field.z = l.number(p, "magnetometer_ga", 2) * 1e-4;
  } else if (has(l, "x") && has(l, "y") && has(l, "z")) {
    m.header.frame_id = "mag";
    m.magnetic_field.x = l.number(p, "x") * 1e-4;
    m.magnetic_field.y = l.number(p, "y") * 1e-4;
    m.magnetic_field.z = l.number(p, "z") * 1e-4;
  } else {
    return std::nullopt;
  }
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  for (double& c : m.magnetic_field_covariance) c = 0;  // not given
  return UlogConverted{"driftlab.magnetometer_t", lcmtypes::encode(m)};
}

std::optional<UlogConverted> gnss(const UlogLayout& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq) {
  gnss_t m;
  if (has(l, "latitude_deg") && has(l, "longitude_deg") && has(l, "altitude_msl_m")) {
    // PX4 1.14 and later: degrees and metres as doubles.
    m.latitude_deg = l.number(p, "latitude_deg");
    m.longitude_deg = l.number(p, "longitude_deg");
    m.altitude_m = l.number(p, "altitude_msl_m");
  } else if (has(l, "lat") && has(l, "lon") && has(l, "alt")) {
    // Earlier: int32_t 1e-7 degrees and millimetres above mean sea level.
    m.latitude_deg = l.number(p, "lat") * 1e-7;
    m.longitude_deg = l.number(p, "lon") * 1e-7;
    m.altitude_m = l.number(p, "alt") * 1e-3;
  } else {
    return std::nullopt;
  }
  if (!has(l, "fix_type")) return std::nullopt;
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  m.header.frame_id = "gps";
  // PX4: 0-1 no fix, 2 2D, 3 3D, 4 DGPS, 5 RTK float, 6 RTK fixed, 8 extrapolated: all of 3 and up are 3D fixes.
  const double fix = l.number(p, "fix_type");
  m.fix_type = fix >= 3 ? 3 : fix == 2 ? 2 : 0;
  const double sats = l.number(p, "satellites_used");
  m.satellites = std::isfinite(sats) ? static_cast<int32_t>(sats) : 0;
  m.eph_m = l.number(p, "eph");
  m.epv_m = l.number(p, "epv");
  // North, east, down into east, north, up; NaN (not measured) when the format has no velocity.
  m.velocity.x = l.number(p, "vel_e_m_s");
  m.velocity.y = l.number(p, "vel_n_m_s");
  m.velocity.z = -l.number(p, "vel_d_m_s");
  m.speed_accuracy_m_s = has(l, "s_variance_m_s") ? l.number(p, "s_variance_m_s") : kNaN;
  return UlogConverted{"driftlab.gnss_t", lcmtypes::encode(m)};
}

std::optional<UlogConverted> local_position(const UlogLayout& l, std::span<const uint8_t> p, uint64_t timestamp,
                                            int64_t seq) {
  const char* heading = has(l, "heading") ? "heading" : has(l, "yaw") ? "yaw" : nullptr;  // "yaw" before PX4 1.10
  for (const char* f : {"x", "y", "z", "vx", "vy", "vz"})
    if (!has(l, f)) return std::nullopt;
  if (!heading) return std::nullopt;
  odometry_t m;
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  m.header.frame_id = "local_ned";  // PX4's local frame: north, east, down from its origin
  m.child_frame_id = "body_frd";
  m.position.x = l.number(p, "x");
  m.position.y = l.number(p, "y");
  m.position.z = l.number(p, "z");
  // The local position carries the heading alone (roll and pitch are vehicle_attitude's): a rotation about down.
  const double yaw = l.number(p, heading);
  m.orientation.w = std::cos(yaw / 2);
  m.orientation.x = m.orientation.y = 0;
  m.orientation.z = std::sin(yaw / 2);
  // The velocity, north-east-down in PX4, into the child frame as odometry_t holds it (about the heading).
  const double vn = l.number(p, "vx"), ve = l.number(p, "vy");
  m.linear_velocity.x = std::cos(yaw) * vn + std::sin(yaw) * ve;
  m.linear_velocity.y = -std::sin(yaw) * vn + std::cos(yaw) * ve;
  m.linear_velocity.z = l.number(p, "vz");
  m.angular_velocity.x = m.angular_velocity.y = m.angular_velocity.z = kNaN;  // not in the message
  for (int i = 0; i < 36; ++i) m.pose_covariance[i] = m.twist_covariance[i] = 0;
  // Standard deviations where PX4 gives them (eph, epv, evh, evv), as variances on the diagonal; 0: not given.
  auto variance = [&](const char* f) {
    const double sd = l.number(p, f);
    return std::isfinite(sd) ? sd * sd : 0.0;
  };
  m.pose_covariance[0] = m.pose_covariance[7] = variance("eph");
  m.pose_covariance[14] = variance("epv");
  m.twist_covariance[0] = m.twist_covariance[7] = variance("evh");
  m.twist_covariance[14] = variance("evv");
  return UlogConverted{"driftlab.odometry_t", lcmtypes::encode(m)};
}

std::optional<UlogConverted> attitude(const UlogLayout& l, std::span<const uint8_t> p, uint64_t timestamp,
                                      int64_t seq) {
  if (!has(l, "q", 4)) return std::nullopt;
  pose_t m;
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  m.header.frame_id = "local_ned";
  m.child_frame_id = "body_frd";
  // The attitude alone: the position is not in the message (vehicle_local_position has it).
  m.position.x = m.position.y = m.position.z = kNaN;
  // PX4's q (w, x, y, z) rotates the body's forward-right-down axes into north-east-down: the body's orientation.
  m.orientation.w = l.number(p, "q", 0);
  m.orientation.x = l.number(p, "q", 1);
  m.orientation.y = l.number(p, "q", 2);
  m.orientation.z = l.number(p, "q", 3);
  for (double& c : m.covariance) c = 0;
  return UlogConverted{"driftlab.pose_t", lcmtypes::encode(m)};
}

}  // namespace

const char* driftlab_type_for_ulog(std::string_view name) {
  if (name == "sensor_combined" || name == "vehicle_imu") return "driftlab.imu_t";
  if (name == "sensor_baro") return "driftlab.barometer_t";
  if (name == "sensor_mag" || name == "vehicle_magnetometer") return "driftlab.magnetometer_t";
  if (name == "sensor_gps" || name == "vehicle_gps_position") return "driftlab.gnss_t";
  if (name == "vehicle_local_position") return "driftlab.odometry_t";
  if (name == "vehicle_attitude") return "driftlab.pose_t";
  return nullptr;
}

std::optional<UlogConverted> convert_ulog_message(const UlogLayout& layout, std::span<const uint8_t> payload,
                                                  uint64_t timestamp, int64_t seq) {
  if (layout.name == "sensor_combined") return imu(layout, payload, timestamp, seq);
  if (layout.name == "vehicle_imu") return vehicle_imu(layout, payload, timestamp, seq);
  if (layout.name == "sensor_baro") return barometer(layout, payload, timestamp, seq);
  if (layout.name == "sensor_mag" || layout.name == "vehicle_magnetometer") {
    return magnetometer(layout, payload, timestamp, seq);
  }
  if (layout.name == "sensor_gps" || layout.name == "vehicle_gps_position") {
    return gnss(layout, payload, timestamp, seq);
  }
  if (layout.name == "vehicle_local_position") return local_position(layout, payload, timestamp, seq);
  if (layout.name == "vehicle_attitude") return attitude(layout, payload, timestamp, seq);
  return std::nullopt;
}

}  // namespace driftlab::formats
