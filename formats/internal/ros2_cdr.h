// ROS 2's wire format, CDR (little endian, XCDR1, as rosbag2 stores ROS 2 messages), written: driftlab's mapped
// types as the standard ROS 2 messages they go out as, and any other driftlab type walked by its .lcm definition.
// For the MCAP and rosbag2 export (formats/export_mcap.cc); the schemas that go with them are formats/ros2_schema.h.
// Thread-safety: a Cdr is one message being written; the functions are pure.
#pragma once

#include <bit>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "driftlab/barometer_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/image_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "driftlab/velocity_command_t.hpp"
#include "lcmtypes/schema.h"

namespace driftlab::formats::internal {

/// Whether every dimension of f is a number (a fixed-size array), and their product.
inline bool fixed_dims(const lcmtypes::FieldDef& f, uint64_t* count) {
  uint64_t n = 1;
  for (const auto& d : f.dims) {
    if (d.empty() || !std::isdigit(static_cast<unsigned char>(d[0]))) return false;
    n *= std::stoull(d);
  }
  *count = n;
  return true;
}

/// One CDR message, from its 4-byte encapsulation header on: every primitive aligned to its size counted from the
/// end of that header, strings with their terminating NUL in their length.
class Cdr {
 public:
  Cdr() { b_ = {0x00, 0x01, 0x00, 0x00}; }
  std::vector<uint8_t>& bytes() { return b_; }
  void reset() { b_.resize(4); }
  template <typename T>
  void put(T v) {
    align(sizeof(T));
    const size_t n = b_.size();
    b_.resize(n + sizeof(T));
    std::memcpy(b_.data() + n, &v, sizeof(T));
  }
  template <typename T>
  void fixed(const T* p, size_t n) {
    if (n == 0) return;
    align(sizeof(T));
    const size_t at = b_.size();
    b_.resize(at + n * sizeof(T));
    std::memcpy(b_.data() + at, p, n * sizeof(T));
  }
  template <typename T>
  void sequence(const T* p, size_t n) {
    put(static_cast<uint32_t>(n));
    fixed(p, n);
  }
  void str(std::string_view s) {
    put(static_cast<uint32_t>(s.size() + 1));
    b_.insert(b_.end(), s.begin(), s.end());
    b_.push_back(0);
  }
  void time(int64_t utime) {
    // builtin_interfaces/Time: whole seconds (rounded down) and the nanoseconds after them.
    const int64_t sec = utime >= 0 ? utime / 1'000'000 : -((-utime + 999'999) / 1'000'000);
    put(static_cast<int32_t>(sec));
    put(static_cast<uint32_t>((utime - sec * 1'000'000) * 1000));
  }
  void header(const header_t& h) {
    time(h.utime);
    str(h.frame_id);
  }
  void vec(const vector3_t& v) {
    put(v.x);
    put(v.y);
    put(v.z);
  }
  void quat(const quaternion_t& q) {
    put(q.x);
    put(q.y);
    put(q.z);
    put(q.w);
  }

 private:
  void align(size_t n) {
    const size_t off = (b_.size() - 4) % n;
    if (off) b_.resize(b_.size() + n - off, 0);
  }
  std::vector<uint8_t> b_;
};
static_assert(std::endian::native == std::endian::little, "CDR is written little endian in place");

// The mapped types, each as the standard message ros2_type_for names (the image_t: CompressedImage when its
// encoding is jpeg or png, else Image).
void laser_scan(Cdr& c, const laser_scan_t& m);
void imu(Cdr& c, const imu_t& m);
void odometry(Cdr& c, const odometry_t& m);
void pose(Cdr& c, const pose_t& m);
void tf(Cdr& c, const tf_t& m);
void twist(Cdr& c, const velocity_command_t& m);
void joint_state(Cdr& c, const joint_state_t& m);
void nav_sat_fix(Cdr& c, const gnss_t& m);
void magnetic_field(Cdr& c, const magnetometer_t& m);
void fluid_pressure(Cdr& c, const barometer_t& m);
bool compressed(const image_t& m);
void image(Cdr& c, const image_t& m);
void compressed_image(Cdr& c, const image_t& m);

/// A driftlab message of any type in CDR by its .lcm definition s: lcmtypes::flatten walks the LCM bytes (every
/// primitive in order, as text that reads back exactly), and the fields are written again in CDR in the same
/// order, with sequence lengths before variable-length arrays. False when the bytes do not walk whole.
bool lcm_to_cdr(std::span<const uint8_t> data, const lcmtypes::StructDef& s, Cdr& out);

}  // namespace driftlab::formats::internal
