#include "slam/slam_module.h"

#include "core/internal/yaml_fields.h"
#include "slam/slam2d.h"

namespace driftlab::slam {

Result<std::unique_ptr<Module>> make_slam(const YAML::Node& config, const std::string& origin) {
  std::string backend = "2d";
  YAML::Node two_d;
  if (config.IsDefined() && !config.IsNull()) {
    try {
      Fields f(config, origin, "slam");
      DL_TRY(f.is_map());
      DL_TRY(f.text("backend", backend));
      two_d = f.node("2d");
      DL_TRY(f.finish("backend, 2d"));
    } catch (const YAML::Exception& e) {
      return Error{origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
    }
    if (backend != "2d") return Error{at(origin, config["backend"]) + ": slam.backend = " + backend + " must be 2d"};
  }
  auto c = parse_slam2d_config(two_d, origin);
  if (!c) return c.error();
  return std::unique_ptr<Module>(new Slam2d(std::move(*c)));
}

}  // namespace driftlab::slam
