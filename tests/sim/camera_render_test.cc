// render_camera: what a camera sees in simple scenes, and pixel-by-pixel agreement with RayCaster::cast.
#include "sim/camera_render.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

namespace driftlab::sim {
namespace {

std::array<uint8_t, 3> rgb_at(const cv::Mat& bgr, int row, int col) {
  const cv::Vec3b p = bgr.at<cv::Vec3b>(row, col);
  return {p[2], p[1], p[0]};
}

/// n uniform draws in order (the order in which function arguments are evaluated is unspecified, so drawing
/// inside one call would give different worlds with different compilers).
/// kGccOrder: the scenes below were tuned with the draws inside the constructors' arguments, which gcc evaluates
/// last to first (a braced list is evaluated first to last); the draws are used in that order so that every
/// compiler builds those same scenes.
template <int N>
std::array<double, N> draw(std::uniform_real_distribution<double>& u, std::mt19937_64& rng) {
  std::array<double, N> a;
  for (double& x : a) x = u(rng);
  return a;
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
    const auto r = draw<6>(u, rng);  // in the order gcc used to draw them (see kGccOrder)
    const Eigen::Vector3d size(0.3 + r[2], 0.3 + r[1], 0.3 + 2 * r[0]);
    w.boxes.push_back({"b", Eigen::Vector3d(-8 + 16 * r[4], -8 + 16 * r[3], 0.5 * size.z() + (i % 5 == 0)), size,
                       3 * r[5], hues[i % 3]});
  }
  for (int i = 0; i < 15; ++i) {
    const auto r = draw<3>(u, rng);
    w.cylinders.push_back({"c", Eigen::Vector3d(-8 + 16 * r[1], -8 + 16 * r[0], 0.6), 0.1 + 0.3 * r[2], 1.2,
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
    const auto r = draw<6>(u, rng);  // in the order gcc used to draw them (see kGccOrder)
    const Eigen::Vector3d size(0.3 + r[2], 0.3 + r[1], 0.3 + 2 * r[0]);
    w.boxes.push_back({"b", Eigen::Vector3d(-8 + 16 * r[4], -8 + 16 * r[3], 0.5 * size.z() + (i % 5 == 0)), size,
                       3 * r[5], {static_cast<uint8_t>(40 + 5 * i), 200, 30}});
  }
  for (int i = 0; i < 15; ++i) {
    const auto r = draw<3>(u, rng);
    w.cylinders.push_back({"c", Eigen::Vector3d(-8 + 16 * r[1], -8 + 16 * r[0], 0.6), 0.1 + 0.3 * r[2], 1.2,
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

TEST(RenderCamera, SpansUntilHandsOverWhatSpansReturns) {
  // RayCaster::spans_until (which the level fast path uses to stop early) hands over spans() in order, in prefixes.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  World w;
  for (int i = 0; i < 80; ++i) {
    const auto r = draw<6>(u, rng);
    w.boxes.push_back({"b", Eigen::Vector3d(-8 + 16 * r[0], -8 + 16 * r[1], 0.5 + r[2]),
                       Eigen::Vector3d(0.1 + 2 * r[3], 0.1 + r[4], 1), 3 * r[5], {1, 2, 3}});
  }
  for (int i = 0; i < 20; ++i) {
    const auto r = draw<3>(u, rng);
    w.cylinders.push_back({"c", Eigen::Vector3d(-8 + 16 * r[0], -8 + 16 * r[1], 0.5), 0.05 + 0.5 * r[2], 1, {4, 5, 6}});
  }
  const RayCaster rc(w, 0.7);
  std::vector<Span> expected, got, pending;
  for (int k = 0; k < 500; ++k) {
    const auto r = draw<4>(u, rng);
    const Eigen::Vector2d origin(-10 + 20 * r[0], -10 + 20 * r[1]);
    // Some rays along the grid's axes and diagonals.
    const double angle = k % 5 == 0 ? M_PI / 4 * std::floor(8 * r[2]) : 2 * M_PI * r[2];
    const Eigen::Vector2d dir(std::cos(angle), std::sin(angle));
    const double max_s = 3 + 25 * r[3];
    rc.spans(origin, dir, max_s, expected);
    size_t calls = 0, seen = 0;
    double last_done = -INFINITY;
    rc.spans_until(origin, dir, max_s, got, pending, [&](const std::vector<Span>& out, size_t first, double s_done) {
      EXPECT_EQ(first, seen);
      EXPECT_GE(s_done, last_done);
      for (size_t i = first; i < out.size(); ++i) {
        EXPECT_LE(out[i].s_in, s_done);
        if (i > 0) {
          EXPECT_LE(out[i - 1].s_in, out[i].s_in);
        }
      }
      // Nothing left out that starts before s_done.
      for (const Span& e : expected) {
        if (e.s_in <= s_done) {
          EXPECT_TRUE(std::any_of(out.begin(), out.end(), [&](const Span& o) { return o.object == e.object; }));
        }
      }
      seen = out.size(), last_done = s_done, ++calls;
      return true;
    });
    EXPECT_GE(calls, 1u);
    ASSERT_EQ(got.size(), expected.size()) << k;
    for (size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].object, expected[i].object) << k << " " << i;
      EXPECT_EQ(got[i].s_in, expected[i].s_in);
      EXPECT_EQ(got[i].s_out, expected[i].s_out);
    }
    // Stopping early leaves a prefix.
    size_t stop_at = 0;
    rc.spans_until(origin, dir, max_s, got, pending, [&](const std::vector<Span>& out, size_t, double) {
      stop_at = out.size();
      return out.size() < 2;
    });
    ASSERT_LE(got.size(), expected.size());
    EXPECT_EQ(got.size(), stop_at);
    for (size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].object, expected[i].object);
  }
}

}  // namespace
}  // namespace driftlab::sim
