// ROS 1 serialization and CDR (ROS 2) read by one Reader (formats/internal/ros_reader.h), so each message is
// decoded by one function for both.
#include "formats/ros_messages.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#include "core/time.h"
#include "driftlab/barometer_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/image_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/joint_trajectory_state_t.hpp"
#include "driftlab/joint_trajectory_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "driftlab/timesync_status_t.hpp"
#include "driftlab/velocity_command_t.hpp"
#include "formats/internal/ros_reader.h"
#include "lcmtypes/encode.h"

namespace driftlab::formats {
namespace {

using internal::Reader;
using lcmtypes::encode;

/// A string for a driftlab message: up to its first NUL, as LCM encodes strings (a NUL inside would make the
/// encoded message longer than its fields).
std::string lcm_string(Reader& r) {
  std::string s = r.str();
  if (const size_t nul = s.find('\0'); nul != std::string::npos) s.resize(nul);
  return s;
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// std_msgs/Header: ROS 1 has a seq first; ROS 2 has none.
void header(Reader& r, Serialization s, header_t& h, bool* has_seq) {
  if (s == Serialization::kRos1) {
    h.seq = r.get<uint32_t>();
    *has_seq = true;
  } else {
    h.seq = r.fallback_seq;
  }
  h.utime = r.time_us();
  h.frame_id = lcm_string(r);
}

void vector3(Reader& r, vector3_t& v) {
  v.x = r.get<double>();
  v.y = r.get<double>();
  v.z = r.get<double>();
}
void quaternion(Reader& r, quaternion_t& q) {  // ROS order: x, y, z, w
  q.x = r.get<double>();
  q.y = r.get<double>();
  q.z = r.get<double>();
  q.w = r.get<double>();
}

struct Decoded {
  std::vector<uint8_t> bytes;
  int64_t stamp = 0;
};

using Convert = std::vector<uint8_t> (*)(Reader&, Serialization, int64_t unstamped, int64_t* stamp, bool* has_seq);

std::vector<uint8_t> laser_scan(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  laser_scan_t m{};
  header(r, s, m.header, has_seq);
  m.angle_min = r.get<float>();
  m.angle_max = r.get<float>();
  m.angle_increment = r.get<float>();
  m.time_increment = r.get<float>();
  m.scan_time = r.get<float>();
  m.range_min = r.get<float>();
  m.range_max = r.get<float>();
  m.nranges = static_cast<int32_t>(r.count(4));
  m.ranges.resize(static_cast<size_t>(m.nranges));
  r.get(m.ranges.data(), m.ranges.size());
  m.nintensities = static_cast<int32_t>(r.count(4));
  m.intensities.resize(static_cast<size_t>(m.nintensities));
  r.get(m.intensities.data(), m.intensities.size());
  *stamp = m.header.utime;
  return encode(m);
}

std::vector<uint8_t> imu(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  imu_t m{};
  header(r, s, m.header, has_seq);
  quaternion(r, m.orientation);
  r.get(m.orientation_covariance, 9);
  vector3(r, m.angular_velocity);
  r.get(m.angular_velocity_covariance, 9);
  vector3(r, m.linear_acceleration);
  r.get(m.linear_acceleration_covariance, 9);
  *stamp = m.header.utime;
  return encode(m);
}

std::vector<uint8_t> odometry(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  odometry_t m{};
  header(r, s, m.header, has_seq);
  m.child_frame_id = lcm_string(r);
  vector3(r, m.position);
  quaternion(r, m.orientation);
  r.get(m.pose_covariance, 36);
  vector3(r, m.linear_velocity);
  vector3(r, m.angular_velocity);
  r.get(m.twist_covariance, 36);
  *stamp = m.header.utime;
  return encode(m);
}

pose_t stamped_pose(Reader& r, Serialization s, bool* has_seq) {
  pose_t m{};
  header(r, s, m.header, has_seq);
  vector3(r, m.position);
  quaternion(r, m.orientation);
  return m;
}

std::vector<uint8_t> pose_stamped(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  pose_t m = stamped_pose(r, s, has_seq);
  *stamp = m.header.utime;
  return encode(m);
}

std::vector<uint8_t> pose_with_covariance(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  pose_t m = stamped_pose(r, s, has_seq);
  r.get(m.covariance, 36);
  *stamp = m.header.utime;
  return encode(m);
}

void transform_stamped(Reader& r, Serialization s, transform_t& t, bool* has_seq) {
  header(r, s, t.header, has_seq);
  t.child_frame_id = lcm_string(r);
  vector3(r, t.translation);
  quaternion(r, t.rotation);
}

std::vector<uint8_t> transform(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  tf_t m{};
  m.ntransforms = 1;
  m.transforms.resize(1);
  transform_stamped(r, s, m.transforms[0], has_seq);
  m.header = m.transforms[0].header;
  *stamp = m.header.utime;
  return encode(m);
}

/// tf2_msgs/TFMessage: a batch without a header of its own; the batch is stamped with its newest transform
/// (what a TF listener sees as the batch's time) and numbered by the caller, as no sequence travels with it.
std::vector<uint8_t> tf_message(Reader& r, Serialization s, int64_t unstamped, int64_t* stamp, bool*) {
  tf_t m{};
  // Each transform: at least a header (ROS 1: 12 bytes + frame), a child frame and 7 doubles.
  m.ntransforms = static_cast<int32_t>(r.count(64));
  m.transforms.resize(static_cast<size_t>(m.ntransforms));
  bool transform_seq = false;
  int64_t newest = std::numeric_limits<int64_t>::min();
  for (auto& t : m.transforms) {
    transform_stamped(r, s, t, &transform_seq);
    newest = std::max(newest, t.header.utime);
  }
  m.header.seq = r.fallback_seq;
  m.header.utime = m.transforms.empty() ? unstamped : newest;
  m.header.frame_id = m.transforms.empty() ? "" : m.transforms[0].header.frame_id;
  *stamp = m.header.utime;
  return encode(m);
}

std::vector<uint8_t> twist_stamped(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  velocity_command_t m{};
  header(r, s, m.header, has_seq);
  vector3(r, m.linear);
  vector3(r, m.angular);
  *stamp = m.header.utime;
  return encode(m);
}

/// geometry_msgs/Twist carries no stamp: header.utime is its arrival, so its latency reads as zero.
std::vector<uint8_t> twist(Reader& r, Serialization, int64_t unstamped, int64_t* stamp, bool*) {
  velocity_command_t m{};
  m.header.seq = r.fallback_seq;
  m.header.utime = unstamped;
  vector3(r, m.linear);
  vector3(r, m.angular);
  *stamp = m.header.utime;
  return encode(m);
}

std::vector<uint8_t> joint_state(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  joint_state_t m{};
  header(r, s, m.header, has_seq);
  const uint32_t n = r.count(4);
  m.name.resize(n);
  for (auto& name : m.name) name = lcm_string(r);
  // position, velocity and effort may each be empty (not measured): NaN then, as driftlab's arrays are njoints.
  auto values = [&](std::vector<double>& out, const char* what) {
    const uint32_t k = r.count(8);
    out.assign(n, kNaN);
    if (k != 0 && k != n) r.fail(std::string(what) + " has " + std::to_string(k) + " values for " +
                                 std::to_string(n) + " joints");
    for (uint32_t i = 0; i < k && r.ok(); ++i) out[i] = r.get<double>();
  };
  values(m.position, "position");
  values(m.velocity, "velocity");
  values(m.effort, "effort");
  m.njoints = static_cast<int32_t>(n);
  *stamp = m.header.utime;
  return encode(m);
}

/// trajectory_msgs/JointTrajectoryPoint for n joints: positions and velocities (accelerations and efforts read past:
/// driftlab's points hold neither) and the time from the start (a duration: ROS 1 int32 nsec, ROS 2 uint32 nanosec;
/// both read as the sign-agnostic sum). Positions may be empty where `positions_may_be_empty` (a controller state's
/// error or output of a velocity-controlled joint), velocities always.
void trajectory_point(Reader& r, uint32_t n, const std::string& which, bool positions_may_be_empty,
                      joint_trajectory_point_t& p) {
  auto values = [&](std::vector<double>* out, const char* what, bool may_be_empty) {
    const uint32_t k = r.count(8);
    if (!(k == n || (may_be_empty && k == 0))) {
      r.fail(which + " has " + std::to_string(k) + " " + what + " for " + std::to_string(n) + " joints");
    }
    for (uint32_t j = 0; j < k && r.ok(); ++j) {
      const double v = r.get<double>();
      if (out != nullptr) out->push_back(v);
    }
  };
  values(&p.positions, "positions", positions_may_be_empty);
  values(&p.velocities, "velocities", true);
  values(nullptr, "accelerations", true);
  values(nullptr, "efforts", true);
  const int64_t sec = r.get<int32_t>();
  const int64_t nsec = r.get<uint32_t>();
  p.time_from_start_us = sec * 1'000'000 + nsec / 1000;
  p.npositions = static_cast<int32_t>(p.positions.size());
  p.nvelocities = static_cast<int32_t>(p.velocities.size());
}

/// trajectory_msgs/JointTrajectory after its header: the joints, then each point.
void trajectory_body(Reader& r, joint_trajectory_t& m) {
  const uint32_t n = r.count(4);
  m.joint_names.resize(n);
  for (auto& name : m.joint_names) name = lcm_string(r);
  m.njoints = static_cast<int32_t>(n);
  const uint32_t points = r.count(4 * 4 + 8);  // four empty sequences and a duration
  m.points.resize(points);
  for (uint32_t i = 0; i < points && r.ok(); ++i) {
    trajectory_point(r, n, "point " + std::to_string(i), false, m.points[i]);
  }
  m.npoints = static_cast<int32_t>(m.points.size());
}

/// trajectory_msgs/JointTrajectory. A zero stamp tells a controller to start the trajectory when it arrives
/// (ROS's joint trajectory controllers): header.utime is then its arrival, as driftlab's joint_trajectory_t says.
std::vector<uint8_t> joint_trajectory(Reader& r, Serialization s, int64_t unstamped, int64_t* stamp, bool* has_seq) {
  joint_trajectory_t m{};
  header(r, s, m.header, has_seq);
  if (m.header.utime == 0) m.header.utime = unstamped;
  trajectory_body(r, m);
  *stamp = m.header.utime;
  return encode(m);
}

/// control_msgs/FollowJointTrajectoryActionGoal (ROS 1 actionlib: how MoveIt hands a plan to a controller): the
/// goal's trajectory, stamped as sent (the action header's stamp) where the trajectory's own is zero; its
/// tolerances read past.
std::vector<uint8_t> follow_joint_trajectory_goal(Reader& r, Serialization s, int64_t unstamped, int64_t* stamp,
                                                  bool* has_seq) {
  joint_trajectory_t m{};
  header(r, s, m.header, has_seq);
  const header_t action = m.header;
  r.time_us();  // goal_id.stamp
  r.str();      // goal_id.id
  bool inner_seq = false;
  header(r, s, m.header, &inner_seq);
  if (m.header.utime == 0) m.header.utime = action.utime != 0 ? action.utime : unstamped;
  m.header.seq = action.seq;
  trajectory_body(r, m);
  for (int list = 0; list < 2 && r.ok(); ++list) {  // path_tolerance, goal_tolerance: JointTolerance[]
    const uint32_t k = r.count(4 + 3 * 8);
    for (uint32_t i = 0; i < k && r.ok(); ++i) {
      r.str();
      for (int v = 0; v < 3; ++v) r.get<double>();
    }
  }
  r.get<int32_t>();  // goal_time_tolerance
  r.get<int32_t>();
  *stamp = m.header.utime;
  return encode(m);
}

/// control_msgs/JointTrajectoryControllerState, what a joint trajectory controller publishes on controller_state.
/// Three layouts share their first three points: ROS 1 and ROS 2 before Humble (desired, actual, error), Humble
/// (reference, feedback, error, output, then desired and actual again and the multi-DOF points) and Jazzy on
/// (reference, feedback, error, output, then the multi-DOF points). The reference (desired) and feedback (actual)
/// are read; the output's velocities, where the message has an output, are the commands. What follows the output
/// (deprecated copies, the multi-DOF points of a mobile base) is read past. `following` is 1 while the desired
/// velocity of a joint is not zero: ROS's message does not say whether a trajectory is active, and a controller
/// holding its position desires no velocity.
std::vector<uint8_t> joint_trajectory_controller_state(Reader& r, Serialization s, int64_t, int64_t* stamp,
                                                       bool* has_seq) {
  joint_trajectory_state_t m{};
  header(r, s, m.header, has_seq);
  const uint32_t n = r.count(4);
  m.joint_names.resize(n);
  for (auto& name : m.joint_names) name = lcm_string(r);
  m.njoints = static_cast<int32_t>(n);
  joint_trajectory_point_t desired, actual, error, output;
  trajectory_point(r, n, "the reference", false, desired);
  trajectory_point(r, n, "the feedback", false, actual);
  trajectory_point(r, n, "the error", true, error);
  const bool has_output = r.ok() && !r.at_end();
  if (has_output) trajectory_point(r, n, "the output", true, output);
  if (!r.ok()) return {};
  if (!r.at_end()) r.bytes(r.remaining());
  auto velocities = [n](std::vector<double>& v) {
    if (v.size() != n) v.assign(n, kNaN);
    return std::move(v);
  };
  m.desired_positions = std::move(desired.positions);
  m.desired_velocities = velocities(desired.velocities);
  m.actual_positions = std::move(actual.positions);
  m.actual_velocities = velocities(actual.velocities);
  m.commands = velocities(output.velocities);
  m.following = std::any_of(m.desired_velocities.begin(), m.desired_velocities.end(),
                            [](double v) { return std::isfinite(v) && v != 0; })
                    ? 1
                    : 0;
  *stamp = m.header.utime;
  return encode(m);
}

/// mavros_msgs/TimesyncStatus: MAVROS's estimate of the flight controller's clock against the companion's.
std::vector<uint8_t> timesync_status(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  timesync_status_t m{};
  header(r, s, m.header, has_seq);
  m.remote_utime = static_cast<int64_t>(r.get<uint64_t>() / 1000);
  m.observed_offset_s = static_cast<double>(r.get<int64_t>()) * 1e-9;
  m.estimated_offset_s = static_cast<double>(r.get<int64_t>()) * 1e-9;
  m.round_trip_s = static_cast<double>(r.get<float>()) * 1e-3;
  *stamp = m.header.utime;
  return encode(m);
}

/// sensor_msgs/Image: rows copied without their padding (driftlab images have none). Encodings other than
/// mono8/rgb8/bgr8 keep ROS's name.
std::vector<uint8_t> image(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  image_t m{};
  header(r, s, m.header, has_seq);
  const uint32_t height = r.get<uint32_t>();
  const uint32_t width = r.get<uint32_t>();
  m.encoding = lcm_string(r);
  r.get<uint8_t>();  // is_bigendian
  const uint32_t step = r.get<uint32_t>();
  const uint32_t n = r.count(1);
  auto data = r.bytes(n);
  if (!r.ok()) return {};
  if (height != 0 && (step == 0 || uint64_t{step} * height > n)) {
    r.fail("image data of " + std::to_string(n) + " bytes for " + std::to_string(height) + " rows of " +
           std::to_string(step));
    return {};
  }
  // Bytes per pixel of the encodings robots use; for others the rows are kept with their step.
  static constexpr std::pair<std::string_view, uint32_t> kBpp[] = {
      {"mono8", 1}, {"8UC1", 1}, {"bayer_rggb8", 1}, {"bayer_bggr8", 1}, {"bayer_gbrg8", 1}, {"bayer_grbg8", 1},
      {"mono16", 2}, {"16UC1", 2}, {"rgb8", 3}, {"bgr8", 3}, {"8UC3", 3}, {"rgba8", 4}, {"bgra8", 4},
      {"32FC1", 4}};
  uint64_t row = step;
  for (const auto& [name, bpp] : kBpp)
    if (m.encoding == name && uint64_t{width} * bpp <= step) row = uint64_t{width} * bpp;
  m.width = static_cast<int32_t>(width);
  m.height = static_cast<int32_t>(height);
  m.data.reserve(row * height);
  for (uint64_t y = 0; y < height; ++y) {
    m.data.insert(m.data.end(), data.begin() + static_cast<ptrdiff_t>(y * step),
                  data.begin() + static_cast<ptrdiff_t>(y * step + row));
  }
  m.size = static_cast<int32_t>(m.data.size());
  *stamp = m.header.utime;
  return encode(m);
}

/// Width and height from a PNG's IHDR or a JPEG's start-of-frame marker; 0 when neither is found.
void image_size(std::span<const uint8_t> d, int32_t* w, int32_t* h) {
  auto be16 = [&](size_t i) { return (d[i] << 8) | d[i + 1]; };
  if (d.size() >= 24 && d[0] == 0x89 && d[1] == 'P' && d[2] == 'N' && d[3] == 'G') {
    *w = (be16(16) << 16) | be16(18);
    *h = (be16(20) << 16) | be16(22);
    return;
  }
  for (size_t i = 2; i + 9 < d.size();) {
    if (d[i] != 0xFF) return;
    const uint8_t marker = d[i + 1];
    if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC) {
      *h = be16(i + 5);
      *w = be16(i + 7);
      return;
    }
    i += 2 + static_cast<size_t>(be16(i + 2));
  }
}

std::vector<uint8_t> compressed_image(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  image_t m{};
  header(r, s, m.header, has_seq);
  const std::string format = lcm_string(r);
  auto data = r.bytes(r.count(1));
  if (!r.ok()) return {};
  m.data.assign(data.begin(), data.end());
  m.size = static_cast<int32_t>(m.data.size());
  const bool png = data.size() >= 4 && data[0] == 0x89 && data[1] == 'P';
  const bool jpeg = data.size() >= 2 && data[0] == 0xFF && data[1] == 0xD8;
  m.encoding = png ? "png" : jpeg ? "jpeg" : format;
  m.width = m.height = 0;
  image_size(data, &m.width, &m.height);
  *stamp = m.header.utime;
  return encode(m);
}

/// sensor_msgs/PointCloud2: x, y, z (float32 or float64), intensity, and per-point time when the driver gives
/// it: `time` (float32 seconds after the stamp, Velodyne), `t` (uint32 nanoseconds, Ouster) or `timestamp`
/// (float64 seconds since the epoch, Hesai and Livox).
std::vector<uint8_t> point_cloud2(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  point_cloud_t m{};
  header(r, s, m.header, has_seq);
  const uint32_t height = r.get<uint32_t>();
  const uint32_t width = r.get<uint32_t>();
  struct Field {
    std::string name;
    uint32_t offset = 0;
    uint8_t type = 0;
  };
  std::vector<Field> fields(r.count(9));
  for (auto& f : fields) {
    f.name = lcm_string(r);
    f.offset = r.get<uint32_t>();
    f.type = r.get<uint8_t>();
    r.get<uint32_t>();  // count
  }
  const bool big = r.get<uint8_t>() != 0;
  const uint32_t point_step = r.get<uint32_t>();
  const uint32_t row_step = r.get<uint32_t>();
  auto data = r.bytes(r.count(1));
  r.get<uint8_t>();  // is_dense
  if (!r.ok()) return {};
  const uint64_t npoints = uint64_t{height} * width;
  // point_cloud_t counts in int32_t: a larger height or width would come out negative.
  if (height > INT32_MAX || width > INT32_MAX) {
    r.fail("a point cloud of " + std::to_string(height) + " x " + std::to_string(width) +
           " points: more rows or columns than point_cloud_t's int32 counts hold");
    return {};
  }
  if (npoints != 0 && (uint64_t{row_step} * height > data.size() || uint64_t{point_step} * width > row_step)) {
    r.fail("point data of " + std::to_string(data.size()) + " bytes for " + std::to_string(height) + " x " +
           std::to_string(width) + " points of " + std::to_string(point_step) + " bytes");
    return {};
  }
  // PointField datatypes: 1 int8, 2 uint8, 3 int16, 4 uint16, 5 int32, 6 uint32, 7 float32, 8 float64.
  static constexpr uint8_t kSize[9] = {0, 1, 1, 2, 2, 4, 4, 4, 8};
  auto find = [&](std::string_view name) -> const Field* {
    for (const auto& f : fields)
      if (f.name == name && f.type >= 1 && f.type <= 8 && f.offset + kSize[f.type] <= point_step) return &f;
    return nullptr;
  };
  auto value = [&](const Field& f, const uint8_t* p) -> double {
    uint8_t raw[8];
    std::memcpy(raw, p + f.offset, kSize[f.type]);
    if (big != (std::endian::native == std::endian::big)) std::reverse(raw, raw + kSize[f.type]);
    switch (f.type) {
      case 1: return static_cast<int8_t>(raw[0]);
      case 2: return raw[0];
      case 3: { int16_t v; std::memcpy(&v, raw, 2); return v; }
      case 4: { uint16_t v; std::memcpy(&v, raw, 2); return v; }
      case 5: { int32_t v; std::memcpy(&v, raw, 4); return v; }
      case 6: { uint32_t v; std::memcpy(&v, raw, 4); return v; }
      case 7: { float v; std::memcpy(&v, raw, 4); return v; }
      default: { double v; std::memcpy(&v, raw, 8); return v; }
    }
  };
  const Field* fx = find("x");
  const Field* fy = find("y");
  const Field* fz = find("z");
  if (npoints != 0 && (!fx || !fy || !fz)) {
    r.fail("a point cloud without x, y and z fields");
    return {};
  }
  const Field* fi = find("intensity");
  const Field* ft = find("time");
  const Field* fns = find("t");
  const Field* fabs = find("timestamp");
  // The common layout (every field used a float32 in the machine's byte order, as lidar drivers write): written
  // straight as LCM encodes point_cloud_t (big-endian numbers; x, y, z, then the counted intensities and times)
  // without filling the message's arrays first, in one pass over the points. Filling the arrays and encoding them
  // were most of an import's time on 3D-lidar recordings. The bytes equal lcm-gen's encoding of the same message
  // (tests/formats/ros2_import_test.cc, PointCloudFastPathEncodesAsLcmGen).
  const bool native = big == (std::endian::native == std::endian::big);
  auto f32 = [](const Field* f) { return !f || f->type == 7; };
  // (An empty cloud may lack x, y and z: it takes the general path, which reads no field.)
  if (native && fx && fy && fz && f32(fx) && f32(fy) && f32(fz) && f32(fi) && f32(ft) && !fns && !fabs) {
    auto be32 = [](uint8_t* to, uint32_t v) {
      v = __builtin_bswap32(v);
      std::memcpy(to, &v, 4);
    };
    auto swapped = [](uint8_t* to, const uint8_t* from) {
      uint32_t v;
      std::memcpy(&v, from, 4);
      v = __builtin_bswap32(v);
      std::memcpy(to, &v, 4);
    };
    const size_t n = npoints;  // < 2^30: each point has 4 bytes or more of data
    const size_t ni = fi ? n : 0, nt = ft ? n : 0;
    const int head = m.header._getEncodedSizeNoHash();
    // The caller's buffer when it gives one: the same size as the last cloud's, it is neither allocated nor
    // zero-filled again (both were a tenth of a zstd MCAP import's time on the converting thread).
    std::vector<uint8_t> out = r.reuse ? std::move(*r.reuse) : std::vector<uint8_t>();
    out.resize(8 + static_cast<size_t>(head) + 12 + 4 * (3 * n + ni + nt) + 8);
    uint8_t* o = out.data();
    const uint64_t hash = __builtin_bswap64(static_cast<uint64_t>(point_cloud_t::getHash()));
    std::memcpy(o, &hash, 8);
    m.header._encodeNoHash(o, 8, head);
    o += 8 + head;
    be32(o, height);
    be32(o + 4, width);
    be32(o + 8, static_cast<uint32_t>(n));
    uint8_t* const x = o + 12;
    uint8_t* const y = x + 4 * n;
    uint8_t* const z = y + 4 * n;
    be32(z + 4 * n, static_cast<uint32_t>(ni));
    uint8_t* const in = z + 4 * n + 4;
    be32(in + 4 * ni, static_cast<uint32_t>(nt));
    uint8_t* const t = in + 4 * ni + 4;
    // One loop for each combination of the optional fields, without a test per point.
    auto copy = [&]<bool kIntensity, bool kTime>() {
      const uint32_t ox = fx->offset, oy = fy->offset, oz = fz->offset;
      const uint32_t oi = kIntensity ? fi->offset : 0, ot = kTime ? ft->offset : 0;
      size_t k = 0;
      for (uint32_t row = 0; row < height && n != 0; ++row) {  // an empty cloud's rows are not walked
        const uint8_t* p = data.data() + uint64_t{row} * row_step;
        for (uint32_t col = 0; col < width; ++col, ++k, p += point_step) {
          swapped(x + 4 * k, p + ox);
          swapped(y + 4 * k, p + oy);
          swapped(z + 4 * k, p + oz);
          if constexpr (kIntensity) swapped(in + 4 * k, p + oi);
          if constexpr (kTime) swapped(t + 4 * k, p + ot);
        }
      }
    };
    if (fi && ft) {
      copy.template operator()<true, true>();
    } else if (fi) {
      copy.template operator()<true, false>();
    } else if (ft) {
      copy.template operator()<false, true>();
    } else {
      copy.template operator()<false, false>();
    }
    *stamp = m.header.utime;
    return out;
  }
  m.height = static_cast<int32_t>(height);
  m.width = static_cast<int32_t>(width);
  m.npoints = static_cast<int32_t>(npoints);
  m.x.resize(npoints);
  m.y.resize(npoints);
  m.z.resize(npoints);
  if (fi) m.intensities.resize(npoints);
  if (ft || fns || fabs) m.time_offsets.resize(npoints);
  const double stamp_s = Time::from_us(m.header.utime).seconds();
  size_t i = 0;
  // No row is walked when there are no points: an empty cloud may declare two billion empty rows.
  for (uint32_t row = 0; row < height && npoints != 0; ++row) {
    for (uint32_t col = 0; col < width; ++col, ++i) {
      const uint8_t* p = data.data() + uint64_t{row} * row_step + uint64_t{col} * point_step;
      m.x[i] = static_cast<float>(value(*fx, p));
      m.y[i] = static_cast<float>(value(*fy, p));
      m.z[i] = static_cast<float>(value(*fz, p));
      if (fi) m.intensities[i] = static_cast<float>(value(*fi, p));
      if (ft) m.time_offsets[i] = static_cast<float>(value(*ft, p));
      else if (fns) m.time_offsets[i] = static_cast<float>(value(*fns, p) * 1e-9);
      else if (fabs) m.time_offsets[i] = static_cast<float>(value(*fabs, p) - stamp_s);
    }
  }
  m.nintensities = static_cast<int32_t>(m.intensities.size());
  m.ntimes = static_cast<int32_t>(m.time_offsets.size());
  *stamp = m.header.utime;
  return encode(m);
}

/// sensor_msgs/NavSatFix: what a GNSS driver publishes. The status says whether there is a fix (a fix without an
/// altitude, NaN, is a 2D fix); the ENU covariance becomes the horizontal and vertical standard deviations (eph the
/// root mean square of the east and north ones). NavSatFix says nothing of velocity or satellites: the velocity and
/// its accuracy are NaN (not measured), the satellite count 0 (not given).
std::vector<uint8_t> nav_sat_fix(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  gnss_t m{};
  header(r, s, m.header, has_seq);
  const auto status = r.get<int8_t>();
  r.get<uint16_t>();  // service: which constellations
  m.latitude_deg = r.get<double>();
  m.longitude_deg = r.get<double>();
  m.altitude_m = r.get<double>();
  double covariance[9];
  r.get(covariance, 9);
  const auto covariance_type = r.get<uint8_t>();
  // NavSatStatus: -2 unknown (newer ROS 2), -1 no fix, 0 fix, 1 SBAS-augmented, 2 GBAS-augmented.
  m.fix_type = status < 0 ? 0 : std::isnan(m.altitude_m) ? 2 : 3;
  m.satellites = 0;
  // COVARIANCE_TYPE_UNKNOWN (0): no accuracy given, which gnss_t says with 0.
  m.eph_m = covariance_type == 0 ? 0 : std::sqrt((covariance[0] + covariance[4]) / 2);
  m.epv_m = covariance_type == 0 ? 0 : std::sqrt(covariance[8]);
  m.velocity = {kNaN, kNaN, kNaN};
  m.speed_accuracy_m_s = kNaN;
  *stamp = m.header.utime;
  return encode(m);
}

/// sensor_msgs/MagneticField: the same fields as magnetometer_t (tesla, row-major covariance).
std::vector<uint8_t> magnetic_field(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  magnetometer_t m{};
  header(r, s, m.header, has_seq);
  vector3(r, m.magnetic_field);
  r.get(m.magnetic_field_covariance, 9);
  *stamp = m.header.utime;
  return encode(m);
}

/// sensor_msgs/FluidPressure (a barometer's static pressure, Pa; variance 0: not given). It carries no temperature:
/// NaN (not measured).
std::vector<uint8_t> fluid_pressure(Reader& r, Serialization s, int64_t, int64_t* stamp, bool* has_seq) {
  barometer_t m{};
  header(r, s, m.header, has_seq);
  m.pressure_pa = r.get<double>();
  m.pressure_variance = r.get<double>();
  m.temperature_c = kNaN;
  *stamp = m.header.utime;
  return encode(m);
}

struct Mapping {
  const char* ros;
  const char* driftlab;
  Convert convert;
};
constexpr Mapping kMappings[] = {
    {"sensor_msgs/LaserScan", "driftlab.laser_scan_t", laser_scan},
    {"sensor_msgs/Imu", "driftlab.imu_t", imu},
    {"sensor_msgs/PointCloud2", "driftlab.point_cloud_t", point_cloud2},
    {"sensor_msgs/Image", "driftlab.image_t", image},
    {"sensor_msgs/CompressedImage", "driftlab.image_t", compressed_image},
    {"sensor_msgs/JointState", "driftlab.joint_state_t", joint_state},
    {"trajectory_msgs/JointTrajectory", "driftlab.joint_trajectory_t", joint_trajectory},
    {"control_msgs/FollowJointTrajectoryActionGoal", "driftlab.joint_trajectory_t", follow_joint_trajectory_goal},
    {"control_msgs/JointTrajectoryControllerState", "driftlab.joint_trajectory_state_t",
     joint_trajectory_controller_state},
    {"sensor_msgs/NavSatFix", "driftlab.gnss_t", nav_sat_fix},
    {"sensor_msgs/MagneticField", "driftlab.magnetometer_t", magnetic_field},
    {"sensor_msgs/FluidPressure", "driftlab.barometer_t", fluid_pressure},
    {"nav_msgs/Odometry", "driftlab.odometry_t", odometry},
    {"geometry_msgs/PoseStamped", "driftlab.pose_t", pose_stamped},
    {"geometry_msgs/PoseWithCovarianceStamped", "driftlab.pose_t", pose_with_covariance},
    {"geometry_msgs/TransformStamped", "driftlab.tf_t", transform},
    {"geometry_msgs/TwistStamped", "driftlab.velocity_command_t", twist_stamped},
    {"geometry_msgs/Twist", "driftlab.velocity_command_t", twist},
    {"tf2_msgs/TFMessage", "driftlab.tf_t", tf_message},
    {"mavros_msgs/TimesyncStatus", "driftlab.timesync_status_t", timesync_status},
    {"tf/tfMessage", "driftlab.tf_t", tf_message},  // ROS 1's older /tf type, same layout
};

const Mapping* find_mapping(std::string_view ros_type) {
  const std::string name = ros1_type_name(ros_type);
  for (const auto& m : kMappings)
    if (name == m.ros) return &m;
  return nullptr;
}

}  // namespace

std::string ros1_type_name(std::string_view type) {
  std::string s(type);
  if (auto p = s.find("/msg/"); p != std::string::npos) s.erase(p, 4);
  return s;
}

const char* driftlab_type_for(std::string_view ros_type) {
  const Mapping* m = find_mapping(ros_type);
  return m ? m->driftlab : nullptr;
}

bool is_ros_clock_type(std::string_view ros_type) { return ros1_type_name(ros_type) == "rosgraph_msgs/Clock"; }

bool read_clock(Serialization serialization, std::span<const uint8_t> payload, int64_t fallback_seq, header_t* out) {
  Reader r(payload, serialization);
  out->seq = fallback_seq;
  out->utime = r.time_us();
  out->frame_id.clear();
  return r.ok();
}

bool read_leading_header(Serialization serialization, std::span<const uint8_t> payload, int64_t fallback_seq,
                         header_t* out, bool* has_seq) {
  Reader r(payload, serialization);
  r.fallback_seq = fallback_seq;
  *has_seq = false;
  header(r, serialization, *out, has_seq);
  return r.ok();
}

std::optional<Converted> convert_ros_message(std::string_view ros_type, Serialization serialization,
                                             std::span<const uint8_t> payload, int64_t unstamped_us,
                                             int64_t fallback_seq, std::string* error, std::vector<uint8_t>* reuse) {
  error->clear();
  const Mapping* m = find_mapping(ros_type);
  if (!m) return std::nullopt;
  Reader r(payload, serialization);
  r.fallback_seq = fallback_seq;
  r.reuse = reuse;
  Converted out;
  out.lcm = m->convert(r, serialization, unstamped_us, &out.stamp_us, &out.has_seq);
  if (r.ok() && !r.at_end()) {
    r.fail(std::to_string(r.remaining()) + " bytes left over after the message");
  }
  if (!r.ok()) {
    *error = "not a " + ros1_type_name(ros_type) + ": " + r.error();
    return std::nullopt;
  }
  return out;
}

}  // namespace driftlab::formats
