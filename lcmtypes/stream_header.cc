#include "lcmtypes/stream_header.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/time.h"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace driftlab::lcmtypes {
namespace {

uint64_t be64(const uint8_t* p) {
  uint64_t v;
  std::memcpy(&v, p, 8);
  return __builtin_bswap64(v);
}
uint32_t be32(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return __builtin_bswap32(v);
}
int64_t fingerprint_of(std::span<const uint8_t> data) {
  return data.size() >= 8 ? static_cast<int64_t>(be64(data.data())) : 0;
}

/// Reads fields of an encoded LCM message in place (big-endian), so hot loops decode only what they need.
/// Offsets follow lcmtypes/*.lcm; tests/lcmtypes/stream_header_test.cc checks them against lcm-gen's decoders.
/// Reading past the end sets a sticky failure instead of reading.
class FieldReader {
 public:
  explicit FieldReader(std::span<const uint8_t> data) : data_(data) {}
  void skip(size_t n) {
    if (ok_ && data_.size() - pos_ >= n) {
      pos_ += n;
    } else {
      ok_ = false;
    }
  }
  void skip_string() {
    if (!ok_ || data_.size() - pos_ < 4) {
      ok_ = false;
      return;
    }
    const uint32_t n = be32(data_.data() + pos_);  // length including the terminating NUL
    pos_ += 4;
    skip(n);
  }
  uint64_t u64() {
    if (!ok_ || data_.size() - pos_ < 8) {
      ok_ = false;
      return 0;
    }
    const uint64_t v = be64(data_.data() + pos_);
    pos_ += 8;
    return v;
  }
  uint32_t u32() {
    if (!ok_ || data_.size() - pos_ < 4) {
      ok_ = false;
      return 0;
    }
    const uint32_t v = be32(data_.data() + pos_);
    pos_ += 4;
    return v;
  }
  double f64() {
    const uint64_t bits = u64();
    double v;
    std::memcpy(&v, &bits, 8);
    return v;
  }
  float f32() {
    const uint32_t bits = u32();
    float v;
    std::memcpy(&v, &bits, 4);
    return v;
  }
  bool ok() const { return ok_; }

 private:
  std::span<const uint8_t> data_;
  size_t pos_ = 0;
  bool ok_ = true;
};

/// A reader positioned after the header (fingerprint, seq, utime, frame_id).
FieldReader after_header(std::span<const uint8_t> data) {
  FieldReader r(data);
  r.skip(kHeaderFrameOffset);
  r.skip_string();
  return r;
}

}  // namespace

bool looks_like_header(std::span<const uint8_t> data, int64_t arrival_utime) {
  if (data.size() < kMinHeaderBytes) return false;
  const auto seq = static_cast<int64_t>(be64(data.data() + kHeaderSeqOffset));
  const auto stamp = static_cast<int64_t>(be64(data.data() + kHeaderStampOffset));
  const uint32_t len = be32(data.data() + kHeaderFrameOffset);  // with the NUL
  constexpr int64_t kDay = 86400LL * 1000000;
  // Compared without subtracting in int64_t: stamp - arrival overflows for arbitrary bytes.
  const bool near =
      std::max(us_after(arrival_utime, stamp), us_after(stamp, arrival_utime)) < static_cast<uint64_t>(kDay);
  return seq >= 0 && seq < (int64_t{1} << 48) && near && len >= 1 && len <= 256 &&
         kHeaderFrameOffset + 4 + static_cast<size_t>(len) <= data.size() &&
         data[kHeaderFrameOffset + 4 + len - 1] == 0;
}

bool has_header(std::span<const uint8_t> data, int64_t arrival_utime) {
  const TypeInfo* type = find_type(fingerprint_of(data));
  if (type == nullptr) return looks_like_header(data, arrival_utime);
  if (!type->has_header || data.size() < kHeaderFrameOffset + 4) return false;
  const uint32_t len = be32(data.data() + kHeaderFrameOffset);
  return len >= 1 && kHeaderFrameOffset + 4 + static_cast<size_t>(len) <= data.size();
}

