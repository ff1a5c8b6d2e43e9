// RayCaster::cast / range / spans: hand-checked cases, and thousands of random rays against BulletWorld::ray_test
// (Bullet's own ray test) in a building-like world.
#include "sim/raycaster.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <thread>

#include "sim/bullet_world.h"

#include <btBulletDynamicsCommon.h>

namespace driftlab::sim {
namespace {

/// n uniform draws in order (the order in which function arguments are evaluated is unspecified, so drawing
/// inside one call would give different worlds with different compilers).
template <int N>
std::array<double, N> draw(std::uniform_real_distribution<double>& u, std::mt19937_64& rng) {
  std::array<double, N> a;
  for (double& x : a) x = u(rng);
  return a;
}

/// A 24 x 16 m building: outer walls, interior walls with door gaps, furniture (yawed boxes, some raised off the
/// floor), pillars; seeded.
World building(uint64_t seed, int furniture = 60, int pillars = 20) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  World w;
  auto wall = [&](double x0, double y0, double x1, double y1) {
    const Eigen::Vector2d a(x0, y0), b(x1, y1);
    w.boxes.push_back({"wall", Eigen::Vector3d(0.5 * (x0 + x1), 0.5 * (y0 + y1), 1.25),
                       Eigen::Vector3d((b - a).norm() + 0.15, 0.15, 2.5), std::atan2(y1 - y0, x1 - x0),
                       {200, 200, 200}});
  };
  wall(0, 0, 24, 0), wall(24, 0, 24, 16), wall(24, 16, 0, 16), wall(0, 16, 0, 0);
  for (int i = 1; i < 4; ++i) wall(6 * i, 0, 6 * i, 6.5), wall(6 * i, 8, 6 * i, 16);  // doors at y 6.5..8
  wall(0, 8, 10, 8), wall(11.2, 8, 24, 8);
  wall(14, 12, 17, 15);  // a slanted wall
  for (int i = 0; i < furniture; ++i) {
    const auto s = draw<3>(u, rng);
    const Eigen::Vector3d size(0.2 + 1.2 * s[0], 0.2 + 1.2 * s[1], 0.2 + 1.5 * s[2]);
    const auto f = draw<2>(u, rng);
    const double z = f[0] < 0.25 ? 0.5 * size.z() + 0.3 + f[1] : 0.5 * size.z();  // some float (shelves)
    const auto c = draw<3>(u, rng);
    w.boxes.push_back({"f", Eigen::Vector3d(1 + 22 * c[0], 1 + 14 * c[1], z), size, 2 * M_PI * c[2],
                       {static_cast<uint8_t>(rng()), static_cast<uint8_t>(rng()), static_cast<uint8_t>(rng())}});
  }
  for (int i = 0; i < pillars; ++i) {
    const auto c = draw<5>(u, rng);
    const double h = 0.3 + 2.5 * c[0];
    w.cylinders.push_back({"p", Eigen::Vector3d(1 + 22 * c[1], 1 + 14 * c[2], c[3] < 0.2 ? h : 0.5 * h),
                           0.05 + 0.4 * c[4], h, {10, 200, 30}});
  }
  return w;
}

bool inside_any(const World& w, const Eigen::Vector3d& p) {
  for (const Box& b : w.boxes) {
    const Eigen::Vector2d q = Eigen::Rotation2Dd(-b.yaw) * (p.head<2>() - b.center.head<2>());
    if (std::abs(q.x()) <= 0.5 * b.size.x() + 1e-3 && std::abs(q.y()) <= 0.5 * b.size.y() + 1e-3 &&
        std::abs(p.z() - b.center.z()) <= 0.5 * b.size.z() + 1e-3) {
      return true;
    }
  }
  for (const Cylinder& c : w.cylinders) {
    if ((p.head<2>() - c.center.head<2>()).norm() <= c.radius + 1e-3 &&
        std::abs(p.z() - c.center.z()) <= 0.5 * c.height + 1e-3) {
      return true;
    }
  }
  return false;
}

Eigen::Vector3d random_direction(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  Eigen::Vector3d d;
  do {
    const double x = g(rng), y = g(rng), z = g(rng);
    d = Eigen::Vector3d(x, y, z);
  }
  while (d.norm() < 1e-3);
  return d.normalized();
}

TEST(RayCaster, BoxFaceRangeNormalAndColour) {
  World w;
  w.boxes.push_back({"red", {5, 0, 0.5}, {2, 2, 1}, 0, {255, 0, 0}});
  w.cylinders.push_back({"c", {0, 5, 1}, 0.5, 2, {0, 0, 255}});
  const RayCaster rc(w);
  auto hit = rc.cast({0, 0, 0.5}, {1, 0, 0}, 100);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->range, 4, 1e-12);
  EXPECT_TRUE(hit->normal.isApprox(Eigen::Vector3d(-1, 0, 0)));
  EXPECT_EQ(hit->object, 0);
  EXPECT_EQ(hit->color, (std::array<uint8_t, 3>{255, 0, 0}));
  // The cylinder's side, then its top from above.
  hit = rc.cast({0, 0, 1}, {0, 1, 0}, 100);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->range, 4.5, 1e-12);
  EXPECT_TRUE(hit->normal.isApprox(Eigen::Vector3d(0, -1, 0)));
  EXPECT_EQ(hit->object, 1);
  hit = rc.cast({0, 5.2, 3}, {0, 0, -1}, 100);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->range, 1, 1e-12);
  EXPECT_TRUE(hit->normal.isApprox(Eigen::Vector3d(0, 0, 1)));
  // The floor, at 45 degrees down.
  hit = rc.cast({0, 0, 1}, Eigen::Vector3d(-1, 0, -1).normalized(), 100);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->range, std::sqrt(2.0), 1e-12);
  EXPECT_EQ(hit->object, -1);
  EXPECT_TRUE(hit->normal.isApprox(Eigen::Vector3d::UnitZ()));
  // Nothing up there; nothing within a short max_range; range() gives +inf.
  EXPECT_FALSE(rc.cast({0, 0, 1}, Eigen::Vector3d(-1, 0, 1).normalized(), 100));
  EXPECT_FALSE(rc.cast({0, 0, 0.5}, {1, 0, 0}, 3.9));
  EXPECT_TRUE(std::isinf(rc.range({0, 0, 0.5}, {-1, 0, 0}, 50)));
  EXPECT_NEAR(rc.range({0, 0, 0.5}, {1, 0, 0}, 50), 4, 1e-12);
}

