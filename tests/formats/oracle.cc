#include "tests/formats/oracle.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <sstream>

#include "driftlab/barometer_t.hpp"
#include "driftlab/foreign_message_t.hpp"
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
#include "driftlab/velocity_command_t.hpp"
#include "formats/ros_definition.h"
#include "lcmtypes/schema.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace driftlab::test {
namespace {

using nlohmann::json;

const std::string kOracleDir = std::string(DRIFTLAB_SOURCE_DIR) + "/tests/oracle";

/// A JSON number as the double it holds; null (how JSON writes NaN) as NaN.
double num(const json& j) {
  if (j.is_null()) return std::nan("");
  return j.get<double>();
}

/// Equal as numbers, NaN equal to NaN (a NaN in a message must stay a NaN).
#define EXPECT_SAME(want, got)                                \
  do {                                                        \
    const double w_ = (want), g_ = (got);                     \
    if (!(std::isnan(w_) && std::isnan(g_))) {                \
      EXPECT_EQ(w_, g_) << #got;                              \
    }                                                         \
  } while (0)

int64_t stamp_us(const json& t) {
  const int64_t sec = t.at("sec").get<int64_t>();
  const int64_t nsec = t.contains("nanosec") ? t.at("nanosec").get<int64_t>() : t.at("nsec").get<int64_t>();
  return sec * 1'000'000 + nsec / 1000;
}

void expect_header(const json& h, const header_t& got, int64_t seq) {
  EXPECT_EQ(got.utime, stamp_us(h.at("stamp")));
  EXPECT_EQ(got.frame_id, h.at("frame_id").get<std::string>());
  EXPECT_EQ(got.seq, h.contains("seq") ? h.at("seq").get<int64_t>() : seq);
}
void expect_vec(const json& v, const vector3_t& got) {
  EXPECT_SAME(num(v.at("x")), got.x);
  EXPECT_SAME(num(v.at("y")), got.y);
  EXPECT_SAME(num(v.at("z")), got.z);
}
void expect_quat(const json& q, const quaternion_t& got) {
  EXPECT_SAME(num(q.at("x")), got.x);
  EXPECT_SAME(num(q.at("y")), got.y);
  EXPECT_SAME(num(q.at("z")), got.z);
  EXPECT_SAME(num(q.at("w")), got.w);
}
template <typename T>
void expect_array(const json& a, const T* got, size_t n) {
  ASSERT_EQ(a.size(), n);
  for (size_t i = 0; i < n; ++i) EXPECT_SAME(num(a[i]), static_cast<double>(got[i]));
}
template <typename T>
void expect_array(const json& a, const std::vector<T>& got) {
  expect_array(a, got.data(), got.size());
}
std::vector<uint8_t> bytes_of(const json& a) {
  std::vector<uint8_t> b;
  b.reserve(a.size());
  for (const auto& v : a) b.push_back(v.get<uint8_t>());
  return b;
}
void expect_transform(const json& t, const transform_t& got) {
  // A transform's own seq exists in ROS 1 only (ROS 2 has none, and driftlab's batch carries the sequence).
  const json& h = t.at("header");
  EXPECT_EQ(got.header.utime, stamp_us(h.at("stamp")));
  EXPECT_EQ(got.header.frame_id, h.at("frame_id").get<std::string>());
  if (h.contains("seq")) {
    EXPECT_EQ(got.header.seq, h.at("seq").get<int64_t>());
  }
  EXPECT_EQ(got.child_frame_id, t.at("child_frame_id").get<std::string>());
  expect_vec(t.at("transform").at("translation"), got.translation);
  expect_quat(t.at("transform").at("rotation"), got.rotation);
}

/// sensor_msgs/PointCloud2's point field `name` of point i, as a double (float32 and float64 fields, little endian).
double cloud_value(const json& m, const std::vector<uint8_t>& data, const std::string& name, size_t row, size_t col) {
  for (const auto& f : m.at("fields")) {
    if (f.at("name") != name) continue;
    const size_t at = row * m.at("row_step").get<size_t>() + col * m.at("point_step").get<size_t>() +
                      f.at("offset").get<size_t>();
    const int type = f.at("datatype").get<int>();
    if (type == 7) {
      float v;
      std::memcpy(&v, data.data() + at, 4);
      return v;
    }
    if (type == 8) {
      double v;
      std::memcpy(&v, data.data() + at, 8);
      return v;
    }
    if (type == 6) {
      uint32_t v;
      std::memcpy(&v, data.data() + at, 4);
      return v;
    }
    ADD_FAILURE() << "the test reads no point field of datatype " << type;
  }
  return std::nan("");
}

}  // namespace

