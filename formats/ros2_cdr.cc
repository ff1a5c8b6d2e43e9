#include "formats/internal/ros2_cdr.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>

namespace driftlab::formats::internal {

void laser_scan(Cdr& c, const laser_scan_t& m) {
  c.header(m.header);
  for (float v :
       {m.angle_min, m.angle_max, m.angle_increment, m.time_increment, m.scan_time, m.range_min, m.range_max}) {
    c.put(v);
  }
  c.sequence(m.ranges.data(), m.ranges.size());
  c.sequence(m.intensities.data(), m.intensities.size());
}
void imu(Cdr& c, const imu_t& m) {
  c.header(m.header);
  c.quat(m.orientation);
  c.fixed(m.orientation_covariance, 9);
  c.vec(m.angular_velocity);
  c.fixed(m.angular_velocity_covariance, 9);
  c.vec(m.linear_acceleration);
  c.fixed(m.linear_acceleration_covariance, 9);
}
void odometry(Cdr& c, const odometry_t& m) {
  c.header(m.header);
  c.str(m.child_frame_id);
  c.vec(m.position);
  c.quat(m.orientation);
  c.fixed(m.pose_covariance, 36);
  c.vec(m.linear_velocity);
  c.vec(m.angular_velocity);
  c.fixed(m.twist_covariance, 36);
}
void pose(Cdr& c, const pose_t& m) {
  c.header(m.header);
  c.vec(m.position);
  c.quat(m.orientation);
  c.fixed(m.covariance, 36);
}
void tf(Cdr& c, const tf_t& m) {
  c.put(static_cast<uint32_t>(m.transforms.size()));
  for (const auto& t : m.transforms) {
    c.header(t.header);
    c.str(t.child_frame_id);
    c.vec(t.translation);
    c.quat(t.rotation);
  }
}
void twist(Cdr& c, const velocity_command_t& m) {
  c.header(m.header);
  c.vec(m.linear);
  c.vec(m.angular);
}
void joint_state(Cdr& c, const joint_state_t& m) {
  c.header(m.header);
  c.put(static_cast<uint32_t>(m.name.size()));
  for (const auto& n : m.name) c.str(n);
  // Values not measured are NaN in driftlab and an empty array in ROS.
  for (const auto* v : {&m.position, &m.velocity, &m.effort}) {
    const bool none = std::all_of(v->begin(), v->end(), [](double x) { return std::isnan(x); });
    if (none) {
      c.put<uint32_t>(0);
    } else {
      c.sequence(v->data(), v->size());
    }
  }
}
/// gnss_t as sensor_msgs/NavSatFix, what Foxglove's map shows: the fix type as the status (no fix below 2D, a
/// ground-augmented fix for PX4's differential and RTK types from 4), a 2D fix without its altitude (NaN, as ROS
/// says "none"), the accuracies as a diagonal covariance (east and north eph^2, up epv^2; unknown when both are 0).
/// NavSatFix has no place for the velocity, its accuracy or the satellite count: they are not carried.
void nav_sat_fix(Cdr& c, const gnss_t& m) {
  c.header(m.header);
  c.put<int8_t>(m.fix_type < 2 ? -1 : m.fix_type >= 4 ? 2 : 0);
  c.put<uint16_t>(0);  // service: the log does not say which systems
  c.put(m.latitude_deg);
  c.put(m.longitude_deg);
  c.put(m.fix_type == 2 && !std::isnan(m.altitude_m) ? std::numeric_limits<double>::quiet_NaN() : m.altitude_m);
  const bool known = !(m.eph_m == 0 && m.epv_m == 0);
  const double h = known ? m.eph_m * m.eph_m : 0, v = known ? m.epv_m * m.epv_m : 0;
  const double covariance[9] = {h, 0, 0, 0, h, 0, 0, 0, v};
  c.fixed(covariance, 9);
  c.put<uint8_t>(known ? 2 : 0);  // COVARIANCE_TYPE_DIAGONAL_KNOWN, or UNKNOWN
}
void magnetic_field(Cdr& c, const magnetometer_t& m) {
  c.header(m.header);
  c.vec(m.magnetic_field);
  c.fixed(m.magnetic_field_covariance, 9);
}
/// barometer_t as sensor_msgs/FluidPressure; its temperature has no place there and is not carried.
void fluid_pressure(Cdr& c, const barometer_t& m) {
  c.header(m.header);
  c.put(m.pressure_pa);
  c.put(m.pressure_variance);
}
bool compressed(const image_t& m) { return m.encoding == "jpeg" || m.encoding == "png"; }

void image(Cdr& c, const image_t& m) {
  c.header(m.header);
  c.put(static_cast<uint32_t>(m.height));
  c.put(static_cast<uint32_t>(m.width));
  c.str(m.encoding);
  c.put<uint8_t>(0);                                                                               // is_bigendian
  c.put(static_cast<uint32_t>(m.height > 0 ? m.data.size() / static_cast<size_t>(m.height) : 0));  // step: no padding
  c.sequence(m.data.data(), m.data.size());
}
void compressed_image(Cdr& c, const image_t& m) {
  c.header(m.header);
  c.str(m.encoding);
  c.sequence(m.data.data(), m.data.size());
}

namespace {

class LcmToCdr {
 public:
  LcmToCdr(std::span<const uint8_t> data, Cdr& out) : d_(data), c_(out) {}
  bool run(const lcmtypes::StructDef& s) {
    const bool whole =
        lcmtypes::flatten(s, d_, [&](const std::string&, const std::string& value) { values_.push_back(value); },
                          {.max_array = SIZE_MAX, .bytes = true});
    return whole && fields(s) && next_ == values_.size();
  }