TEST(RayCaster, YawedBoxAndRaysFromOutsideTheGrid) {
  World w;
  w.boxes.push_back({"diamond", {0, 0, 1}, {2, 2, 2}, M_PI / 4, {1, 2, 3}});
  const RayCaster rc(w);
  // From far outside the grid: the corner of the diamond is at x = -sqrt(2).
  auto hit = rc.cast({-50, 0, 1}, {1, 0, 0}, 100);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->range, 50 - std::sqrt(2.0), 1e-9);
  hit = rc.cast({-50, 0.5, 1}, {1, 0, 0}, 100);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->range, 50 - (std::sqrt(2.0) - 0.5), 1e-9);
  EXPECT_TRUE(hit->normal.isApprox(Eigen::Vector3d(-1, 1, 0).normalized()));
  // Passing beside it, it reaches the floor.
  hit = rc.cast({-50, 3, 1}, Eigen::Vector3d(1, 0, -0.01).normalized(), 1000);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->object, -1);
  // A ray that starts inside the box does not see it.
  EXPECT_FALSE(rc.cast({0, 0, 1}, {0, 0, 1}, 100));
}

TEST(RayCaster, GridSizeDoesNotChangeResults) {
  const World w = building(3);
  const RayCaster fine(w, 0.13), normal(w), coarse(w, 1000);  // coarse: one cell holding everything
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 20000; ++i) {
    const auto r = draw<3>(u, rng);
    const Eigen::Vector3d o(-5 + 34 * r[0], -5 + 26 * r[1], 0.01 + 4 * r[2]);
    const Eigen::Vector3d d = random_direction(rng);
    const auto a = fine.cast(o, d, 40), b = normal.cast(o, d, 40), c = coarse.cast(o, d, 40);
    ASSERT_EQ(a.has_value(), c.has_value()) << i;
    ASSERT_EQ(b.has_value(), c.has_value()) << i;
    if (c) {
      ASSERT_EQ(a->object, c->object) << i;
      ASSERT_EQ(b->object, c->object) << i;
      ASSERT_DOUBLE_EQ(a->range, c->range);
      ASSERT_DOUBLE_EQ(b->range, c->range);
      ASSERT_TRUE(b->normal.isApprox(c->normal));
    }
  }
}

