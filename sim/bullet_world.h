// The Bullet side of a World: a dynamics world with the floor and every obstacle as static collision objects.
// World frame, metres. The robot parts of the simulator add their bodies to dynamics().
// Thread-safety: not thread-safe (Bullet's world is mutable); ray_test may run concurrently with other const calls
// only while nobody steps or edits the dynamics world.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>

#include "sim/world.h"

class btDiscreteDynamicsWorld;

namespace driftlab::sim {

/// Owns a btDiscreteDynamicsWorld with gravity -9.81 m/s^2 along z, a static floor plane z = 0 and one static
/// btCollisionObject per box/cylinder (btBoxShape, btCylinderShapeZ), all with the World's friction. Obstacles have a
/// zero collision margin so that their surfaces are exactly the World's (moving bodies keep Bullet's default margin,
/// which gives contacts slack). Static objects use the StaticFilter collision group.
class BulletWorld {
 public:
  explicit BulletWorld(const World& world);
  ~BulletWorld();
  BulletWorld(const BulletWorld&) = delete;
  BulletWorld& operator=(const BulletWorld&) = delete;

  btDiscreteDynamicsWorld& dynamics();

  /// Bullet's own closest-hit ray test from `from` along the unit vector `dir` up to max_range [m]: the range [m]
  /// of the first surface hit, or nullopt. (The reference the RayCaster is checked against, and the "generic"
  /// baseline in benchmarks.) It runs on a separate Bullet collision world holding the same obstacles as one BVH
  /// triangle mesh (cylinders within 1e-5 m) plus the floor plane: Bullet's ray test on convex primitives stops
  /// within ~1 cm, on triangles it is exact to float precision. Bodies added to dynamics() are not seen.
  std::optional<double> ray_test(const Eigen::Vector3d& from, const Eigen::Vector3d& dir, double max_range) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace driftlab::sim