namespace {

/// Whether node and the oracle's npm modules are here; if not, skips the calling test (fails it under CI).
bool have_oracle() {
  const bool ci = std::getenv("CI") != nullptr && std::string(std::getenv("CI")) == "true";
  const bool have = run("node --version >/dev/null 2>&1") == 0 &&
                    std::filesystem::exists(kOracleDir + "/node_modules/@mcap/core/package.json");
  if (!have) {
    if (ci) {
      ADD_FAILURE() << "node or the oracle's npm modules are missing under CI (scripts/bootstrap installs them)";
    } else {
      [] { GTEST_SKIP() << "node or tests/oracle/node_modules missing (scripts/bootstrap installs them)"; }();
    }
  }
  return have;
}

}  // namespace

bool oracle_write_mcap(const json& spec, const std::string& out) {
  if (!have_oracle()) return false;
  TempDir dir;
  // Log times as strings: JavaScript's numbers hold 53 bits, a time in nanoseconds needs more.
  json copy = spec;
  for (auto& m : copy.at("messages")) m["time_ns"] = std::to_string(m.at("time_ns").get<int64_t>());
  const std::string in = dir.file("spec.json"), err = dir.file("write.err");
  const std::string text = copy.dump();
  write_file(in, {text.begin(), text.end()});
  if (run("node '" + kOracleDir + "/write_mcap.mjs' '" + in + "' '" + out + "' 2>'" + err + "'") != 0) {
    const auto e = read_file(err);
    ADD_FAILURE() << "the oracle cannot write " << out << ": " << std::string(e.begin(), e.end());
    return false;
  }
  return true;
}

bool oracle_relayout_mcap(const std::string& in, const std::string& out, const json& layout) {
  if (!have_oracle()) return false;
  TempDir dir;
  const std::string spec = dir.file("layout.json"), err = dir.file("relayout.err");
  const std::string text = layout.dump();
  write_file(spec, {text.begin(), text.end()});
  if (run("node '" + kOracleDir + "/relayout_mcap.mjs' '" + in + "' '" + out + "' '" + spec + "' 2>'" + err + "'") !=
      0) {
    const auto e = read_file(err);
    ADD_FAILURE() << "the oracle cannot write " << in << " again: " << std::string(e.begin(), e.end());
    return false;
  }
  return true;
}

std::optional<std::vector<json>> oracle_messages(const std::string& file) {
  if (!have_oracle()) return std::nullopt;
  TempDir dir;
  const std::string out = dir.file("dump.jsonl"), err = dir.file("dump.err");
  const int rc = run("node '" + kOracleDir + "/dump.mjs' '" + file + "' >'" + out + "' 2>'" + err + "'");
  if (rc != 0) {
    const auto e = read_file(err);
    ADD_FAILURE() << "the oracle cannot read " << file << ": " << std::string(e.begin(), e.end());
    return std::vector<json>{};
  }
  std::vector<json> msgs;
  std::istringstream in([&] {
    const auto b = read_file(out);
    return std::string(b.begin(), b.end());
  }());
  for (std::string line; std::getline(in, line);) msgs.push_back(json::parse(line));
  return msgs;
}

