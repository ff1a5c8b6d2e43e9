// render_camera: what a camera sees in simple scenes, and pixel-by-pixel agreement with RayCaster::cast.
#include "sim/camera_render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

namespace driftlab::sim {
namespace {

std::array<uint8_t, 3> rgb_at(const cv::Mat& bgr, int row, int col) {
  const cv::Vec3b p = bgr.at<cv::Vec3b>(row, col);
  return {p[2], p[1], p[0]};
}

bool reddish(const std::array<uint8_t, 3>& c) { return c[0] > 80 && c[1] < 10 && c[2] < 10; }

Eigen::Isometry3d pose(double x, double y, double z, double yaw, double pitch = 0, double roll = 0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  return T;
}

TEST(RenderCamera, RedBoxAheadFillsTheCentre) {
  World w;
  w.boxes.push_back({"red", {4, 0, 1}, {1, 2, 2}, 0.2, {255, 0, 0}});
  const RayCaster rc(w);
  cv::Mat img;
  const CameraModel model;
  render_camera(rc, model, pose(0, 0, 0.5, 0), img);
  ASSERT_EQ(img.type(), CV_8UC3);
  ASSERT_EQ(img.cols, 320);
  ASSERT_EQ(img.rows, 240);
  EXPECT_TRUE(reddish(rgb_at(img, 120, 160)));
  // Turned away, the centre sees no red anywhere.
  render_camera(rc, model, pose(0, 0, 0.5, M_PI), img);
  int red = 0;
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) red += reddish(rgb_at(img, r, c));
  EXPECT_EQ(red, 0);
}

TEST(RenderCamera, EmptySpaceIsFloorBelowTheHorizonAndSkyAbove) {
  World w;
  w.boxes.push_back({"far away", {100, 100, 1}, {1, 1, 2}, 0, {255, 0, 0}});
  const RayCaster rc(w);
  cv::Mat img;
  CameraModel model;
  model.width = 160;
  model.height = 120;
  render_camera(rc, model, pose(0.5, 0.5, 1.0, 0.3), img);
  ASSERT_EQ(img.cols, 160);
  for (int c = 0; c < img.cols; ++c) {
    EXPECT_EQ(rgb_at(img, 0, c), kSkyColor) << c;
    EXPECT_EQ(rgb_at(img, 59, c), kSkyColor) << c;  // just above the horizon
    const auto floor = rgb_at(img, 119, c);
    EXPECT_NE(floor, kSkyColor);
    EXPECT_EQ(floor[0], floor[1]);  // grey
  }
  // The checkerboard: the bottom row crosses squares of both shades.
  std::set<int> shades;
  for (int c = 0; c < img.cols; ++c) shades.insert(rgb_at(img, 119, c)[0]);
  EXPECT_GE(shades.size(), 2u);
}

/// The colour class of what RayCaster::cast says a pixel sees: the object index, -1 floor, -2 sky.
int cast_class(const RayCaster& rc, const CameraModel& m, const Eigen::Isometry3d& T, int row, int col) {
  const double f = 0.5 * m.width / std::tan(0.5 * m.hfov);
  const double u = (col + 0.5 - 0.5 * m.width) / f, v = (row + 0.5 - 0.5 * m.height) / f;
  const Eigen::Vector3d d = (T.linear() * Eigen::Vector3d(1, -u, -v)).normalized();
  const auto hit = rc.cast(T.translation(), d, m.max_range);
  return hit ? hit->object : -2;
}

TEST(RenderCamera, AgreesWithPerPixelCastingLevelAndTilted) {
  // Every obstacle a pure hue that no floor/sky pixel has: the rendered hue tells which object a pixel shows.
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(0, 1);
  World w;
  const std::array<std::array<uint8_t, 3>, 3> hues{{{255, 0, 0}, {0, 255, 0}, {0, 0, 255}}};
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector3d size(0.3 + u(rng), 0.3 + u(rng), 0.3 + 2 * u(rng));
    w.boxes.push_back({"b", Eigen::Vector3d(-8 + 16 * u(rng), -8 + 16 * u(rng), 0.5 * size.z() + (i % 5 == 0)), size,
                       3 * u(rng), hues[i % 3]});
  }
  for (int i = 0; i < 15; ++i) {
    w.cylinders.push_back({"c", Eigen::Vector3d(-8 + 16 * u(rng), -8 + 16 * u(rng), 0.6), 0.1 + 0.3 * u(rng), 1.2,
                           hues[i % 3]});
  }
  const RayCaster rc(w);
  CameraModel model;
  const Eigen::Isometry3d poses[] = {pose(0, 0, 0.4, 0.1), pose(-9, -9, 1.5, 0.8), pose(0, 0, 3, 2.0, 0.5),
                                     pose(1, -1, 0.6, -1.0, -0.2, 0.3), pose(0, 0, 5, 0, M_PI / 2)};
  for (const auto& T : poses) {
    cv::Mat img;
    render_camera(rc, model, T, img);
    int agree = 0, objects = 0;
    for (int r = 0; r < img.rows; ++r) {
      for (int c = 0; c < img.cols; ++c) {
        const int k = cast_class(rc, model, T, r, c);
        const auto px = rgb_at(img, r, c);
        bool same;
        if (k == -2) {
          same = px == kSkyColor || (px[0] == px[1] && px[1] > 0);  // sky, or floor beyond max_range
        } else if (k == -1) {
          same = px[0] == px[1] && std::abs(px[1] - px[2]) < 20;  // floor grey
        } else {
          ++objects;
          const auto& hue = rc.num_objects() > k ? (k < 40 ? w.boxes[k].color : w.cylinders[k - 40].color) : hues[0];
          same = true;
          for (int ch = 0; ch < 3; ++ch) same = same && ((hue[ch] == 0) == (px[ch] == 0));
        }
        agree += same;
      }
    }
    const int total = img.rows * img.cols;
    EXPECT_GT(objects, total / 50) << "pose " << T.translation().transpose();
    EXPECT_GT(agree, total * 0.995) << "pose " << T.translation().transpose() << ": " << total - agree
                                    << " pixels differ";
  }
}