TEST(RayCaster, AgreesWithBulletOnRandomRaysInABuilding) {
  for (uint64_t seed : {1, 2, 3}) {
    const World w = building(seed);
    const RayCaster rc(w);
    const BulletWorld bullet(w);
    // The same world grown by 0.1 mm: a ray that grazes an edge closer than that may be a hit for Bullet (float
    // triangles) and a miss for us (double); it must then be a hit in the grown world, at Bullet's range.
    World grown = w;
    for (Box& b : grown.boxes) b.size.array() += 2e-4;
    for (Cylinder& c : grown.cylinders) c.radius += 1e-4, c.height += 2e-4;
    const RayCaster rc_grown(grown);
    std::mt19937_64 rng(seed * 77);
    std::uniform_real_distribution<double> u(0, 1);
    const double max_range = 12;
    int hits = 0, floor_hits = 0, cylinder_hits = 0, misses = 0, rays = 0, grazing = 0;
    while (rays < 5000) {
      const auto r = draw<3>(u, rng);
      const Eigen::Vector3d o(0.2 + 23.6 * r[0], 0.2 + 15.6 * r[1], 0.05 + 2.6 * r[2]);
      if (inside_any(w, o)) continue;
      ++rays;
      const Eigen::Vector3d d = random_direction(rng);
      const auto ours = rc.cast(o, d, max_range);
      const auto ref = bullet.ray_test(o, d, max_range);
      const std::string where = "seed " + std::to_string(seed) + " ray from " + std::to_string(o.x()) + "," +
                                std::to_string(o.y()) + "," + std::to_string(o.z()) + " along " +
                                std::to_string(d.x()) + "," + std::to_string(d.y()) + "," + std::to_string(d.z());
      if (ref && (!ours || std::abs(ours->range - *ref) > 1e-3)) {
        const auto g = rc_grown.cast(o, d, max_range);
        if (g && std::abs(g->range - *ref) < 1e-3) {
          ++grazing;
          continue;
        }
      }
      if (ours && ref) {
        EXPECT_NEAR(ours->range, *ref, 1e-3) << where << " object " << ours->object;
        ++hits;
        floor_hits += ours->object == -1;
        cylinder_hits += ours->object >= static_cast<int>(w.boxes.size());
      } else {
        // Only a hit within rounding of max_range may be seen by one and not the other.
        const double r = ours ? ours->range : ref ? *ref : 0;
        EXPECT_TRUE((!ours && !ref) || r > max_range - 1e-3) << where << (ours ? " only ours" : " only Bullet's");
        misses += !ours && !ref;
      }
    }
    // The random rays exercised every kind of surface.
    EXPECT_GT(floor_hits, 500);
    EXPECT_GT(cylinder_hits, 20);
    EXPECT_GT(hits - floor_hits - cylinder_hits, 1000);
    EXPECT_GT(misses, 10);
    EXPECT_LE(grazing, 5);  // out of 5000
  }
}

// The dynamics world's primitives (btBoxShape, btCylinderShapeZ) sit where the World says: Bullet's ray test on them
// (a convex cast that stops within ~1 cm) lands on the same surfaces.
TEST(BulletWorld, DynamicsPrimitivesMatchTheWorld) {
  const World w = building(2);
  const RayCaster rc(w);
  BulletWorld bullet(w);
  EXPECT_EQ(bullet.dynamics().getNumCollisionObjects(), static_cast<int>(1 + w.boxes.size() + w.cylinders.size()));
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(0, 1);
  int rays = 0, close = 0;
  while (rays < 3000) {
    const auto r = draw<3>(u, rng);
      const Eigen::Vector3d o(0.2 + 23.6 * r[0], 0.2 + 15.6 * r[1], 0.05 + 2.6 * r[2]);
    if (inside_any(w, o)) continue;
    ++rays;
    const Eigen::Vector3d d = random_direction(rng);
    const btVector3 a(o.x(), o.y(), o.z()), b(o.x() + 12 * d.x(), o.y() + 12 * d.y(), o.z() + 12 * d.z());
    btCollisionWorld::ClosestRayResultCallback cb(a, b);
    bullet.dynamics().rayTest(a, b, cb);
    const double ours = rc.range(o, d, 12);
    const double theirs = cb.hasHit() ? 12.0 * cb.m_closestHitFraction : std::numeric_limits<double>::infinity();
    close += (std::isinf(ours) && std::isinf(theirs)) || std::abs(ours - theirs) < 0.03;
  }
  EXPECT_GT(close, rays * 0.98);
}

