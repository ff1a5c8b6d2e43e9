#include "formats/ulog_messages.h"

#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "driftlab/barometer_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/motor_command_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/timesync_status_t.hpp"
#include "driftlab/trajectory_setpoint_t.hpp"
#include "driftlab/vehicle_status_t.hpp"
#include "lcmtypes/encode.h"

namespace driftlab::formats {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A format's fields, each looked up by name once: at its first use, in the layout's index; after, by the address
/// of its name. Every name given is a string literal of this file (a name's address stands for its text).
class Fields {
 public:
  explicit Fields(const UlogLayout& l) : l_(l) {}
  const UlogLayout& layout() const { return l_; }
  const UlogLayout::Field* find(const char* name) const {
    for (const auto& [n, f] : memo_)
      if (n == name) return f;
    const UlogLayout::Field* f = l_.find(name);
    memo_.emplace_back(name, f);
    return f;
  }
  double number(std::span<const uint8_t> p, const char* name, uint32_t i = 0) const {
    return l_.number(p, find(name), i);
  }
  std::optional<uint64_t> u64(std::span<const uint8_t> p, const char* name) const { return l_.u64(p, find(name)); }

 private:
  const UlogLayout& l_;
  mutable std::vector<std::pair<const char*, const UlogLayout::Field*>> memo_;
};

/// m encoded into *out: its type's name.
template <typename T>
const char* put(const T& m, const char* type, std::vector<uint8_t>* out) {
  lcmtypes::encode_into(m, out);
  return type;
}

/// header.utime: when the sensor sampled (timestamp_sample) where the message says, else its timestamp.
int64_t sample_time(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp) {
  return ulog_utime(l.u64(p, "timestamp_sample").value_or(timestamp));
}

bool has(const Fields& l, const char* name, uint32_t count = 0) {
  const UlogLayout::Field* f = l.find(name);
  return f && f->count == count && f->type != UlogType::kChar;
}

/// An imu_t of a PX4 IMU topic: no orientation (PX4's IMU topics carry none), stamped when sampled, in PX4's body
/// frame (forward, right, down); the caller sets its rates and accelerations.
imu_t bare_imu(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq) {
  imu_t m{};
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

const char* imu(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                std::vector<uint8_t>* out) {
  if (!has(l, "gyro_rad", 3) || !has(l, "accelerometer_m_s2", 3)) return nullptr;
  // sensor_combined's timestamp is its gyro sample's time (the accelerometer's is timestamp +
  // accelerometer_timestamp_relative); it has no timestamp_sample.
  imu_t m = bare_imu(l, p, timestamp, seq);
  m.angular_velocity.x = l.number(p, "gyro_rad", 0);
  m.angular_velocity.y = l.number(p, "gyro_rad", 1);
  m.angular_velocity.z = l.number(p, "gyro_rad", 2);
  m.linear_acceleration.x = l.number(p, "accelerometer_m_s2", 0);
  m.linear_acceleration.y = l.number(p, "accelerometer_m_s2", 1);
  m.linear_acceleration.z = l.number(p, "accelerometer_m_s2", 2);
  return put(m, "driftlab.imu_t", out);
}

/// vehicle_imu (PX4 1.11 and later): one IMU's integrated rotation and velocity change over its interval; the mean
/// rate and specific force over the interval are the changes over their dt (NaN, not measured, for a dt of 0).
const char* vehicle_imu(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                        std::vector<uint8_t>* out) {
  if (!has(l, "delta_angle", 3) || !has(l, "delta_velocity", 3) || !has(l, "delta_angle_dt") ||
      !has(l, "delta_velocity_dt")) {
    return nullptr;
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
  return put(m, "driftlab.imu_t", out);
}

/// sensor_baro: static pressure and temperature. PX4 1.12 and earlier log millibar, later Pascal: a pressure under
/// 2000 is millibar (2000 Pa is the air 27 km up; 2000 mbar no air a vehicle meets).
const char* barometer(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                      std::vector<uint8_t>* out) {
  if (!has(l, "pressure")) return nullptr;
  barometer_t m{};
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  m.header.frame_id = "baro";
  const double pressure = l.number(p, "pressure");
  m.pressure_pa = std::abs(pressure) < 2000 ? pressure * 100 : pressure;
  m.temperature_c = has(l, "temperature") ? l.number(p, "temperature") : kNaN;
  m.pressure_variance = 0;  // not given
  return put(m, "driftlab.barometer_t", out);
}

/// sensor_mag (the sensor's frame: x, y, z) and vehicle_magnetometer (the body frame: magnetometer_ga), in gauss:
/// tesla are 1e-4 of them.
const char* magnetometer(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                         std::vector<uint8_t>* out) {
  magnetometer_t m{};
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
    return nullptr;
  }
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  for (double& c : m.magnetic_field_covariance) c = 0;  // not given
  return put(m, "driftlab.magnetometer_t", out);
}

const char* gnss(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                 std::vector<uint8_t>* out) {
  gnss_t m{};
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
    return nullptr;
  }
  if (!has(l, "fix_type")) return nullptr;
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
  return put(m, "driftlab.gnss_t", out);
}

const char* local_position(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                           std::vector<uint8_t>* out) {
  const char* heading = has(l, "heading") ? "heading" : has(l, "yaw") ? "yaw" : nullptr;  // "yaw" before PX4 1.10
  for (const char* f : {"x", "y", "z", "vx", "vy", "vz"})
    if (!has(l, f)) return nullptr;
  if (!heading) return nullptr;
  odometry_t m{};
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
  return put(m, "driftlab.odometry_t", out);
}

const char* attitude(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                     std::vector<uint8_t>* out) {
  if (!has(l, "q", 4)) return nullptr;
  pose_t m{};
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
  return put(m, "driftlab.pose_t", out);
}

/// Three values of a vector PX4 logs either as one array (PX4 1.14 and later: `position[3]`) or as three fields
/// (earlier: `x`, `y`, `z`); nullopt when the format has neither.
std::optional<std::array<double, 3>> vector3(const Fields& l, std::span<const uint8_t> p, const char* array,
                                             const std::array<const char*, 3>& fields) {
  if (has(l, array, 3))
    return std::array<double, 3>{l.number(p, array, 0), l.number(p, array, 1), l.number(p, array, 2)};
  for (const char* f : fields)
    if (!has(l, f)) return std::nullopt;
  return std::array<double, 3>{l.number(p, fields[0]), l.number(p, fields[1]), l.number(p, fields[2])};
}

/// v, given in the frame the unit quaternion q (w, x, y, z) rotates the body into, expressed in the body: q^-1 v q.
std::array<double, 3> into_body(const std::array<double, 4>& q, const std::array<double, 3>& v) {
  const double w = q[0], x = -q[1], y = -q[2], z = -q[3];  // the conjugate rotates the other way
  // v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)
  const double cx = y * v[2] - z * v[1], cy = z * v[0] - x * v[2], cz = x * v[1] - y * v[0];
  return {v[0] + 2 * (w * cx + y * cz - z * cy), v[1] + 2 * (w * cy + z * cx - x * cz),
          v[2] + 2 * (w * cz + x * cy - y * cx)};
}

/// vehicle_odometry: the pose of the body (forward-right-down) in a local frame and its velocities. PX4 1.14 and
/// later: `position[3]`, `q[4]`, `velocity[3]`, `angular_velocity[3]`, `pose_frame` (1 NED, 2 FRD: a local frame
/// whose x is the vehicle's heading at start), `velocity_frame` (1 NED, 2 FRD, 3 the body's FRD), the variances'
/// diagonals; before: `x`, `y`, `z`, `vx`, `vy`, `vz`, `rollspeed`, `pitchspeed`, `yawspeed`, `local_frame` (0 NED,
/// 1 FRD), `velocity_frame` (0 NED, 1 FRD, 3 body; PX4 1.12 and later), the upper triangles of the covariances.
const char* odometry(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                     std::vector<uint8_t>* out) {
  const auto position = vector3(l, p, "position", {"x", "y", "z"});
  const auto velocity = vector3(l, p, "velocity", {"vx", "vy", "vz"});
  const auto rates = vector3(l, p, "angular_velocity", {"rollspeed", "pitchspeed", "yawspeed"});
  if (!position || !velocity || !rates || !has(l, "q", 4)) return nullptr;
  const bool v1_14 = has(l, "pose_frame");
  if (!v1_14 && !has(l, "local_frame")) return nullptr;
  const double pose_frame = l.number(p, v1_14 ? "pose_frame" : "local_frame");
  odometry_t m{};
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  // Which local frame: north-east-down, or forward-right-down (x along the heading PX4 started with).
  const double frd = v1_14 ? 2 : 1;
  m.header.frame_id = pose_frame == frd ? "local_frd" : "local_ned";
  m.child_frame_id = "body_frd";
  m.position.x = (*position)[0];
  m.position.y = (*position)[1];
  m.position.z = (*position)[2];
  const std::array<double, 4> q{l.number(p, "q", 0), l.number(p, "q", 1), l.number(p, "q", 2), l.number(p, "q", 3)};
  m.orientation.w = q[0];
  m.orientation.x = q[1];
  m.orientation.y = q[2];
  m.orientation.z = q[3];
  // The velocity into the body's frame, as odometry_t holds it: as it is when PX4 gives it there, turned by the
  // attitude when given in the local frame; NaN (not known) when the frame is not said (PX4 before 1.12) or is
  // another PX4 does not define.
  const double body_frame = 3;
  const double velocity_frame = has(l, "velocity_frame") ? l.number(p, "velocity_frame") : kNaN;
  const bool local = v1_14 ? velocity_frame == 1 || velocity_frame == 2 : velocity_frame == 0 || velocity_frame == 1;
  std::array<double, 3> v{kNaN, kNaN, kNaN};
  if (velocity_frame == body_frame) {
    v = *velocity;
  } else if (local) {
    v = into_body(q, *velocity);
  }
  m.linear_velocity.x = v[0];
  m.linear_velocity.y = v[1];
  m.linear_velocity.z = v[2];
  m.angular_velocity.x = (*rates)[0];  // PX4: about the body's axes
  m.angular_velocity.y = (*rates)[1];
  m.angular_velocity.z = (*rates)[2];
  for (int i = 0; i < 36; ++i) m.pose_covariance[i] = m.twist_covariance[i] = 0;
  auto finite_or_0 = [](double x) { return std::isfinite(x) ? x : 0.0; };  // 0: not given, as elsewhere
  if (has(l, "position_variance", 3)) {
    for (uint32_t i = 0; i < 3; ++i) {
      const size_t d = size_t{7} * i;  // (i, i) of the 6x6
      m.pose_covariance[d] = finite_or_0(l.number(p, "position_variance", i));
      m.pose_covariance[d + 21] = finite_or_0(l.number(p, "orientation_variance", i));  // (i + 3, i + 3)
      m.twist_covariance[d] = finite_or_0(l.number(p, "velocity_variance", i));
    }
  } else {
    // The upper triangle of a 6x6, row by row (21 values), into the full matrix.
    for (const char* name : {"pose_covariance", "velocity_covariance"}) {
      if (!has(l, name, 21)) continue;
      double* out = std::string_view(name) == "pose_covariance" ? m.pose_covariance : m.twist_covariance;
      uint32_t k = 0;
      for (int r = 0; r < 6; ++r) {
        for (int c = r; c < 6; ++c, ++k) out[6 * r + c] = out[6 * c + r] = finite_or_0(l.number(p, name, k));
      }
    }
  }
  return put(m, "driftlab.odometry_t", out);
}

/// actuator_motors (PX4 1.13 and later): each motor's thrust setpoint, normalised, NaN for a motor stopped (all of
/// them when disarmed) or not configured (those after the vehicle's last motor). actuator_outputs is not mapped: its
/// values are in the output driver's units (PWM microseconds, DShot steps), not thrust.
const char* motors(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                   std::vector<uint8_t>* out) {
  const UlogLayout::Field* f = l.find("control");
  if (!f || f->count == 0 || f->type != UlogType::kFloat) return nullptr;
  motor_command_t m{};
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  m.header.frame_id = "base_link";
  std::vector<double> control(f->count);
  int32_t n = 0;  // up to the last motor with a setpoint
  for (uint32_t i = 0; i < f->count; ++i) {
    control[i] = l.number(p, "control", i);
    if (std::isfinite(control[i])) n = static_cast<int32_t>(i) + 1;
  }
  m.armed = n > 0;
  m.nmotors = n;
  // A motor stopped among running ones (NaN) commands no thrust.
  for (int32_t i = 0; i < n; ++i) m.control.push_back(std::isfinite(control[i]) ? control[i] : 0.0);
  return put(m, "driftlab.motor_command_t", out);
}

/// trajectory_setpoint and vehicle_local_position_setpoint: where the vehicle should be in PX4's local frame
/// (north-east-down), how fast and how it should be accelerating, and its heading (about down, from north); NaN
/// where PX4 leaves a part unset. PX4 1.14 and later: `position[3]`, `velocity[3]`, `acceleration[3]`; before: `x`,
/// `y`, `z`, `vx`, `vy`, `vz`, and `acceleration[3]` or (PX4 1.9) `acc_x`, `acc_y`, `acc_z`.
const char* setpoint(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                     std::vector<uint8_t>* out) {
  const auto position = vector3(l, p, "position", {"x", "y", "z"});
  const auto velocity = vector3(l, p, "velocity", {"vx", "vy", "vz"});
  const auto acceleration = vector3(l, p, "acceleration", {"acc_x", "acc_y", "acc_z"});
  if (!position || !velocity || !acceleration || !has(l, "yaw")) return nullptr;
  trajectory_setpoint_t m{};
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  m.header.frame_id = "local_ned";
  auto set = [](vector3_t& to, const std::array<double, 3>& v) {
    to.x = v[0];
    to.y = v[1];
    to.z = v[2];
  };
  set(m.position, *position);
  set(m.velocity, *velocity);
  set(m.acceleration, *acceleration);
  m.yaw = l.number(p, "yaw");
  return put(m, "driftlab.trajectory_setpoint_t", out);
}

/// PX4's nav_state as a mode's name (vehicle_status.msg: the values have kept their meaning across versions).
const char* nav_state_name(double s) {
  static constexpr const char* kNames[] = {"manual",
                                           "altitude",
                                           "position",
                                           "mission",
                                           "hold",
                                           "return",
                                           "position_slow",
                                           "",
                                           "",
                                           "",
                                           "acro",
                                           "",
                                           "descend",
                                           "termination",
                                           "offboard",
                                           "stabilized",
                                           "",
                                           "takeoff",
                                           "land",
                                           "follow_target",
                                           "precision_land",
                                           "orbit",
                                           "vtol_takeoff"};
  if (!(s >= 0 && s < static_cast<double>(std::size(kNames)))) return "unknown";
  const char* n = kNames[static_cast<size_t>(s)];
  return *n ? n : "unknown";
}

/// vehicle_status: armed (arming_state 2, ARMED, in every version), the navigation state's name as the mode, and why
/// the vehicle was last armed or disarmed where PX4 says (latest_arming_reason, latest_disarming_reason: the number).
/// vehicle_status carries no land detector's verdict (vehicle_land_detected does): `landed` is what PX4's land
/// detector holds of a disarmed vehicle (landed) and false when armed; no offboard losses or setpoint age (-1).
const char* status(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                   std::vector<uint8_t>* out) {
  if (!has(l, "arming_state") || !has(l, "nav_state")) return nullptr;
  vehicle_status_t m{};
  m.header.seq = seq;
  m.header.utime = sample_time(l, p, timestamp);
  m.header.frame_id = "base_link";
  m.armed = l.number(p, "arming_state") == 2;
  m.landed = !m.armed;
  m.mode = nav_state_name(l.number(p, "nav_state"));
  const char* reason = m.armed ? "latest_arming_reason" : "latest_disarming_reason";
  const double r = has(l, reason) ? l.number(p, reason) : kNaN;
  m.reason = std::isfinite(r)
                 ? std::string(m.armed ? "armed" : "disarmed") + " by reason " + std::to_string(static_cast<int64_t>(r))
                 : "";
  m.offboard_losses = 0;
  m.setpoint_age_s = -1;  // none known
  return put(m, "driftlab.vehicle_status_t", out);
}

/// timesync_status (PX4 1.13 and later; `timesync` before): the flight controller's estimate of a companion's clock
/// against its own, from one exchange: `remote_timestamp`, `observed_offset` and `estimated_offset` (remote - local
/// [us]), `round_trip_time` [us]. Stamped with its timestamp, the flight controller's clock (the local side).
const char* timesync(const Fields& l, std::span<const uint8_t> p, uint64_t timestamp, int64_t seq,
                     std::vector<uint8_t>* out) {
  for (const char* f : {"remote_timestamp", "observed_offset", "estimated_offset", "round_trip_time"})
    if (!has(l, f)) return nullptr;
  timesync_status_t m{};
  m.header.seq = seq;
  m.header.utime = ulog_utime(timestamp);
  m.header.frame_id = "";
  m.remote_utime = ulog_utime(l.u64(p, "remote_timestamp").value_or(0));
  m.observed_offset_s = l.number(p, "observed_offset") * 1e-6;
  m.estimated_offset_s = l.number(p, "estimated_offset") * 1e-6;
  m.round_trip_s = l.number(p, "round_trip_time") * 1e-6;
  return put(m, "driftlab.timesync_status_t", out);
}

/// Each mapped topic: its driftlab type and mapping.
using Mapping = const char* (*)(const Fields&, std::span<const uint8_t>, uint64_t, int64_t, std::vector<uint8_t>*);
struct Mapped {
  std::string_view topic;
  const char* type;
  Mapping mapping;
};
constexpr Mapped kMapped[] = {
    {"sensor_combined", "driftlab.imu_t", imu},
    {"vehicle_imu", "driftlab.imu_t", vehicle_imu},
    {"sensor_baro", "driftlab.barometer_t", barometer},
    {"sensor_mag", "driftlab.magnetometer_t", magnetometer},
    {"vehicle_magnetometer", "driftlab.magnetometer_t", magnetometer},
    {"sensor_gps", "driftlab.gnss_t", gnss},
    {"vehicle_gps_position", "driftlab.gnss_t", gnss},
    {"vehicle_local_position", "driftlab.odometry_t", local_position},
    {"vehicle_attitude", "driftlab.pose_t", attitude},
    {"vehicle_odometry", "driftlab.odometry_t", odometry},
    {"actuator_motors", "driftlab.motor_command_t", motors},
    {"trajectory_setpoint", "driftlab.trajectory_setpoint_t", setpoint},
    {"vehicle_local_position_setpoint", "driftlab.trajectory_setpoint_t", setpoint},
    {"vehicle_status", "driftlab.vehicle_status_t", status},
    {"timesync_status", "driftlab.timesync_status_t", timesync},
    {"timesync", "driftlab.timesync_status_t", timesync},
};

const Mapped* mapped(std::string_view topic) {
  for (const Mapped& m : kMapped)
    if (m.topic == topic) return &m;
  return nullptr;
}

bool is_gnss(std::string_view topic) { return topic == "sensor_gps" || topic == "vehicle_gps_position"; }

std::optional<UlogUtcTie> gnss_utc(const Fields& l, std::span<const uint8_t> payload, uint64_t timestamp) {
  const auto utc = l.u64(payload, "time_utc_usec");
  if (!utc || *utc == 0 || *utc > static_cast<uint64_t>(INT64_MAX) || !has(l, "fix_type")) return std::nullopt;
  if (!(l.number(payload, "fix_type") >= 3)) return std::nullopt;
  double relative = has(l, "timestamp_time_relative") ? l.number(payload, "timestamp_time_relative") : 0;
  if (!std::isfinite(relative)) relative = 0;
  const int64_t boot = ulog_utime(timestamp);
  // timestamp_time_relative is an int32_t [us]: the sum stays in int64_t for any boot time short of its end.
  if (boot > INT64_MAX / 2) return std::nullopt;
  return UlogUtcTie{boot + static_cast<int64_t>(relative), static_cast<int64_t>(*utc)};
}

}  // namespace