TEST(RenderCamera, LevelFastPathAgreesWithGenericPath) {
  // render_camera draws a (nearly) level camera column by column; detail::render_camera_generic is the path used
  // for any other orientation. Same scene as above, with boxes floating 1 m up (their bottoms visible).
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  World w;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector3d size(0.3 + u(rng), 0.3 + u(rng), 0.3 + 2 * u(rng));
    w.boxes.push_back({"b", Eigen::Vector3d(-8 + 16 * u(rng), -8 + 16 * u(rng), 0.5 * size.z() + (i % 5 == 0)), size,
                       3 * u(rng), {static_cast<uint8_t>(40 + 5 * i), 200, 30}});
  }
  for (int i = 0; i < 15; ++i) {
    w.cylinders.push_back({"c", Eigen::Vector3d(-8 + 16 * u(rng), -8 + 16 * u(rng), 0.6), 0.1 + 0.3 * u(rng), 1.2,
                           {250, static_cast<uint8_t>(10 * i), 90}});
  }
  w.boxes.push_back({"around the camera", {3, 3, 1}, {1, 1, 2}, 0, {255, 255, 0}});
  const RayCaster rc(w);
  struct Case {
    Eigen::Isometry3d pose;
    CameraModel model;
  };
  CameraModel small;
  small.width = 161, small.height = 97, small.hfov = 1.9, small.max_range = 6;
  const Case cases[] = {{pose(0, 0, 0.3, 0.1), {}},
                        {pose(-9, -9, 1.5, 0.8), {}},
                        {pose(1, -2, 0.4, 2.5, 1e-4, -2e-4), {}},  // nearly level
                        {pose(3, 3, 0.5, -0.7), {}},               // inside a box: it is not seen
                        {pose(0, 0, 0.3, 4.0), small},
                        {pose(0, 0, -0.5, 0.3), {}}};              // below the floor
  for (const Case& k : cases) {
    cv::Mat fast, generic;
    render_camera(rc, k.model, k.pose, fast);
    detail::render_camera_generic(rc, k.model, k.pose, generic);
    ASSERT_EQ(fast.size, generic.size);
    ASSERT_EQ(fast.type(), generic.type());
    int differ = 0;
    for (int r = 0; r < fast.rows; ++r) {
      for (int c = 0; c < fast.cols; ++c) {
        const cv::Vec3b a = fast.at<cv::Vec3b>(r, c), b = generic.at<cv::Vec3b>(r, c);
        for (int ch = 0; ch < 3; ++ch) differ += std::abs(a[ch] - b[ch]) > 2 ? 1 : 0;
      }
    }
    // The generic path takes each pixel's azimuth to within an eighth of a pixel, the fast path exactly: they may
    // differ along silhouettes only.
    EXPECT_LT(differ, 0.005 * fast.rows * fast.cols) << "pose " << k.pose.translation().transpose();
  }
}

}  // namespace
}  // namespace driftlab::sim