std::optional<StreamHeader> read_header(std::span<const uint8_t> data, int64_t arrival_utime) {
  if (!has_header(data, arrival_utime)) return std::nullopt;
  StreamHeader h;
  h.seq = static_cast<int64_t>(be64(data.data() + kHeaderSeqOffset));
  h.utime = static_cast<int64_t>(be64(data.data() + kHeaderStampOffset));
  const uint32_t len = be32(data.data() + kHeaderFrameOffset);
  h.frame_id = std::string_view(reinterpret_cast<const char*>(data.data() + kHeaderFrameOffset + 4), len - 1);
  return h;
}

std::optional<int64_t> header_stamp(std::span<const uint8_t> data, int64_t arrival_utime) {
  if (!has_header(data, arrival_utime)) return std::nullopt;
  return static_cast<int64_t>(be64(data.data() + kHeaderStampOffset));
}

bool map_stamps(std::vector<uint8_t>& bytes, int64_t arrival_utime, const std::function<int64_t(int64_t)>& f) {
  if (fingerprint_of(bytes) == driftlab::tf_t::getHash()) {
    // Through the layout check: the generated decoder trusts ntransforms and allocates for it before reading (a
    // 1.5 KB message claiming 2,000,000 transforms asked for 270 MB on every restamped TF message).
    driftlab::tf_t tf;
    if (!decode(bytes, tf)) return false;
    tf.header.utime = f(tf.header.utime);
    for (auto& t : tf.transforms) t.header.utime = f(t.header.utime);
    bytes.resize(static_cast<size_t>(tf.getEncodedSize()));
    tf.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    return true;
  }
  const auto stamp = header_stamp(bytes, arrival_utime);
  if (!stamp) return false;
  const auto v = static_cast<uint64_t>(f(*stamp));
  for (int i = 0; i < 8; ++i) bytes[kHeaderStampOffset + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (56 - 8 * i));
  return true;
}

int64_t ready_after_us(std::span<const uint8_t> data) {
  if (fingerprint_of(data) != driftlab::laser_scan_t::getHash()) return 0;
  FieldReader r = after_header(data);
  r.skip(3 * 4);  // angle_min, angle_max, angle_increment
  const float time_increment = r.f32();
  r.skip(3 * 4);  // scan_time, range_min, range_max
  const auto nranges = static_cast<int32_t>(r.u32());
  if (!r.ok() || nranges <= 1 || !(time_increment > 0 && time_increment < 1)) return 0;
  return Duration::from_seconds_rounded((nranges - 1) * static_cast<double>(time_increment)).us();
}

std::optional<Motion> read_motion(std::span<const uint8_t> data) {
  static const int64_t kImu = driftlab::imu_t::getHash(), kOdom = driftlab::odometry_t::getHash(),
                       kPose = driftlab::pose_t::getHash();
  const int64_t fp = fingerprint_of(data);
  if (fp != kImu && fp != kOdom && fp != kPose) return std::nullopt;
  FieldReader r = after_header(data);
  Motion m;
  m.is_pose = fp == kPose;
  if (fp == kImu) {
    r.skip(4 * 8 + 9 * 8 + 2 * 8);  // orientation, its covariance, angular_velocity.x and .y
    m.value = r.f64();              // angular_velocity.z
  } else if (fp == kOdom) {
    r.skip_string();                                  // child_frame_id
    r.skip(3 * 8 + 4 * 8 + 36 * 8 + 3 * 8 + 2 * 8);  // position, orientation, covariance, linear, angular.x/.y
    m.value = r.f64();                                // angular_velocity.z
  } else {
    r.skip_string();  // child_frame_id
    r.skip(3 * 8);    // position
    const double w = r.f64(), x = r.f64(), y = r.f64(), z = r.f64();
    m.value = std::atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));  // yaw
  }
  if (!r.ok()) return std::nullopt;
  m.stamp_s = Time::from_us(static_cast<int64_t>(be64(data.data() + kHeaderStampOffset))).seconds();
  return m;
}

}  // namespace driftlab::lcmtypes