const char* driftlab_type_for_ulog(std::string_view name) {
  const Mapped* m = mapped(name);
  return m ? m->type : nullptr;
}

std::optional<UlogUtcTie> ulog_gnss_utc(const UlogLayout& layout, std::span<const uint8_t> payload,
                                        uint64_t timestamp) {
  if (!is_gnss(layout.name)) return std::nullopt;
  return gnss_utc(Fields(layout), payload, timestamp);
}

std::optional<UlogConverted> convert_ulog_message(const UlogLayout& layout, std::span<const uint8_t> payload,
                                                  uint64_t timestamp, int64_t seq) {
  UlogConverted c;
  const Mapped* m = mapped(layout.name);
  if (!m || !(c.type = m->mapping(Fields(layout), payload, timestamp, seq, &c.lcm))) return std::nullopt;
  return c;
}

struct UlogConverter::Plan {
  std::shared_ptr<const UlogLayout> layout;
  Fields fields;
  Mapping mapping;
  bool gnss;
};

UlogConverter::UlogConverter(std::shared_ptr<const UlogLayout> layout) {
  const UlogLayout& l = *layout;
  const Mapped* m = formats::mapped(l.name);
  plan_ = std::make_unique<Plan>(Plan{std::move(layout), Fields(l), m ? m->mapping : nullptr, is_gnss(l.name)});
}
UlogConverter::UlogConverter(UlogConverter&&) noexcept = default;
UlogConverter& UlogConverter::operator=(UlogConverter&&) noexcept = default;
UlogConverter::~UlogConverter() = default;

bool UlogConverter::mapped() const { return plan_->mapping != nullptr; }

const char* UlogConverter::convert(std::span<const uint8_t> payload, uint64_t timestamp, int64_t seq,
                                   std::vector<uint8_t>* out) const {
  return plan_->mapping ? plan_->mapping(plan_->fields, payload, timestamp, seq, out) : nullptr;
}

std::optional<UlogUtcTie> UlogConverter::gnss_utc(std::span<const uint8_t> payload, uint64_t timestamp) const {
  if (!plan_->gnss) return std::nullopt;
  return formats::gnss_utc(plan_->fields, payload, timestamp);
}

}  // namespace driftlab::formats
