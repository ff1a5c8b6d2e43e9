// Ray casting in a ~200-box building: RayCaster (grid + DDA) against Bullet's own ray tests on the same world
// (BulletWorld::ray_test: one BVH triangle mesh; and the dynamics world's convex primitives), for a 2D lidar
// (360 horizontal rays) and a 16-ring 3D lidar; and render_camera per 320x240 frame.
// Run: build-helper/bin/raycast_bench ; "per_ray" is the time of one ray, "per_frame" of one image.
#include <benchmark/benchmark.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "sim/bullet_world.h"
#include "sim/camera_render.h"
#include "sim/raycaster.h"

namespace {

using driftlab::sim::Box;
using driftlab::sim::Cylinder;
using driftlab::sim::World;

/// A 40 x 30 m floor of 5 x 4 rooms with doors, furniture and pillars: about 200 boxes and 20 cylinders.
World building() {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(0, 1);
  World w;
  auto wall = [&](double x0, double y0, double x1, double y1) {
    const Eigen::Vector2d a(x0, y0), b(x1, y1);
    w.boxes.push_back({"wall", Eigen::Vector3d(0.5 * (x0 + x1), 0.5 * (y0 + y1), 1.25),
                       Eigen::Vector3d((b - a).norm() + 0.15, 0.15, 2.5), std::atan2(y1 - y0, x1 - x0),
                       {220, 220, 220}});
  };
  wall(0, 0, 40, 0), wall(40, 0, 40, 30), wall(40, 30, 0, 30), wall(0, 30, 0, 0);
  for (int i = 1; i < 5; ++i) {
    for (int j = 0; j < 4; ++j) wall(8 * i, 7.5 * j, 8 * i, 7.5 * j + 3), wall(8 * i, 7.5 * j + 4, 8 * i, 7.5 * (j + 1));
  }
  for (int j = 1; j < 4; ++j) {
    for (int i = 0; i < 5; ++i) wall(8 * i, 7.5 * j, 8 * i + 3.5, 7.5 * j), wall(8 * i + 4.5, 7.5 * j, 8 * (i + 1), 7.5 * j);
  }
  while (w.boxes.size() < 200) {
    const Eigen::Vector3d size(0.3 + u(rng), 0.3 + u(rng), 0.4 + 1.2 * u(rng));
    w.boxes.push_back({"furniture", Eigen::Vector3d(1 + 38 * u(rng), 1 + 28 * u(rng), 0.5 * size.z()), size,
                       2 * M_PI * u(rng), {150, 100, 60}});
  }
  for (int i = 0; i < 20; ++i) {
    w.cylinders.push_back({"pillar", Eigen::Vector3d(1 + 38 * u(rng), 1 + 28 * u(rng), 1.25), 0.15, 2.5, {90, 90, 200}});
  }
  return w;
}

struct Fixture {
  World world = building();
  driftlab::sim::RayCaster caster{world};
  driftlab::sim::BulletWorld bullet{world};
  std::vector<Eigen::Vector3d> origins;  // sensor positions in free space
  Fixture() {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0, 1);
    while (origins.size() < 64) {
      const Eigen::Vector3d p(0.5 + 39 * u(rng), 0.5 + 29 * u(rng), 0.5);
      // Free if a tiny step in every horizontal direction hits nothing.
      bool free = true;
      for (int k = 0; k < 8 && free; ++k) {
        free = std::isinf(caster.range(p, Eigen::Vector3d(std::cos(k * M_PI / 4), std::sin(k * M_PI / 4), 0), 0.3));
      }
      if (free) origins.push_back(p);
    }
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

std::vector<Eigen::Vector3d> lidar_2d() {
  std::vector<Eigen::Vector3d> d;
  for (int i = 0; i < 360; ++i) d.emplace_back(std::cos(i * M_PI / 180), std::sin(i * M_PI / 180), 0);
  return d;
}

std::vector<Eigen::Vector3d> lidar_3d() {  // 16 rings from -15 to +15 degrees, 0.5 degree steps: 11520 rays
  std::vector<Eigen::Vector3d> d;
  for (int ring = 0; ring < 16; ++ring) {
    const double el = (-15 + 2 * ring) * M_PI / 180;
    for (int i = 0; i < 720; ++i) {
      const double az = i * M_PI / 360;
      d.emplace_back(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    }
  }
  return d;
}

constexpr double kMaxRange = 30;

template <typename Cast>
void run(benchmark::State& state, const std::vector<Eigen::Vector3d>& dirs, Cast&& cast) {
  const Fixture& f = fixture();
  size_t k = 0;
  double sum = 0;
  for (auto _ : state) {
    const Eigen::Vector3d& o = f.origins[k++ % f.origins.size()];
    for (const Eigen::Vector3d& d : dirs) {
      const double r = cast(o, d);
      sum += std::isinf(r) ? 0 : r;
    }
  }
  benchmark::DoNotOptimize(sum);
  state.counters["per_ray"] = benchmark::Counter(static_cast<double>(dirs.size()),
                                                 benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

double ours(const Eigen::Vector3d& o, const Eigen::Vector3d& d) { return fixture().caster.range(o, d, kMaxRange); }

double bullet_mesh(const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const auto r = fixture().bullet.ray_test(o, d, kMaxRange);
  return r ? *r : INFINITY;
}

double bullet_primitives(const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const btVector3 a(o.x(), o.y(), o.z()), b(o.x() + kMaxRange * d.x(), o.y() + kMaxRange * d.y(), o.z() + kMaxRange * d.z());
  btCollisionWorld::ClosestRayResultCallback cb(a, b);
  const_cast<driftlab::sim::BulletWorld&>(fixture().bullet).dynamics().rayTest(a, b, cb);
  return cb.hasHit() ? kMaxRange * cb.m_closestHitFraction : INFINITY;
}

void BM_Lidar2D_RayCaster(benchmark::State& s) { run(s, lidar_2d(), ours); }
void BM_Lidar2D_BulletMesh(benchmark::State& s) { run(s, lidar_2d(), bullet_mesh); }
void BM_Lidar2D_BulletPrimitives(benchmark::State& s) { run(s, lidar_2d(), bullet_primitives); }
void BM_Lidar3D_RayCaster(benchmark::State& s) { run(s, lidar_3d(), ours); }
void BM_Lidar3D_BulletMesh(benchmark::State& s) { run(s, lidar_3d(), bullet_mesh); }
void BM_Lidar3D_BulletPrimitives(benchmark::State& s) { run(s, lidar_3d(), bullet_primitives); }

/// One 320x240 frame; arg 0: a level camera 0.3 m up (ground robot), arg 1: pitched down 20 degrees and rolled 5,
/// arg 2: as arg 0 but without the level fast path (render_camera's generic path, for comparison).
void BM_RenderCamera(benchmark::State& state) {
  const Fixture& f = fixture();
  const driftlab::sim::CameraModel model;
  cv::Mat img;
  size_t k = 0;
  for (auto _ : state) {
    const Eigen::Vector3d& o = f.origins[k % f.origins.size()];
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(o.x(), o.y(), state.range(0) == 1 ? 1.2 : 0.3);
    T.linear() = Eigen::AngleAxisd(0.7 * static_cast<double>(k++), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    if (state.range(0) == 1) {
      T.linear() = T.linear() * Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                   Eigen::AngleAxisd(0.087, Eigen::Vector3d::UnitX()).toRotationMatrix();
    }
    if (state.range(0) == 2) {
      driftlab::sim::detail::render_camera_generic(f.caster, model, T, img);
    } else {
      driftlab::sim::render_camera(f.caster, model, T, img);
    }
    benchmark::DoNotOptimize(img.data);
  }
  state.counters["per_frame"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

/// Per-pixel casting with RayCaster::cast, for comparison with render_camera's slices (same frame, same poses).
void BM_RenderCamera_PerPixelCast(benchmark::State& state) {
  const Fixture& f = fixture();
  const driftlab::sim::CameraModel model;
  const double fpx = 0.5 * model.width / std::tan(0.5 * model.hfov);
  size_t k = 0;
  double sum = 0;
  for (auto _ : state) {
    const Eigen::Vector3d o(f.origins[k % f.origins.size()].x(), f.origins[k % f.origins.size()].y(), 0.3);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7 * static_cast<double>(k++), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (int r = 0; r < model.height; ++r) {
      for (int c = 0; c < model.width; ++c) {
        const Eigen::Vector3d d =
            (R * Eigen::Vector3d(1, -(c + 0.5 - 0.5 * model.width) / fpx, -(r + 0.5 - 0.5 * model.height) / fpx)).normalized();
        const auto hit = f.caster.cast(o, d, model.max_range);
        sum += hit ? hit->range : 0;
      }
    }
  }
  benchmark::DoNotOptimize(sum);
  state.counters["per_frame"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

/// The level camera's pose for frame k (as BM_RenderCamera/0).
Eigen::Isometry3d level_pose(size_t k) {
  const Fixture& f = fixture();
  const Eigen::Vector3d& o = f.origins[k % f.origins.size()];
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(o.x(), o.y(), 0.3);
  T.linear() = Eigen::AngleAxisd(0.7 * static_cast<double>(k), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

/// cv::imencode of rendered level 320x240 frames at JPEG quality 80, as sim::Camera calls it (arg 0), with
/// IMWRITE_JPEG_OPTIMIZE on (arg 1, smaller files), progressive (arg 2); the 64 frames are rendered beforehand.
void BM_EncodeJpeg(benchmark::State& state) {
  const Fixture& f = fixture();
  const driftlab::sim::CameraModel model;
  std::vector<cv::Mat> frames(f.origins.size());
  for (size_t k = 0; k < frames.size(); ++k) driftlab::sim::render_camera(f.caster, model, level_pose(k), frames[k]);
  std::vector<int> params{cv::IMWRITE_JPEG_QUALITY, 80};
  if (state.range(0) == 1) params.insert(params.end(), {cv::IMWRITE_JPEG_OPTIMIZE, 1});
  if (state.range(0) == 2) params.insert(params.end(), {cv::IMWRITE_JPEG_PROGRESSIVE, 1});
  size_t k = 0, bytes = 0;
  for (auto _ : state) {
    std::vector<uint8_t> out;  // sim::Camera encodes into a fresh message each frame
    cv::imencode(".jpg", frames[k++ % frames.size()], out, params);
    bytes += out.size();
  }
  state.counters["per_frame"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["bytes"] = static_cast<double>(bytes) / static_cast<double>(std::max<size_t>(k, 1));
}

/// What sim::Camera spends per level 320x240 frame: render_camera, then cv::imencode at JPEG quality 80.
void BM_CameraFrame(benchmark::State& state) {
  const Fixture& f = fixture();
  const driftlab::sim::CameraModel model;
  const std::vector<int> params{cv::IMWRITE_JPEG_QUALITY, 80};
  cv::Mat img;
  size_t k = 0;
  for (auto _ : state) {
    driftlab::sim::render_camera(f.caster, model, level_pose(k++), img);
    std::vector<uint8_t> out;
    cv::imencode(".jpg", img, out, params);
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["per_frame"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

}  // namespace

BENCHMARK(BM_Lidar2D_RayCaster)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Lidar2D_BulletMesh)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Lidar2D_BulletPrimitives)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Lidar3D_RayCaster)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Lidar3D_BulletMesh)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Lidar3D_BulletPrimitives)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderCamera)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderCamera_PerPixelCast)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EncodeJpeg)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CameraFrame)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
