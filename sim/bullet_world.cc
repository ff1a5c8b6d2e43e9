#include "sim/bullet_world.h"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace driftlab::sim {
namespace {

btVector3 bt(const Eigen::Vector3d& v) { return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z())); }

/// Largest distance between a cylinder and its tessellation for ray tests [m].
constexpr double kTessellationError = 1e-5;

/// The 12 triangles of a box.
void add_box(btTriangleMesh& mesh, const Box& b) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(b.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  btVector3 v[8];
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d corner(((i & 1) ? 0.5 : -0.5) * b.size.x(), ((i & 2) ? 0.5 : -0.5) * b.size.y(),
                                 ((i & 4) ? 0.5 : -0.5) * b.size.z());
    v[i] = bt(b.center + R * corner);
  }
  static constexpr int kFaces[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
  for (const auto& f : kFaces) {
    mesh.addTriangle(v[f[0]], v[f[1]], v[f[2]], false);
    mesh.addTriangle(v[f[0]], v[f[2]], v[f[3]], false);
  }
}

/// A prism with enough sides to stay within kTessellationError of the cylinder (vertices slightly outside the
/// circle, so the polygon's sides cross it and the error is spread both ways).
void add_cylinder(btTriangleMesh& mesh, const Cylinder& c) {
  // Error of n sides at radius R = 2r / (1 + cos(pi/n)): about r (pi/n)^2 / 4.
  const int n = std::clamp(static_cast<int>(std::ceil(M_PI / std::sqrt(4 * kTessellationError / c.radius))), 16, 4096);
  const double R = 2 * c.radius / (1 + std::cos(M_PI / n));
  const double z0 = c.center.z() - 0.5 * c.height, z1 = c.center.z() + 0.5 * c.height;
  const btVector3 bottom = bt(Eigen::Vector3d(c.center.x(), c.center.y(), z0));
  const btVector3 top = bt(Eigen::Vector3d(c.center.x(), c.center.y(), z1));
  for (int i = 0; i < n; ++i) {
    const double a0 = 2 * M_PI * i / n, a1 = 2 * M_PI * (i + 1) / n;
    const double x0 = c.center.x() + R * std::cos(a0), y0 = c.center.y() + R * std::sin(a0);
    const double x1 = c.center.x() + R * std::cos(a1), y1 = c.center.y() + R * std::sin(a1);
    const btVector3 p0 = bt({x0, y0, z0}), p1 = bt({x1, y1, z0}), q0 = bt({x0, y0, z1}), q1 = bt({x1, y1, z1});
    mesh.addTriangle(p0, p1, q1, false);
    mesh.addTriangle(p0, q1, q0, false);
    mesh.addTriangle(bottom, p1, p0, false);
    mesh.addTriangle(top, q0, q1, false);
  }
}

}  // namespace

struct BulletWorld::Impl {
  // Members are destroyed in reverse order: each world goes before what it refers to.
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher{&config};
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btCollisionObject>> objects;
  btDiscreteDynamicsWorld dynamics{&dispatcher, &broadphase, &solver, &config};

  // The same obstacles for ray_test: one BVH triangle mesh (exact surfaces) and the floor plane, in a collision
  // world of their own. Bullet ray-tests convex primitives (btBoxShape, btCylinderShape) with a sub-simplex convex
  // cast that stops once within ~1 cm (a fixed tolerance in btSubsimplexConvexCast); triangles are tested exactly,
  // and a static BVH mesh is also what Bullet recommends for static scenery, so it is the fair baseline.
  btCollisionDispatcher ray_dispatcher{&config};
  btDbvtBroadphase ray_broadphase;
  btTriangleMesh mesh{true, false};  // 32-bit indices, 3 components
  std::unique_ptr<btBvhTriangleMeshShape> mesh_shape;
  btStaticPlaneShape ray_floor{btVector3(0, 0, 1), 0};
  btCollisionObject mesh_object, floor_object;
  btCollisionWorld ray_world{&ray_dispatcher, &ray_broadphase, &config};

  ~Impl() {
    for (auto& o : objects) dynamics.removeCollisionObject(o.get());
    ray_world.removeCollisionObject(&floor_object);
    if (mesh_shape) ray_world.removeCollisionObject(&mesh_object);
  }

  void add(std::unique_ptr<btCollisionShape> shape, const btTransform& pose, double friction) {
    auto object = std::make_unique<btCollisionObject>();
    object->setCollisionShape(shape.get());
    object->setWorldTransform(pose);
    object->setFriction(static_cast<btScalar>(friction));
    object->setCollisionFlags(object->getCollisionFlags() | btCollisionObject::CF_STATIC_OBJECT);
    // Asleep, so the world does not refresh its bounding box every step (it never moves).
    object->setActivationState(ISLAND_SLEEPING);
    dynamics.addCollisionObject(object.get(), btBroadphaseProxy::StaticFilter,
                                btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter);
    shapes.push_back(std::move(shape));
    objects.push_back(std::move(object));
  }
};

BulletWorld::BulletWorld(const World& world) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.dynamics.setGravity(btVector3(0, 0, btScalar(-9.81)));
  // Static obstacles never move: skip refreshing their bounding boxes on every step.
  m.dynamics.setForceUpdateAllAabbs(false);
  m.add(std::make_unique<btStaticPlaneShape>(btVector3(0, 0, 1), 0), btTransform::getIdentity(), world.friction);
  for (const Box& b : world.boxes) {
    auto shape = std::make_unique<btBoxShape>(bt(0.5 * b.size));
    shape->setMargin(0);
    m.add(std::move(shape), btTransform(btQuaternion(btVector3(0, 0, 1), btScalar(b.yaw)), bt(b.center)),
          world.friction);
    add_box(m.mesh, b);
  }
  for (const Cylinder& c : world.cylinders) {
    auto shape = std::make_unique<btCylinderShapeZ>(bt(Eigen::Vector3d(c.radius, c.radius, 0.5 * c.height)));
    shape->setMargin(0);
    m.add(std::move(shape), btTransform(btQuaternion::getIdentity(), bt(c.center)), world.friction);
    add_cylinder(m.mesh, c);
  }

  m.floor_object.setCollisionShape(&m.ray_floor);
  m.ray_world.addCollisionObject(&m.floor_object);
  if (m.mesh.getNumTriangles() > 0) {
    m.mesh_shape = std::make_unique<btBvhTriangleMeshShape>(&m.mesh, true);
    m.mesh_object.setCollisionShape(m.mesh_shape.get());
    m.ray_world.addCollisionObject(&m.mesh_object);
  }
}

BulletWorld::~BulletWorld() = default;

btDiscreteDynamicsWorld& BulletWorld::dynamics() { return impl_->dynamics; }

std::optional<double> BulletWorld::ray_test(const Eigen::Vector3d& from, const Eigen::Vector3d& dir,
                                            double max_range) const {
  const btVector3 a = bt(from), b = bt(from + max_range * dir);
  btCollisionWorld::ClosestRayResultCallback result(a, b);
  impl_->ray_world.rayTest(a, b, result);
  if (!result.hasHit()) return std::nullopt;
  return static_cast<double>(result.m_closestHitFraction) * max_range;
}

}  // namespace driftlab::sim