TEST(BulletWorld, ABallDroppedOnABoxRestsOnItsTop) {
  World w;
  w.boxes.push_back({"table", {0, 0, 0.4}, {1, 1, 0.8}, 0.5, {}});
  BulletWorld bullet(w);
  btSphereShape sphere(0.1);
  btVector3 inertia;
  sphere.calculateLocalInertia(1, inertia);
  btDefaultMotionState motion(btTransform(btQuaternion::getIdentity(), btVector3(0.1, 0, 2)));
  btRigidBody ball(btRigidBody::btRigidBodyConstructionInfo(1, &motion, &sphere, inertia));
  bullet.dynamics().addRigidBody(&ball);
  for (int i = 0; i < 1000; ++i) bullet.dynamics().stepSimulation(1.0 / 500, 0);
  const btVector3 p = ball.getWorldTransform().getOrigin();
  bullet.dynamics().removeRigidBody(&ball);
  EXPECT_NEAR(p.z(), 0.9, 0.01);
  EXPECT_NEAR(p.x(), 0.1, 0.01);
}

TEST(RayCaster, SpansMatchHorizontalCasts) {
  const World w = building(4);
  const RayCaster rc(w);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Span> spans;
  for (int i = 0; i < 3000; ++i) {
    const auto r = draw<3>(u, rng);
      const Eigen::Vector3d o(0.2 + 23.6 * r[0], 0.2 + 15.6 * r[1], 0.05 + 2.6 * r[2]);
    if (inside_any(w, o)) continue;
    const double a = 2 * M_PI * u(rng);
    const Eigen::Vector3d d(std::cos(a), std::sin(a), 0);
    rc.spans(o.head<2>(), d.head<2>(), 30, spans);
    ASSERT_TRUE(std::is_sorted(spans.begin(), spans.end(),
                               [](const Span& x, const Span& y) { return x.s_in < y.s_in; }));
    // The first span at the ray's height is what the caster hits.
    const Span* first = nullptr;
    for (const Span& s : spans) {
      if (s.s_in > 0 && o.z() >= s.z_min && o.z() <= s.z_max) {
        first = &s;
        break;
      }
    }
    const auto hit = rc.cast(o, d, 30);
    ASSERT_EQ(first != nullptr, hit.has_value()) << i;
    if (first != nullptr) {
      EXPECT_NEAR(first->s_in, hit->range, 1e-9);
      // Where two walls meet, their faces coincide: either may be reported.
      if (first->object == hit->object) {
        EXPECT_TRUE(Eigen::Vector3d(first->normal.x(), first->normal.y(), 0).isApprox(hit->normal, 1e-9));
      } else {
        const Span& other = *std::find_if(spans.begin(), spans.end(), [&](const Span& s) { return s.object == hit->object; });
        EXPECT_NEAR(other.s_in, first->s_in, 1e-9) << i;
      }
    }
  }
}

TEST(RayCaster, ConstCastsRunConcurrently) {
  const World w = building(6);
  const RayCaster rc(w);
  std::vector<Eigen::Vector3d> origins, dirs;
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 20000; ++i) {
    const auto r = draw<3>(u, rng);
    origins.emplace_back(24 * r[0], 16 * r[1], 0.1 + 2 * r[2]);
    dirs.push_back(random_direction(rng));
  }
  std::vector<double> expected(origins.size()), got(origins.size());
  for (size_t i = 0; i < origins.size(); ++i) expected[i] = rc.range(origins[i], dirs[i], 20);
  std::thread t1([&] {
    for (size_t i = 0; i < origins.size(); i += 2) got[i] = rc.range(origins[i], dirs[i], 20);
  });
  std::thread t2([&] {
    for (size_t i = 1; i < origins.size(); i += 2) got[i] = rc.range(origins[i], dirs[i], 20);
  });
  t1.join();
  t2.join();
  EXPECT_EQ(got, expected);
}

}  // namespace
}  // namespace driftlab::sim
