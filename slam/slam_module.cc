#include "slam/slam_module.h"

#include "core/internal/yaml_fields.h"
#include "slam/slam2d.h"
#include "slam/slam3d.h"

namespace driftlab::slam {

Result<std::unique_ptr<Module>> make_slam(const YAML::Node& config, const std::string& origin, const HasData& has_data,
                                          std::string* chosen) {
  std::string backend = "auto";
  YAML::Node two_d, three_d;
  if (config.IsDefined() && !config.IsNull()) {
    try {
      Fields f(config, origin, "slam");
      DL_TRY(f.is_map());
      DL_TRY(f.text("backend", backend));
      two_d = f.node("2d");
      three_d = f.node("3d");
      DL_TRY(f.finish("backend, 2d, 3d"));
    } catch (const YAML::Exception& e) {
      return Error{origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
    }
    if (backend != "auto" && backend != "2d" && backend != "3d") {
      return Error{at(origin, config["backend"]) + ": slam.backend = " + backend + " must be auto, 2d or 3d"};
    }
  }
  // Both settings are read, so a bad key is reported whichever backend runs.
  auto c2 = parse_slam2d_config(two_d, origin);
  if (!c2) return c2.error();
  auto c3 = parse_slam3d_config(three_d, origin);
  if (!c3) return c3.error();
  if (backend == "auto") {
    const bool scans = has_data(c2->scan_channel, "driftlab.laser_scan_t");
    backend = !scans && has_data(c3->cloud_channel, "driftlab.point_cloud_t") ? "3d" : "2d";
  }
  if (chosen != nullptr) *chosen = backend;
  if (backend == "2d") return std::unique_ptr<Module>(new Slam2d(std::move(*c2)));
  return std::unique_ptr<Module>(new Slam3d(std::move(*c3)));
}

}  // namespace driftlab::slam
