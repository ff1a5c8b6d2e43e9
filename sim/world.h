// The simulator's static world: boxes and vertical cylinders standing on the floor plane z = 0, loaded from YAML
// (docs/worlds.md). Every length is in metres and every position in the world frame (x, y horizontal, z up).
// Thread-safety: plain value types; the functions are reentrant.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab::sim {

/// A box: `size` is the full extent along its own x, y, z [m]; it is rotated about the vertical through `center`
/// by `yaw` [rad]. Colours are RGB.
struct Box {
  std::string name;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d size = Eigen::Vector3d::Zero();
  double yaw = 0;
  std::array<uint8_t, 3> color{180, 180, 180};
};

/// A cylinder with a vertical axis; `center` is the middle of the cylinder (half way up) [m].
struct Cylinder {
  std::string name;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0;
  double height = 0;
  std::array<uint8_t, 3> color{180, 180, 180};
};

/// Static obstacles on the floor plane z = 0 (the floor is implicit and infinite).
struct World {
  std::vector<Box> boxes;
  std::vector<Cylinder> cylinders;
  double friction = 0.8;  ///< Coulomb friction of the floor and of every obstacle.
  /// The horizontal footprint of every obstacle [m] (the floor excluded); empty when there is none.
  Eigen::AlignedBox2d bounds() const;
};

/// Parses a world description. `origin` names the text in errors ("FILE:LINE: ..."); relative image paths are
/// resolved against `base_dir`. Never throws.
Result<World> parse_world(const std::string& yaml_text, const std::string& origin, const std::string& base_dir);
/// The keys of a world file, from the table parse_world reads it with (`driftlab sim --help-config`).
std::string world_reference();

/// Reads and parses a world file; images are resolved relative to the file's folder.
Result<World> load_world(const std::string& path);

}  // namespace driftlab::sim