 private:
  bool primitive(const std::string& t, int64_t* value) {
    if (next_ >= values_.size()) return false;
    const std::string& v = values_[next_++];
    if (t == "string") {
      c_.str(v);
      return true;
    }
    const char* b = v.data();
    const char* e = b + v.size();
    if (t == "double" || t == "float") {
      double d = 0;
      if (std::from_chars(b, e, d).ec != std::errc()) d = std::strtod(v.c_str(), nullptr);  // nan, inf
      if (t == "double") {
        c_.put(d);
      } else {
        c_.put(static_cast<float>(d));
      }
      return true;
    }
    int64_t i = 0;
    if (std::from_chars(b, e, i).ec != std::errc()) return false;
    if (value) *value = i;
    if (t == "int64_t") {
      c_.put(i);
    } else if (t == "int32_t") {
      c_.put(static_cast<int32_t>(i));
    } else if (t == "int16_t") {
      c_.put(static_cast<int16_t>(i));
    } else if (t == "int8_t") {
      c_.put(static_cast<int8_t>(i));
    } else {
      c_.put(static_cast<uint8_t>(i));  // byte, boolean
    }
    return true;
  }
  bool element(const lcmtypes::FieldDef& f, int64_t* value) {
    if (const auto* nested = lcmtypes::find_struct(f.type)) return fields(*nested);
    return primitive(f.type, value);
  }
  bool fields(const lcmtypes::StructDef& s) {
    std::map<std::string, int64_t> ints;  // integer fields seen, for the lengths of later arrays
    for (const auto& f : s.fields) {
      if (f.dims.empty()) {
        int64_t v = 0;
        if (!element(f, &v)) return false;
        ints[f.name] = v;
        continue;
      }
      uint64_t total = 1;
      for (const auto& d : f.dims) {
        total *= std::isdigit(static_cast<unsigned char>(d[0])) ? std::stoull(d)
                                                                : static_cast<uint64_t>(std::max<int64_t>(0, ints[d]));
      }
      uint64_t fixed = 0;
      if (!fixed_dims(f, &fixed)) c_.put(static_cast<uint32_t>(total));
      for (uint64_t i = 0; i < total; ++i)
        if (!element(f, nullptr)) return false;
    }
    return true;
  }
  std::span<const uint8_t> d_;
  Cdr& c_;
  std::vector<std::string> values_;
  size_t next_ = 0;
};

}  // namespace

bool lcm_to_cdr(std::span<const uint8_t> data, const lcmtypes::StructDef& s, Cdr& out) {
  return LcmToCdr(data, out).run(s);
}

}  // namespace driftlab::formats::internal
