#include "formats/ros2_schema.h"

#include <cctype>
#include <functional>
#include <set>
#include <utility>

#include "formats/internal/ros2_cdr.h"
#include "lcmtypes/schema.h"

namespace driftlab::formats {
namespace {

using internal::fixed_dims;

struct MsgText {
  const char* name;
  const char* text;
};
constexpr MsgText kStandard[] = {
#include "formats/internal/ros2_msg_texts.inc"
};

const char* standard_text(std::string_view name) {
  for (const auto& m : kStandard)
    if (name == m.name) return m.text;
  return nullptr;
}

std::string without_msg(std::string_view name) {
  std::string s(name);
  if (auto p = s.find("/msg/"); p != std::string::npos) s.erase(p, 4);
  return s;
}

// --- driftlab_msgs: ros2msg definitions made from lcmtypes/*.lcm -----------------------------------------------

/// "channel_stats_t" -> "ChannelStats"; header_t -> "Header" (driftlab's, with seq).
std::string camel(std::string_view lcm_name) {
  std::string_view n = lcm_name;
  if (n.ends_with("_t")) n.remove_suffix(2);
  std::string out;
  bool up = true;
  for (const char c : n) {
    if (c == '_') {
      up = true;
      continue;
    }
    out += up ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
    up = false;
  }
  return out;
}

const char* ros_primitive(const std::string& lcm_type) {
  static const std::pair<const char*, const char*> kMap[] = {
      {"int8_t", "int8"},    {"int16_t", "int16"}, {"int32_t", "int32"}, {"int64_t", "int64"}, {"float", "float32"},
      {"double", "float64"}, {"string", "string"}, {"boolean", "bool"},  {"byte", "uint8"}};
  for (const auto& [l, r] : kMap)
    if (lcm_type == l) return r;
  return nullptr;
}

/// The .msg text of a driftlab type: its fields in order, arrays of several dimensions flattened (row-major), a
/// variable-length array as a sequence (its length field stays, as in the .lcm).
std::string driftlab_msg_text(const lcmtypes::StructDef& s) {
  std::string t = "# driftlab." + s.name + " (lcmtypes/" + s.name + ".lcm), as driftlab exports it\n";
  for (const auto& f : s.fields) {
    std::string type;
    if (const char* p = ros_primitive(f.type)) {
      type = p;
    } else {
      type = "driftlab_msgs/" + camel(f.type);
    }
    if (!f.dims.empty()) {
      uint64_t n = 0;
      type += fixed_dims(f, &n) ? "[" + std::to_string(n) + "]" : "[]";
    }
    t += type + " " + f.name + "\n";
  }
  return t;
}

/// The .msg text of a type by its "pkg/Type" name: standard, or driftlab_msgs made from lcmtypes.
std::string msg_text(const std::string& name) {
  if (const char* t = standard_text(name)) return t;
  if (name.starts_with("driftlab_msgs/")) {
    const std::string want = name.substr(14);
    for (const auto& s : lcmtypes::all_structs())
      if (camel(s.name) == want) return driftlab_msg_text(s);
  }
  return {};
}

/// The message types a .msg text uses, as "pkg/Type" (a bare name is in the text's own package).
std::set<std::string> dependencies(const std::string& name, const std::string& text) {
  static const std::set<std::string> kPrimitives = {"bool",   "byte",  "char",   "float32", "float64",
                                                    "int8",   "uint8", "int16",  "uint16",  "int32",
                                                    "uint32", "int64", "uint64", "string",  "wstring"};
  const std::string package = name.substr(0, name.find('/'));
  std::set<std::string> out;
  size_t start = 0;
  while (start < text.size()) {
    size_t nl = text.find('\n', start);
    if (nl == std::string::npos) nl = text.size();
    std::string line = text.substr(start, nl - start);
    start = nl + 1;
    if (const size_t h = line.find('#'); h != std::string::npos) line.resize(h);
    const size_t b = line.find_first_not_of(" \t");
    if (b == std::string::npos) continue;
    const size_t e = line.find_first_of(" \t", b);
    if (e == std::string::npos) continue;
    const size_t n = line.find_first_not_of(" \t", e);
    if (n == std::string::npos) continue;
    const size_t ne = line.find_first_of(" \t=", n);
    if (ne != std::string::npos && line.find_first_not_of(" \t", ne) != std::string::npos &&
        line[line.find_first_not_of(" \t", ne)] == '=') {
      continue;  // a constant
    }
    std::string type = line.substr(b, e - b);
    type = type.substr(0, type.find('['));
    type = type.substr(0, type.find("<="));
    if (kPrimitives.count(type)) continue;
    out.insert(type.find('/') == std::string::npos ? package + "/" + type : without_msg(type));
  }
  return out;
}

}  // namespace

std::string ros2_type_for(std::string_view driftlab_type) {
  static const std::pair<const char*, const char*> kMap[] = {
      {"driftlab.laser_scan_t", "sensor_msgs/msg/LaserScan"},
      {"driftlab.imu_t", "sensor_msgs/msg/Imu"},
      {"driftlab.odometry_t", "nav_msgs/msg/Odometry"},
      {"driftlab.pose_t", "geometry_msgs/msg/PoseWithCovarianceStamped"},
      {"driftlab.tf_t", "tf2_msgs/msg/TFMessage"},
      {"driftlab.velocity_command_t", "geometry_msgs/msg/TwistStamped"},
      {"driftlab.joint_state_t", "sensor_msgs/msg/JointState"},
      {"driftlab.point_cloud_t", "sensor_msgs/msg/PointCloud2"},
      {"driftlab.image_t", "sensor_msgs/msg/Image"},
      {"driftlab.gnss_t", "sensor_msgs/msg/NavSatFix"},
      {"driftlab.magnetometer_t", "sensor_msgs/msg/MagneticField"},
      {"driftlab.barometer_t", "sensor_msgs/msg/FluidPressure"},
  };
  for (const auto& [d, r] : kMap)
    if (driftlab_type == d) return r;
  std::string_view n = driftlab_type;
  if (n.starts_with("driftlab.")) n.remove_prefix(9);
  return "driftlab_msgs/msg/" + camel(n);
}

std::string ros2_schema(std::string_view ros_type) {
  const std::string root = without_msg(ros_type);
  std::string out = msg_text(root);
  if (out.empty()) return {};
  std::set<std::string> seen = {root};
  std::function<void(const std::string&, const std::string&)> add = [&](const std::string& name,
                                                                        const std::string& text) {
    for (const auto& dep : dependencies(name, text)) {
      if (!seen.insert(dep).second) continue;
      const std::string t = msg_text(dep);
      out += "\n" + std::string(80, '=') + "\nMSG: " + dep + "\n" + t;
      add(dep, t);
    }
  };
  add(root, out);
  return out;
}

}  // namespace driftlab::formats
