// parse_world / load_world / World::bounds: every format feature, occupancy images, and one-line errors.
#include "sim/world.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/test_util.h"

namespace driftlab::sim {
namespace {

bool inside(const Box& b, const Eigen::Vector2d& p) {
  const Eigen::Vector2d q = Eigen::Rotation2Dd(-b.yaw) * (p - b.center.head<2>());
  return std::abs(q.x()) <= 0.5 * b.size.x() && std::abs(q.y()) <= 0.5 * b.size.y();
}

TEST(ParseWorld, EveryFeature) {
  const std::string text = R"(friction: 0.6
walls:
  - {from: [0, 0], to: [10, 0]}
  - {from: [0, 0], to: [0, 4], thickness: 0.2, height: 3, color: [10, 20, 30], name: west}
boxes:
  - {name: crate, center: [2, 3], size: [1, 0.5, 0.8], yaw: 0.3}
  - {center: [5, 1, 2], size: [1, 1, 1], color: [255, 0, 0]}
cylinders:
  - {center: [4, 4], radius: 0.2, height: 1.0}
  - {name: pole, center: [6, 2, 3], radius: 0.1, height: 2, color: [1, 2, 3]}
)";
  auto w = parse_world(text, "w.yaml", "");
  ASSERT_TRUE(w.ok()) << w.error().message;
  EXPECT_DOUBLE_EQ(w->friction, 0.6);
  ASSERT_EQ(w->boxes.size(), 4u);
  ASSERT_EQ(w->cylinders.size(), 2u);
  const Box& south = w->boxes[0];
  EXPECT_TRUE(south.center.isApprox(Eigen::Vector3d(5, 0, 1.25)));
  EXPECT_TRUE(south.size.isApprox(Eigen::Vector3d(10.1, 0.1, 2.5)));  // extended by the thickness: corners close
  EXPECT_NEAR(south.yaw, 0, 1e-12);
  EXPECT_EQ(south.color, (std::array<uint8_t, 3>{200, 200, 200}));
  const Box& west = w->boxes[1];
  EXPECT_EQ(west.name, "west");
  EXPECT_TRUE(west.center.isApprox(Eigen::Vector3d(0, 2, 1.5)));
  EXPECT_TRUE(west.size.isApprox(Eigen::Vector3d(4.2, 0.2, 3)));
  EXPECT_NEAR(west.yaw, M_PI / 2, 1e-12);
  EXPECT_EQ(west.color, (std::array<uint8_t, 3>{10, 20, 30}));
  const Box& crate = w->boxes[2];
  EXPECT_EQ(crate.name, "crate");
  EXPECT_TRUE(crate.center.isApprox(Eigen::Vector3d(2, 3, 0.4)));  // 2D centre: standing on the floor
  EXPECT_DOUBLE_EQ(crate.yaw, 0.3);
  EXPECT_TRUE(w->boxes[3].center.isApprox(Eigen::Vector3d(5, 1, 2)));  // 3D centre kept
  EXPECT_EQ(w->boxes[3].color, (std::array<uint8_t, 3>{255, 0, 0}));
  EXPECT_TRUE(w->cylinders[0].center.isApprox(Eigen::Vector3d(4, 4, 0.5)));
  EXPECT_DOUBLE_EQ(w->cylinders[0].radius, 0.2);
  EXPECT_DOUBLE_EQ(w->cylinders[0].height, 1.0);
  EXPECT_EQ(w->cylinders[1].name, "pole");
  EXPECT_TRUE(w->cylinders[1].center.isApprox(Eigen::Vector3d(6, 2, 3)));
  EXPECT_EQ(w->cylinders[1].color, (std::array<uint8_t, 3>{1, 2, 3}));
}

TEST(ParseWorld, EmptyIsAnEmptyWorld) {
  auto w = parse_world("", "w.yaml", "");
  ASSERT_TRUE(w.ok());
  EXPECT_TRUE(w->boxes.empty());
  EXPECT_TRUE(w->bounds().isEmpty());
  EXPECT_DOUBLE_EQ(w->friction, 0.8);
}

TEST(WorldBounds, CoversRotatedBoxesAndCylinders) {
  World w;
  w.boxes.push_back({"b", {0, 0, 0.5}, {2, 0, 1}, M_PI / 4, {}});
  w.cylinders.push_back({"c", {5, 5, 0.5}, 1, 1, {}});
  const Eigen::AlignedBox2d b = w.bounds();
  EXPECT_NEAR(b.min().x(), -std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(b.min().y(), -std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(b.max().x(), 6, 1e-12);
  EXPECT_NEAR(b.max().y(), 6, 1e-12);
}

TEST(ParseWorld, ImageBecomesFewBoxesCoveringExactlyTheOccupiedPixels) {
  test::TempDir dir;
  cv::Mat img(30, 40, CV_8UC1, cv::Scalar(255));
  cv::rectangle(img, cv::Rect(0, 0, 40, 2), cv::Scalar(0), cv::FILLED);    // top wall
  cv::rectangle(img, cv::Rect(5, 10, 7, 12), cv::Scalar(40), cv::FILLED);  // a room block
  cv::circle(img, cv::Point(28, 18), 5, cv::Scalar(100), cv::FILLED);      // round: many runs
  img.at<uint8_t>(29, 39) = 127;                                           // just below the threshold
  img.at<uint8_t>(29, 0) = 128;                                            // not occupied
  ASSERT_TRUE(cv::imwrite(dir.file("map.png"), img));
  auto w = parse_world("images:\n  - {file: map.png, resolution: 0.05, origin: [-1, 2], height: 2, color: [9, 9, 9]}\n",
                       "w.yaml", dir.path());
  ASSERT_TRUE(w.ok()) << w.error().message;
  EXPECT_LT(w->boxes.size(), 20u);
  for (const Box& b : w->boxes) {
    EXPECT_DOUBLE_EQ(b.center.z(), 1.0);
    EXPECT_DOUBLE_EQ(b.size.z(), 2.0);
    EXPECT_EQ(b.color, (std::array<uint8_t, 3>{9, 9, 9}));
  }
  for (int r = 0; r < img.rows; ++r) {
    for (int c = 0; c < img.cols; ++c) {
      const Eigen::Vector2d p(-1 + (c + 0.5) * 0.05, 2 + (img.rows - 1 - r + 0.5) * 0.05);
      int covering = 0;
      for (const Box& b : w->boxes) covering += inside(b, p);
      EXPECT_EQ(covering, img.at<uint8_t>(r, c) < 128 ? 1 : 0) << "pixel row " << r << " col " << c;
    }
  }
}

TEST(ParseWorld, FloorPlanImageGivesHundredsOfBoxesNotThousands) {
  test::TempDir dir;
  cv::Mat img(400, 400, CV_8UC1, cv::Scalar(254));
  cv::rectangle(img, cv::Rect(0, 0, 400, 400), cv::Scalar(0), 4);
  for (int i = 1; i < 5; ++i) {
    cv::line(img, cv::Point(i * 80, 0), cv::Point(i * 80, 300), cv::Scalar(0), 3);
    cv::line(img, cv::Point(0, i * 80), cv::Point(330, i * 80), cv::Scalar(0), 3);
  }
  cv::line(img, cv::Point(20, 390), cv::Point(380, 330), cv::Scalar(0), 3);  // a slanted wall
  for (int i = 0; i < 30; ++i) cv::circle(img, cv::Point(37 + i * 11, 360), 3, cv::Scalar(0), cv::FILLED);
  ASSERT_TRUE(cv::imwrite(dir.file("plan.png"), img));
  auto w = parse_world("images: [{file: plan.png, resolution: 0.05, origin: [-10, -10]}]", "w.yaml", dir.path());
  ASSERT_TRUE(w.ok()) << w.error().message;
  EXPECT_GT(w->boxes.size(), 50u);
  EXPECT_LT(w->boxes.size(), 1000u);
  const Eigen::AlignedBox2d b = w->bounds();
  EXPECT_NEAR(b.min().x(), -10, 1e-9);
  EXPECT_NEAR(b.max().y(), 10, 1e-9);
}

TEST(LoadWorld, ResolvesImagesNextToTheFile) {
  test::TempDir dir;
  cv::Mat img(4, 4, CV_8UC1, cv::Scalar(0));
  ASSERT_TRUE(cv::imwrite(dir.file("m.png"), img));
  {
    std::ofstream f(dir.file("w.yaml"));
    f << "images: [{file: m.png, resolution: 1}]\n";
  }
  auto w = load_world(dir.file("w.yaml"));
  ASSERT_TRUE(w.ok()) << w.error().message;
  ASSERT_EQ(w->boxes.size(), 1u);  // one 4 x 4 m square
  EXPECT_TRUE(w->boxes[0].size.isApprox(Eigen::Vector3d(4, 4, 2.5)));
  EXPECT_TRUE(w->boxes[0].center.isApprox(Eigen::Vector3d(2, 2, 1.25)));

  auto missing = load_world(dir.file("nope.yaml"));
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("nope.yaml"), std::string::npos);
}

/// The error of parsing `text` as w.yaml with images in `dir`.
std::string error_of(const std::string& text, const std::string& dir = "") {
  auto w = parse_world(text, "w.yaml", dir);
  return w.ok() ? std::string("(parsed)") : w.error().message;
}

// A 3000x3000 checkerboard: every occupied pixel its own box, 4.5 million Bullet objects. Refused with one line
// naming the file and the bound (issue 31).
TEST(ParseWorld, AnImageNeedingMillionsOfBoxesIsRefusedWithItsBound) {
  test::TempDir dir;
  cv::Mat img(3000, 3000, CV_8UC1, cv::Scalar(255));
  for (int r = 0; r < img.rows; ++r)
    for (int c = r % 2; c < img.cols; c += 2) img.at<uint8_t>(r, c) = 0;
  ASSERT_TRUE(cv::imwrite(dir.file("checker.png"), img));
  const std::string e = error_of("images:\n  - {file: checker.png, resolution: 0.05}\n", dir.path());
  EXPECT_EQ(e.rfind("w.yaml:2: ", 0), 0u) << e;
  EXPECT_NE(e.find("checker.png (3000x3000) needs more than 100000 boxes"), std::string::npos) << e;
}

TEST(ParseWorld, ErrorsNameFileLineAndKey) {
  EXPECT_EQ(error_of("boxes:\n  - {center: [1, 2], size: [1, 1, 1]\n").rfind("w.yaml:3: ", 0), 0u)
      << error_of("boxes:\n  - {center: [1, 2], size: [1, 1, 1]\n");  // malformed: unclosed map

  std::string e = error_of("friction: 0.5\nboxes:\n  - {center: [1, 2], size: [1, 1, 1], colour: [1, 2, 3]}\n");
  EXPECT_EQ(e.rfind("w.yaml:3: ", 0), 0u) << e;
  EXPECT_NE(e.find("unknown key 'boxes[0].colour': did you mean 'color'? (known: name, center, size, yaw, color)"),
            std::string::npos)
      << e;

  e = error_of("friction: 0.5\nfloor: 1\n");
  EXPECT_EQ(e.rfind("w.yaml:2: ", 0), 0u) << e;
  EXPECT_NE(e.find("'floor'"), std::string::npos) << e;

  e = error_of("boxes:\n  - center: [1, 2]\n    size: [1, -0.5, 1]\n");
  EXPECT_EQ(e.rfind("w.yaml:3: ", 0), 0u) << e;
  EXPECT_NE(e.find("boxes[0].size"), std::string::npos) << e;

  e = error_of("cylinders:\n  - {center: [1, 2], radius: -1, height: 1}\n");
  EXPECT_EQ(e.rfind("w.yaml:2: ", 0), 0u) << e;
  EXPECT_NE(e.find("cylinders[0].radius"), std::string::npos) << e;

  e = error_of("walls:\n  - {from: [1, 1], to: [1, 1]}\n");
  EXPECT_NE(e.find("w.yaml:2: walls[0] has 'from' equal to 'to'"), std::string::npos) << e;
  e = error_of("boxes:\n  - {center: [0, 0], size: [1, 1, 1], color: [0, 300, 0]}\n");
  EXPECT_NE(e.find("boxes[0].color must be [r, g, b] with each in 0..255"), std::string::npos) << e;

  e = error_of("walls:\n  - {from: [0, 0], to: [1, 0], height: abc}\n");
  EXPECT_EQ(e.rfind("w.yaml:2: ", 0), 0u) << e;
  EXPECT_NE(e.find("walls[0].height = abc must be a number"), std::string::npos) << e;

  e = error_of("boxes:\n  - {center: [1, 2, 3, 4], size: [1, 1, 1]}\n");
  EXPECT_NE(e.find("boxes[0].center must be a list of 2 or 3 numbers"), std::string::npos) << e;

  e = error_of("friction: 1\nboxes: {center: [1, 2]}\n");
  EXPECT_EQ(e.rfind("w.yaml:2: ", 0), 0u) << e;

  e = error_of("boxes:\n  - {size: [1, 1, 1]}\n");
  EXPECT_NE(e.find("missing key 'boxes[0].center'"), std::string::npos) << e;
}

// The obstacles are made in the order the file gives its keys: the order of the Bullet objects and of the
// default names, so a world file reads as the same world (and a simulation of it runs the same) whatever it holds.
TEST(ParseWorld, ObstaclesFollowTheOrderOfTheKeys) {
  auto w = parse_world("boxes:\n  - {center: [3, 0], size: [1, 1, 1]}\nwalls:\n  - {from: [0, 0], to: [2, 0]}\n",
                       "w.yaml", "");
  ASSERT_TRUE(w) << w.error().message;
  ASSERT_EQ(w->boxes.size(), 2u);
  EXPECT_EQ(w->boxes[0].name, "box_0");
  EXPECT_EQ(w->boxes[1].name, "wall_1");
  EXPECT_TRUE(w->boxes[1].size.isApprox(Eigen::Vector3d(2.1, 0.1, 2.5)));  // extended by half its thickness each end
}

TEST(ParseWorld, ImageErrorsNameTheImage) {
  test::TempDir dir;
  std::string e = error_of("\nimages:\n  - {file: missing.png, resolution: 0.05}\n", dir.path());
  EXPECT_EQ(e.rfind("w.yaml:3: ", 0), 0u) << e;
  EXPECT_NE(e.find(dir.file("missing.png")), std::string::npos) << e;

  test::write_file(dir.file("broken.png"), {1, 2, 3, 4, 5});
  e = error_of("images:\n  - {file: broken.png, resolution: 0.05}\n", dir.path());
  EXPECT_EQ(e.rfind("w.yaml:2: ", 0), 0u) << e;
  EXPECT_NE(e.find("cannot read " + dir.file("broken.png")), std::string::npos) << e;

  e = error_of("images:\n  - {file: broken.png, resolution: 0}\n", dir.path());
  EXPECT_NE(e.find("images[0].resolution = 0 must be > 0"), std::string::npos) << e;
}

}  // namespace
}  // namespace driftlab::sim
