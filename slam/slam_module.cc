#include "slam/slam_module.h"

#include <algorithm>
#include <cctype>

#include "core/config.h"

namespace driftlab::slam {

namespace {

/// The type of a delivered channel, "" when it is not delivered.
std::string type_of(const InputChannels& inputs, const std::string& channel) {
  for (const auto& c : inputs) {
    if (c.name == channel) return c.type;
  }
  return "";
}

/// The delivered channels of a type, most messages first.
std::vector<const InputChannel*> of_type(const InputChannels& inputs, const std::string& type) {
  std::vector<const InputChannel*> out;
  for (const auto& c : inputs) {
    if (c.type == type && c.count > 0) out.push_back(&c);
  }
  std::stable_sort(out.begin(), out.end(), [](const auto* a, const auto* b) { return a->count > b->count; });
  return out;
}

/// Whether the config sets `backend.key`.
bool set_in(const YAML::Node& config, const char* backend, const char* key) {
  return config.IsMap() && config[backend].IsMap() && config[backend][key].IsDefined();
}

/// Finds the input channels of one backend that are not set and not delivered: `data` (the scans or clouds, of
/// `data_type`), the odometry and the static transforms. Says what it took in `notes`.
void find_inputs(const InputChannels& inputs, const YAML::Node& config, const char* backend, const char* data_key,
                 const std::string& data_type, std::string& data, std::string& odom, std::string& tf_static,
                 std::vector<std::string>* notes) {
  auto take = [&](std::string& channel, const std::string& found, const std::string& what, const std::string& type,
                  const std::string& others) {
    if (notes != nullptr) {
      notes->push_back("slam: " + what + " from " + found + " (" + type + "; none on " + channel +
                       (others.empty() ? "" : "; also " + others + ": set slam." + backend + "." + data_key) + ")");
    }
    channel = found;
  };
  if (!set_in(config, backend, data_key) && type_of(inputs, data) != data_type) {
    const auto found = of_type(inputs, data_type);
    std::string others;
    for (size_t i = 1; i < found.size(); ++i) others += (others.empty() ? "" : ", ") + found[i]->name;
    if (!found.empty())
      take(data, found[0]->name, data_type == "driftlab.laser_scan_t" ? "scans" : "clouds", data_type, others);
  }
  const std::string odom_type = type_of(inputs, odom);
  if (!set_in(config, backend, "odom_channel") && !odom.empty() && odom_type != "driftlab.odometry_t" &&
      odom_type != "driftlab.pose_t") {
    const auto found = of_type(inputs, "driftlab.odometry_t");
    if (!found.empty()) {
      take(odom, found[0]->name, "odometry", "driftlab.odometry_t", "");
    } else if (type_of(inputs, data + "_POSE") == "driftlab.pose_t") {
      take(odom, data + "_POSE", "odometry", "driftlab.pose_t, the pose its scans carry", "");
    }
  }
  if (!set_in(config, backend, "tf_static_channel") && !tf_static.empty() &&
      type_of(inputs, tf_static) != "driftlab.tf_t") {
    for (const auto* c : of_type(inputs, "driftlab.tf_t")) {
      std::string lower = c->name;
      std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char ch) { return std::tolower(ch); });
      if (lower.ends_with("tf_static")) {
        take(tf_static, c->name, "the sensor's mounting", "driftlab.tf_t", "");
        break;
      }
    }
  }
}

}  // namespace

Result<std::unique_ptr<Module>> make_slam(const YAML::Node& config, const std::string& origin,
                                          const InputChannels& inputs, std::vector<std::string>* notes) {
  // Both backends' settings are read, so a bad key is reported whichever backend runs.
  auto c = slam_config_table().parse(config::Value(config, origin, "slam"));
  if (!c) return c.error();
  std::string backend = c->backend;
  if (backend == "auto") {
    const bool scans = !of_type(inputs, "driftlab.laser_scan_t").empty();
    backend = !scans && !of_type(inputs, "driftlab.point_cloud_t").empty() ? "3d" : "2d";
  }
  if (notes != nullptr) notes->push_back("slam: " + backend + " backend");
  if (backend == "2d") {
    find_inputs(inputs, config, "2d", "scan_channel", "driftlab.laser_scan_t", c->two_d.scan_channel,
                c->two_d.odom_channel, c->two_d.tf_static_channel, notes);
    return std::unique_ptr<Module>(new Slam2d(std::move(c->two_d)));
  }
  find_inputs(inputs, config, "3d", "cloud_channel", "driftlab.point_cloud_t", c->three_d.cloud_channel,
              c->three_d.odom_channel, c->three_d.tf_static_channel, notes);
  return std::unique_ptr<Module>(new Slam3d(std::move(c->three_d)));
}

}  // namespace driftlab::slam