void expect_same_message(const json& ros, const OwnedEvent& e, int64_t seq, const std::string& schema) {
  SCOPED_TRACE(e.channel + " at " + std::to_string(e.utime));
  const std::string type = formats::ros1_type_name(ros.at("type").get<std::string>());
  const json& m = ros.at("msg");
  EXPECT_EQ(e.utime, ros.at("time_ns").get<int64_t>() / 1000);
  if (type.starts_with("driftlab_msgs/")) {
    // driftlab's own types: every field of the LCM message, flattened, against the oracle's reading.
    int64_t fp = 0;
    for (int i = 0; i < 8; ++i) fp = static_cast<int64_t>((static_cast<uint64_t>(fp) << 8) | e.data[static_cast<size_t>(i)]);
    const lcmtypes::StructDef* def = lcmtypes::find_struct(lcmtypes::type_name(fp));
    ASSERT_NE(def, nullptr);
    std::map<std::string, json> want;
    std::function<void(const json&, const std::string&)> flat = [&](const json& v, const std::string& path) {
      if (v.is_object()) {
        for (const auto& [k, x] : v.items()) flat(x, path.empty() ? k : path + "." + k);
      } else if (v.is_array()) {
        for (size_t i = 0; i < v.size(); ++i) flat(v[i], path + "[" + std::to_string(i) + "]");
      } else {
        want[path] = v;
      }
    };
    flat(m, "");
    size_t columns = 0;
    lcmtypes::flatten(*def, e.data, [&](const std::string& column, const std::string& value) {
      ++columns;
      ASSERT_TRUE(want.count(column)) << column;
      const json& w = want.at(column);
      if (w.is_string()) {
        EXPECT_EQ(value, w.get<std::string>()) << column;
      } else if (w.is_boolean()) {
        EXPECT_EQ(value, w.get<bool>() ? "1" : "0") << column;
      } else {
        EXPECT_SAME(num(w), std::strtod(value.c_str(), nullptr));
      }
    }, {.max_array = SIZE_MAX, .bytes = true});
    EXPECT_EQ(columns, want.size());
    return;
  }
  if (!formats::driftlab_type_for(type) || (ros["encoding"] != "cdr" && ros["encoding"] != "ros1")) {
    const auto f = test::decode<foreign_message_t>(e);
    EXPECT_EQ(f.type, ros.at("type").get<std::string>());
    EXPECT_EQ(f.encoding, ros.at("encoding").get<std::string>());
    auto d = formats::RosDefinition::parse(f.type, schema,
                                           f.encoding == "ros1" ? formats::Serialization::kRos1
                                                                : formats::Serialization::kCdr);
    ASSERT_TRUE(d.ok()) << d.error().message;
    auto walked = d->to_json(f.data);
    ASSERT_TRUE(walked.ok()) << walked.error().message;
    EXPECT_EQ(json::parse(*walked), m);
    return;
  }
  if (type == "sensor_msgs/LaserScan") {
    const auto s = test::decode<laser_scan_t>(e);
    expect_header(m.at("header"), s.header, seq);
    for (const char* k : {"angle_min", "angle_max", "angle_increment", "time_increment", "scan_time", "range_min",
                          "range_max"}) {
      const double got = k == std::string("angle_min")         ? s.angle_min
                         : k == std::string("angle_max")       ? s.angle_max
                         : k == std::string("angle_increment") ? s.angle_increment
                         : k == std::string("time_increment")  ? s.time_increment
                         : k == std::string("scan_time")       ? s.scan_time
                         : k == std::string("range_min")       ? s.range_min
                                                               : s.range_max;
      EXPECT_SAME(num(m.at(k)), got);
    }
    expect_array(m.at("ranges"), s.ranges);
    expect_array(m.at("intensities"), s.intensities);
  } else if (type == "sensor_msgs/Imu") {
    const auto s = test::decode<imu_t>(e);
    expect_header(m.at("header"), s.header, seq);
    expect_quat(m.at("orientation"), s.orientation);
    expect_array(m.at("orientation_covariance"), s.orientation_covariance, 9);
    expect_vec(m.at("angular_velocity"), s.angular_velocity);
    expect_array(m.at("angular_velocity_covariance"), s.angular_velocity_covariance, 9);
    expect_vec(m.at("linear_acceleration"), s.linear_acceleration);
    expect_array(m.at("linear_acceleration_covariance"), s.linear_acceleration_covariance, 9);
  } else if (type == "nav_msgs/Odometry") {
    const auto o = test::decode<odometry_t>(e);
    expect_header(m.at("header"), o.header, seq);
    EXPECT_EQ(o.child_frame_id, m.at("child_frame_id").get<std::string>());
    expect_vec(m.at("pose").at("pose").at("position"), o.position);
    expect_quat(m.at("pose").at("pose").at("orientation"), o.orientation);
    expect_array(m.at("pose").at("covariance"), o.pose_covariance, 36);
    expect_vec(m.at("twist").at("twist").at("linear"), o.linear_velocity);
    expect_vec(m.at("twist").at("twist").at("angular"), o.angular_velocity);
    expect_array(m.at("twist").at("covariance"), o.twist_covariance, 36);
  } else if (type == "geometry_msgs/PoseStamped" || type == "geometry_msgs/PoseWithCovarianceStamped") {
    const auto p = test::decode<pose_t>(e);
    expect_header(m.at("header"), p.header, seq);
    const json& pose = type == "geometry_msgs/PoseStamped" ? m.at("pose") : m.at("pose").at("pose");
    expect_vec(pose.at("position"), p.position);
    expect_quat(pose.at("orientation"), p.orientation);
    if (type == "geometry_msgs/PoseWithCovarianceStamped") expect_array(m.at("pose").at("covariance"), p.covariance, 36);
  } else if (type == "tf2_msgs/TFMessage" || type == "tf/tfMessage") {
    const auto tf = test::decode<tf_t>(e);
    ASSERT_EQ(static_cast<size_t>(tf.ntransforms), m.at("transforms").size());
    int64_t newest = INT64_MIN;
    for (size_t i = 0; i < m.at("transforms").size(); ++i) {
      const json& t = m.at("transforms")[i];
      expect_transform(t, tf.transforms[i]);
      newest = std::max(newest, stamp_us(t.at("header").at("stamp")));
    }
    EXPECT_EQ(tf.header.seq, seq);
    EXPECT_EQ(tf.header.utime, tf.ntransforms ? newest : e.utime);
  } else if (type == "geometry_msgs/TransformStamped") {
    const auto tf = test::decode<tf_t>(e);
    ASSERT_EQ(tf.ntransforms, 1);
    expect_transform(m, tf.transforms[0]);
    EXPECT_EQ(tf.transforms[0].header.seq, m.at("header").contains("seq") ? m["header"]["seq"].get<int64_t>() : seq);
  } else if (type == "geometry_msgs/TwistStamped" || type == "geometry_msgs/Twist") {
    const auto v = test::decode<velocity_command_t>(e);
    const json& twist = type == "geometry_msgs/Twist" ? m : m.at("twist");
    if (type == "geometry_msgs/TwistStamped") {
      expect_header(m.at("header"), v.header, seq);
    } else {
      EXPECT_EQ(v.header.utime, e.utime);
      EXPECT_EQ(v.header.seq, seq);
    }
    expect_vec(twist.at("linear"), v.linear);
    expect_vec(twist.at("angular"), v.angular);
  } else if (type == "sensor_msgs/JointState") {
    const auto j = test::decode<joint_state_t>(e);
    expect_header(m.at("header"), j.header, seq);
    ASSERT_EQ(static_cast<size_t>(j.njoints), m.at("name").size());
    for (size_t i = 0; i < m.at("name").size(); ++i) EXPECT_EQ(j.name[i], m["name"][i].get<std::string>());
    for (const auto& [k, got] : {std::pair{"position", &j.position}, {"velocity", &j.velocity}, {"effort", &j.effort}}) {
      if (m.at(k).empty()) {
        for (double v : *got) EXPECT_TRUE(std::isnan(v)) << k;
      } else {
        expect_array(m.at(k), *got);
      }
    }
  } else if (type == "sensor_msgs/Image") {
    const auto im = test::decode<image_t>(e);
    expect_header(m.at("header"), im.header, seq);
    EXPECT_EQ(im.width, m.at("width").get<int32_t>());
    EXPECT_EQ(im.height, m.at("height").get<int32_t>());
    EXPECT_EQ(im.encoding, m.at("encoding").get<std::string>());
    const auto data = bytes_of(m.at("data"));
    const size_t step = m.at("step").get<size_t>();
    const size_t row = im.height ? im.data.size() / static_cast<size_t>(im.height) : 0;
    ASSERT_LE(row, step);
    for (size_t y = 0; y < static_cast<size_t>(im.height); ++y) {
      ASSERT_TRUE(std::equal(im.data.begin() + static_cast<ptrdiff_t>(y * row),
                             im.data.begin() + static_cast<ptrdiff_t>((y + 1) * row),
                             data.begin() + static_cast<ptrdiff_t>(y * step)))
          << "row " << y;
    }
  } else if (type == "sensor_msgs/CompressedImage") {
    const auto im = test::decode<image_t>(e);
    expect_header(m.at("header"), im.header, seq);
    EXPECT_EQ(im.data, bytes_of(m.at("data")));
    EXPECT_EQ(im.encoding, m.at("format").get<std::string>());
  } else if (type == "sensor_msgs/PointCloud2") {
    const auto pc = test::decode<point_cloud_t>(e);
    expect_header(m.at("header"), pc.header, seq);
    EXPECT_EQ(pc.height, m.at("height").get<int32_t>());
    EXPECT_EQ(pc.width, m.at("width").get<int32_t>());
    const auto data = bytes_of(m.at("data"));
    bool intensity = false, time = false;
    for (const auto& f : m.at("fields")) {
      intensity |= f.at("name") == "intensity";
      time |= f.at("name") == "time";
    }
    // Both ways: a field for every point (an import makes one array per field; an export writes a field for an
    // array with a value for every point, and none for one that has not).
    if (pc.npoints > 0) {
      EXPECT_EQ(intensity, pc.nintensities == pc.npoints);
      EXPECT_EQ(time, pc.ntimes == pc.npoints);
    }
    size_t i = 0;
    for (size_t r = 0; r < static_cast<size_t>(pc.height); ++r) {
      for (size_t c = 0; c < static_cast<size_t>(pc.width); ++c, ++i) {
        EXPECT_SAME(static_cast<float>(cloud_value(m, data, "x", r, c)), pc.x[i]);
        EXPECT_SAME(static_cast<float>(cloud_value(m, data, "y", r, c)), pc.y[i]);
        EXPECT_SAME(static_cast<float>(cloud_value(m, data, "z", r, c)), pc.z[i]);
        if (intensity) EXPECT_SAME(static_cast<float>(cloud_value(m, data, "intensity", r, c)), pc.intensities[i]);
        if (time) EXPECT_SAME(static_cast<float>(cloud_value(m, data, "time", r, c)), pc.time_offsets[i]);
      }
    }
  } else if (type == "sensor_msgs/NavSatFix") {
    // Both ways (docs/import.md, docs/export.md): the status says whether there is a fix, a 2D fix has no
    // altitude, the covariance is the accuracies' (eph: the RMS of the east and north deviations).
    const auto g = test::decode<gnss_t>(e);
    expect_header(m.at("header"), g.header, seq);
    EXPECT_EQ(g.latitude_deg, num(m.at("latitude")));
    EXPECT_EQ(g.longitude_deg, num(m.at("longitude")));
    EXPECT_EQ(m.at("status").at("status").get<int>() < 0, g.fix_type < 2) << g.fix_type;
    if (g.fix_type == 2) {
      EXPECT_TRUE(std::isnan(num(m.at("altitude"))));
    } else {
      EXPECT_SAME(num(m.at("altitude")), g.altitude_m);
    }
    const json& c = m.at("position_covariance");
    if (m.at("position_covariance_type").get<int>() == 0) {
      EXPECT_EQ(g.eph_m, 0);
      EXPECT_EQ(g.epv_m, 0);
    } else {
      EXPECT_SAME(std::sqrt((num(c[0]) + num(c[4])) / 2), g.eph_m);
      EXPECT_SAME(std::sqrt(num(c[8])), g.epv_m);
    }
  } else if (type == "sensor_msgs/MagneticField") {
    const auto mag = test::decode<magnetometer_t>(e);
    expect_header(m.at("header"), mag.header, seq);
    expect_vec(m.at("magnetic_field"), mag.magnetic_field);
    expect_array(m.at("magnetic_field_covariance"), mag.magnetic_field_covariance, 9);
  } else if (type == "sensor_msgs/FluidPressure") {
    const auto b = test::decode<barometer_t>(e);
    expect_header(m.at("header"), b.header, seq);
    EXPECT_SAME(num(m.at("fluid_pressure")), b.pressure_pa);
    EXPECT_SAME(num(m.at("variance")), b.pressure_variance);
  } else {
    ADD_FAILURE() << "the test has no check for " << type;
  }
}

}  // namespace driftlab::test
