// The 2D SLAM module and the rawlog import/export, end to end on MRPT's SENA dataset (Debian's mrpt-common): our
// SLAM on the imported log agrees with MRPT's icp-slam application on the rawlog; the map is written; round trips
// keep the data; bad input names the file.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>

#include "core/log_reader.h"
#include "driftlab/image_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/planar.h"
#include "lcmtypes/validate.h"
#include "replayer/replayer.h"
#include "slam/rawlog.h"
#include "slam/slam2d.h"
#include "tests/doc_figures.h"
#include "tests/fakes/fake_bus.h"
#include "tests/slam/icp_slam.h"
#include "tests/test_util.h"

namespace driftlab::slam {
namespace {

const std::string kSena = "/usr/share/mrpt/datasets/2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog";
const std::string& kIcpIni = test::kIcpSlamIni;
using test::run_icp_slam;

struct Pose {
  int64_t utime;
  double x, y, yaw;
};

/// The poses on a channel of a log, and the stamps of the messages on another.
std::vector<Pose> poses(const std::string& log, const std::string& channel) {
  std::vector<Pose> out;
  auto r = LogReader::open(log, {.channels = channel});
  EXPECT_TRUE(r);
  Event e;
  while (r->next(e)) {
    driftlab::pose_t p;
    EXPECT_GE(p.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
    out.push_back({p.header.utime, p.position.x, p.position.y, yaw_of(p.orientation)});
  }
  return out;
}

std::vector<int64_t> odometry_stamps(const std::string& log) {
  std::vector<int64_t> out;
  auto r = LogReader::open(log, {.channels = "ODOM"});
  Event e;
  while (r->next(e)) {
    driftlab::odometry_t o;
    EXPECT_GE(o.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
    out.push_back(o.header.utime);
  }
  return out;
}

/// icp-slam's estimated path (x, y, yaw per step) on the SENA rawlog.
std::vector<Pose> icp_slam_path(const test::TempDir& dir) {
  EXPECT_EQ(run_icp_slam(dir, kSena), 0);
  std::vector<Pose> out;
  std::ifstream path(dir.file("icp/log_estimated_path.txt"));
  int step;
  Pose p{};
  while (path >> step >> p.x >> p.y >> p.yaw) out.push_back(p);
  return out;
}

TEST(Slam2d, AgreesWithMrptIcpSlamOnTheSenaDataset) {
  test::TempDir dir;
  auto counts = import_rawlog(kSena, dir.file("sena.lcm"));
  ASSERT_TRUE(counts) << counts.error().message;
  EXPECT_EQ(counts->written.at("SCAN"), 225);
  EXPECT_EQ(counts->written.at("ODOM"), 224);

  replay::ReplayOptions o;
  o.logs = {dir.file("sena.lcm")};
  o.out = dir.file("slam.lcm");
  replay::Replayer r(o);
  // The same configuration as icp-slam's.
  auto config = parse_slam2d_config(YAML::Load("ini: " + kIcpIni), "test");
  ASSERT_TRUE(config);
  r.add_module(std::make_unique<Slam2d>(*config));
  auto report = r.run();
  ASSERT_TRUE(report) << report.error().message;
  EXPECT_TRUE(report->modules[0].warnings.empty());
  const auto ours = poses(dir.file("slam.lcm"), "SLAM_POSE");
  ASSERT_EQ(ours.size(), 224u);  // the first scan comes before any odometry

  // icp-slam steps through (odometry, scan) pairs: the imported log marks each with an odometry message at the
  // scan's time. Compare our pose at those scans with icp-slam's, step by step.
  const auto icp = icp_slam_path(dir);
  const auto pairs = odometry_stamps(dir.file("sena.lcm"));
  ASSERT_EQ(icp.size(), pairs.size());
  double worst = 0, sum_sq = 0, worst_yaw = 0;
  size_t k = 0;
  for (const Pose& p : ours) {
    if (k < pairs.size() && p.utime == pairs[k]) {
      const double d = std::hypot(p.x - icp[k].x, p.y - icp[k].y);
      worst = std::max(worst, d);
      worst_yaw = std::max(worst_yaw, std::abs(std::remainder(p.yaw - icp[k].yaw, 2 * M_PI)));
      sum_sq += d * d;
      ++k;
    }
  }
  ASSERT_EQ(k, pairs.size());
  const double rms = std::sqrt(sum_sq / static_cast<double>(k));
  std::printf("SENA: %zu steps; path difference to icp-slam: rms %.4f m, max %.4f m, max yaw %.4f rad; "
              "icp-slam ends at (%.2f, %.2f)\n", k, rms, worst, worst_yaw, icp.back().x, icp.back().y);
  // The loop is about 40 m long and ends some 18 m from the start: a different map would differ by metres.
  EXPECT_GT(std::hypot(icp.back().x, icp.back().y), 10);
  EXPECT_LT(rms, 0.03);
  EXPECT_LT(worst, 0.15);
  EXPECT_LT(worst_yaw, 0.02);
  const std::string page = "docs/slam.md", table = "### The icp-slam method against MRPT's icp-slam";
  const std::string row = "ours against icp-slam's";
  test::expect_doc_figures(page, table, row, 1, {static_cast<double>(k)});
  test::expect_doc_figures(page, table, row, 2, {100 * rms});
  test::expect_doc_figures(page, table, row, 3, {100 * worst});
  test::expect_doc_figures(page, table, row, 4, {worst_yaw * 180 / M_PI});
  test::expect_doc_figures(page, table, row, 5, {std::hypot(icp.back().x, icp.back().y)});
  // The occupancy map beside the output log.
  EXPECT_GT(std::filesystem::file_size(dir.file("slam-map.png")), 1000u);
  std::ifstream yaml(dir.file("slam-map.yaml"));
  std::stringstream text;
  text << yaml.rdbuf();
  EXPECT_NE(text.str().find("resolution: 0.05"), std::string::npos) << text.str();
}

/// A scanner mounted at (-10.43, -10.43) m from the base, turned 0.668 rad, seeing a wall 3.96 m away five times:
/// the map grows past its first 20 m x 20 m to an origin that is no round number.
void feed_far_scanner(test::FakeBus& bus) {
  driftlab::tf_t tf{};
  driftlab::transform_t t{};
  t.header = {0, 1'000'000, "base_link"};
  t.child_frame_id = "laser";
  t.translation = {-10.43, -10.43, 0};
  t.rotation = {std::cos(0.334), 0, 0, std::sin(0.334)};
  tf.transforms.push_back(t);
  tf.ntransforms = 1;
  ASSERT_TRUE(bus.deliver_message("TF_STATIC", tf, Time::from_us(1'000'000)).ok());
  for (int i = 0; i < 5; ++i) {
    driftlab::laser_scan_t m{};
    m.header = {i, 1'100'000 + int64_t{i} * 100'000, "laser"};
    m.angle_min = -0.0333f;
    m.angle_increment = 0.0333f;
    m.nranges = 3;
    m.angle_max = m.angle_min + 2 * m.angle_increment;
    m.range_min = 0.1f;
    m.range_max = 30.0f;
    m.ranges = {3.96f, 3.96f, 3.96f};
    ASSERT_TRUE(bus.deliver_message("SCAN", m, Time::from_us(m.header.utime)).ok());
  }
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// A scanner mounted 14.8 m from the base whose short beams end inside the map's first 20 m x 20 m: MRPT grows the
// grid to the beams' ends but ray-traces from the sensor's cell, which lay outside it (a read out of bounds, found
// by the modules fuzzer). The map is drawn, the sensor inside it.
TEST(Slam2d, AScannerMountedFarFromTheBaseIsInsideTheMap) {
  Slam2dConfig config;
  config.odom_channel = "";  // scan matching alone (with odometry the first second's scans wait for it)
  Slam2d slam{config};
  test::FakeBus bus;
  bus.add(slam);
  ASSERT_TRUE(bus.start().ok());
  feed_far_scanner(bus);
  ASSERT_TRUE(bus.finish().ok());
  const auto maps = bus.published("SLAM_MAP");
  for (const auto& r : bus.reports()) {
    for (const auto& w : r.warnings) ADD_FAILURE() << w;
  }
  ASSERT_EQ(maps.size(), 1u);
  driftlab::image_t image;
  ASSERT_TRUE(lcmtypes::decode(maps[0].data, image));
  EXPECT_GT(image.width, 0);
}

double metric(const std::vector<runtime::ModuleReport>& reports, const std::string& name) {
  for (const auto& r : reports) {
    for (const auto& [key, value] : r.metrics) {
      if (key == name) return value;
    }
  }
  ADD_FAILURE() << "no metric " << name;
  return -1;
}

// A CARMEN .clf's odometry rides on its laser lines: the import gives each scan, then its pose (driftlab.pose_t)
// with the same stamp. The first scan waits for its pose like the others, and is kept: dropping it (as a scan
// "before any odometry") moved every keyframe of MIT CSAIL's .clf and its error went from the bag's 0.034 m to
// 0.100 m. A scan stamped before the first odometry, in the first second, is still left out.
TEST(Slam2d, TheFirstScanWaitsForThePoseThatRidesOnIt) {
  Slam2dConfig config;
  config.odom_channel = "ODOM";
  Slam2d slam{config};
  test::FakeBus bus;
  bus.add(slam);
  ASSERT_TRUE(bus.start().ok());
  auto scan_at = [](int64_t utime) {
    driftlab::laser_scan_t m{};
    m.header = {0, utime, "laser"};
    m.nranges = 90;
    m.angle_increment = 0.035f;
    m.angle_min = -1.56f;
    m.angle_max = m.angle_min + 89 * m.angle_increment;
    m.range_min = 0.1f;
    m.range_max = 30.0f;
    for (int i = 0; i < m.nranges; ++i) m.ranges.push_back(2.0f + 0.01f * static_cast<float>(i % 7));
    return m;
  };
  const auto early = scan_at(900'000);  // before the first pose, in the first second: left out
  ASSERT_TRUE(bus.deliver_message("SCAN", early, Time::from_us(900'000)).ok());
  for (int i = 0; i < 5; ++i) {
    const int64_t t = 1'000'000 + int64_t{i} * 200'000;
    ASSERT_TRUE(bus.deliver_message("SCAN", scan_at(t), Time::from_us(t)).ok());
    driftlab::pose_t p{};
    p.header = {i, t, "world"};
    p.child_frame_id = "laser";
    p.orientation = {1, 0, 0, 0};
    ASSERT_TRUE(bus.deliver_message("ODOM", p, Time::from_us(t)).ok());
  }
  ASSERT_TRUE(bus.finish().ok());
  EXPECT_EQ(metric(bus.reports(), "scans"), 5);
  EXPECT_EQ(metric(bus.reports(), "scans_before_odometry"), 1);
  std::vector<int64_t> stamps;
  for (const auto& e : bus.published("SLAM_POSE")) {
    driftlab::pose_t p;
    ASSERT_TRUE(lcmtypes::decode(e.data, p));
    stamps.push_back(p.header.utime);
  }
  EXPECT_EQ(stamps, (std::vector<int64_t>{1'000'000, 1'200'000, 1'400'000, 1'600'000, 1'800'000}));
}

/// a (+) b
Pose2 compose(const Pose2& a, const Pose2& b) {
  return Pose2{a.x + std::cos(a.yaw) * b.x - std::sin(a.yaw) * b.y, a.y + std::sin(a.yaw) * b.x + std::cos(a.yaw) * b.y,
               wrap_angle(a.yaw + b.yaw)};
}

/// b as seen from a
Pose2 seen_from(const Pose2& a, const Pose2& b) {
  const double c = std::cos(a.yaw), s = std::sin(a.yaw), dx = b.x - a.x, dy = b.y - a.y;
  return Pose2{c * dx + s * dy, -s * dx + c * dy, wrap_angle(b.yaw - a.yaw)};
}

/// A robot driving a square (1.5 m sides, turns on the spot) in a 12 x 8 m room with a pillar, its laser 0.3 m
/// ahead and 0.1 m to its left; exact odometry, exact scans (181 beams over 180 degrees, every 0.2 s).
struct SquareRoom {
  const Pose2 mount{0.3, 0.1, 0};
  std::vector<Pose2> path;

  SquareRoom() {
    Pose2 robot{-3, -1, 0};
    for (int side = 0; side < 4; ++side) {
      for (int i = 0; i < 15; ++i) path.push_back(robot = compose(robot, {0.1, 0, 0}));
      for (int i = 0; i < 9; ++i) path.push_back(robot = compose(robot, {0, 0, M_PI / 18}));
    }
  }
  static int64_t stamp(size_t i) { return 1'000'000 + static_cast<int64_t>(i) * 200'000; }

  driftlab::laser_scan_t scan(size_t i) const {
    static const std::vector<std::array<double, 4>> walls = {{-6, -4, 6, -4}, {6, -4, 6, 4}, {6, 4, -6, 4},
                                                             {-6, 4, -6, -4}, {1, 1, 2, 1},  {2, 1, 2, 2},
                                                             {2, 2, 1, 2},    {1, 2, 1, 1},  {-3, -2, -2, -3}};
    const Pose2 laser = compose(path[i], mount);
    driftlab::laser_scan_t m{};
    m.header = {static_cast<int32_t>(i), stamp(i), "laser"};
    m.nranges = 181;
    m.angle_min = static_cast<float>(-M_PI / 2);
    m.angle_increment = static_cast<float>(M_PI / 180);
    m.angle_max = static_cast<float>(M_PI / 2);
    m.range_min = 0.1f;
    m.range_max = 30.0f;
    for (int k = 0; k < m.nranges; ++k) {
      const double a = laser.yaw + m.angle_min + k * static_cast<double>(m.angle_increment);
      const double dx = std::cos(a), dy = std::sin(a);
      double best = 30;
      for (const auto& [x1, y1, x2, y2] : walls) {  // the ray against each wall
        const double ex = x2 - x1, ey = y2 - y1, den = dx * ey - dy * ex;
        if (std::abs(den) < 1e-12) continue;
        const double t = ((x1 - laser.x) * ey - (y1 - laser.y) * ex) / den;
        const double u = ((x1 - laser.x) * dy - (y1 - laser.y) * dx) / den;
        if (t > 0 && u >= 0 && u <= 1) best = std::min(best, t);
      }
      m.ranges.push_back(static_cast<float>(best));
    }
    return m;
  }

  driftlab::tf_t mounting() const {
    driftlab::tf_t tf{};
    driftlab::transform_t t{};
    t.header = {0, stamp(0), "base_link"};
    t.child_frame_id = "laser";
    t.translation = {mount.x, mount.y, 0};
    t.rotation = yaw_quaternion(mount.yaw);
    tf.transforms.push_back(t);
    tf.ntransforms = 1;
    return tf;
  }

  /// The robot's odometry (driftlab.odometry_t), or the laser's pose (driftlab.pose_t, child frame "laser").
  Status deliver_odometry(test::FakeBus& bus, size_t i, bool laser_pose) const {
    if (laser_pose) {
      const Pose2 laser = compose(path[i], mount);
      driftlab::pose_t p{};
      p.header = {static_cast<int32_t>(i), stamp(i), "world"};
      p.child_frame_id = "laser";
      p.position = {laser.x, laser.y, 0};
      p.orientation = yaw_quaternion(laser.yaw);
      return bus.deliver_message("ODOM", p, Time::from_us(stamp(i)));
    }
    driftlab::odometry_t o{};
    o.header = {static_cast<int32_t>(i), stamp(i), "odom"};
    o.child_frame_id = "base_link";
    o.position = {path[i].x, path[i].y, 0};
    o.orientation = yaw_quaternion(path[i].yaw);
    return bus.deliver_message("ODOM", o, Time::from_us(stamp(i)));
  }
};

/// What a run of the module (loop closure off) gave: its poses, one metric and its warnings.
struct RoomRun {
  std::vector<Pose2> poses;
  double odometry_of_sensor = 0;
  std::vector<std::string> warnings;
};

/// Runs the module on the room, the messages in the order `deliver` sends them.
RoomRun run_room(const std::function<void(test::FakeBus&)>& deliver, const std::string& match_odometry = "auto") {
  Slam2dConfig config;
  config.odom_channel = "ODOM";
  config.loop_closure = false;
  config.match_odometry = match_odometry;
  Slam2d slam{config};
  test::FakeBus bus;
  bus.add(slam);
  EXPECT_TRUE(bus.start().ok());
  deliver(bus);
  EXPECT_TRUE(bus.finish().ok());
  RoomRun out;
  for (const auto& r : bus.reports()) {
    for (const auto& [name, value] : r.metrics) {
      if (name == "odometry_of_sensor") out.odometry_of_sensor = value;
    }
    out.warnings.insert(out.warnings.end(), r.warnings.begin(), r.warnings.end());
  }
  for (const auto& e : bus.published("SLAM_POSE")) {
    driftlab::pose_t p;
    EXPECT_TRUE(lcmtypes::decode(e.data, p));
    out.poses.push_back({p.position.x, p.position.y, yaw_of(p.orientation)});
  }
  return out;
}

/// The largest distance [m] and heading difference [rad] between two runs' poses, one by one.
std::pair<double, double> largest_difference(const std::vector<Pose2>& a, const std::vector<Pose2>& b) {
  EXPECT_EQ(a.size(), b.size());
  std::pair<double, double> worst{0, 0};
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    worst.first = std::max(worst.first, std::hypot(a[i].x - b[i].x, a[i].y - b[i].y));
    worst.second = std::max(worst.second, std::abs(wrap_angle(a[i].yaw - b[i].yaw)));
  }
  return worst;
}

// A pose stream may give a sensor's pose rather than the robot's: a CARMEN laser line carries its laser's pose
// (child_frame_id "laser"). With the laser mounted off the robot's centre (TF_STATIC says where), the module takes
// the mounting off and has the robot's odometry: the same path as from the robot's own odometry. Taken as the
// robot's, the prior is the mounting's lever arm off on every turn (the Freiburg clinic's .clf without ODOM lines:
// 0.127 m of relation error against the 0.102 m of the robot's pose; SlamOnTheClinicsClf).
TEST(Slam2d, ASensorsPoseAsOdometryIsTheRobotsWithTheMountingTakenOff) {
  const SquareRoom room;
  auto run = [&](bool laser_pose) {
    return run_room([&](test::FakeBus& bus) {
      ASSERT_TRUE(bus.deliver_message("TF_STATIC", room.mounting(), Time::from_us(room.stamp(0))).ok());
      for (size_t i = 0; i < room.path.size(); ++i) {
        ASSERT_TRUE(room.deliver_odometry(bus, i, laser_pose).ok());
        ASSERT_TRUE(bus.deliver_message("SCAN", room.scan(i), Time::from_us(room.stamp(i))).ok());
      }
    });
  };
  const RoomRun from_robot = run(false), from_laser = run(true);
  EXPECT_EQ(from_robot.odometry_of_sensor, 0);
  EXPECT_EQ(from_laser.odometry_of_sensor, static_cast<double>(room.path.size()));
  ASSERT_EQ(from_robot.poses.size(), room.path.size());
  // The same path to a micrometre (the mounting's round trip differs in the last bits); the lever arm would be
  // centimetres to 0.3 m.
  const auto [apart, turned] = largest_difference(from_laser.poses, from_robot.poses);
  EXPECT_LT(apart, 1e-6);
  EXPECT_LT(turned, 1e-6);
  // And that path is the robot's, not the laser's: each pose seen from the first, against the robot's path and
  // against the laser's (which swings the mounting's arc on each turn).
  double off_robot = 0, off_laser = 0;
  for (size_t i = 0; i < room.path.size(); ++i) {
    const Pose2 ours = seen_from(from_robot.poses[0], from_robot.poses[i]),
                robot = seen_from(room.path[0], room.path[i]),
                laser = seen_from(compose(room.path[0], room.mount), compose(room.path[i], room.mount));
    off_robot = std::max(off_robot, std::hypot(ours.x - robot.x, ours.y - robot.y));
    off_laser = std::max(off_laser, std::hypot(ours.x - laser.x, ours.y - laser.y));
  }
  std::printf("the path off the robot's by %.3f m at most, off the laser's by %.3f m\n", off_robot, off_laser);
  EXPECT_LT(off_robot, 0.1);  // the front end drifts a few centimetres in this room (ours: 0.044 m)
  EXPECT_GT(off_laser, 0.3);  // the laser's path swings 0.32 m of lever arm through each turn (ours: 0.65 m)
}

// A bag sorted by stamp may hold the first scan before /tf_static of the same stamp (ricoslam's sorted bag of the
// Freiburg clinic: its relation error was 0.103 m against the original bag's 0.099 m, the first keyframe's laser
// on the robot's centre and the rest 0.22 m ahead). The scan waits for its frame's mounting as for its odometry
// (odom_wait_s, in scan stamps): the same path as with the mounting first. Without any, after that wait, the
// sensor_pose setting, said once.
TEST(Slam2d, AScanBeforeItsMountingWaitsForIt) {
  const SquareRoom room;
  auto run = [&](std::optional<size_t> mounting_after) {
    return run_room([&](test::FakeBus& bus) {
      for (size_t i = 0; i < room.path.size(); ++i) {
        ASSERT_TRUE(bus.deliver_message("SCAN", room.scan(i), Time::from_us(room.stamp(i))).ok());
        if (mounting_after == i) {
          ASSERT_TRUE(bus.deliver_message("TF_STATIC", room.mounting(), Time::from_us(room.stamp(i))).ok());
        }
        ASSERT_TRUE(room.deliver_odometry(bus, i, false).ok());
      }
    });
  };
  const RoomRun first = run(0), third = run(2), none = run(std::nullopt);
  for (const RoomRun* r : {&first, &third}) EXPECT_TRUE(r->warnings.empty()) << ::testing::PrintToString(r->warnings);
  // The mounting after the first scan, or after the third (0.4 s of scans later, within the 2 s wait): every scan
  // on it, the same path.
  ASSERT_EQ(first.poses.size(), room.path.size());
  const auto [apart, turned] = largest_difference(first.poses, third.poses);
  EXPECT_LT(apart, 1e-9);
  EXPECT_LT(turned, 1e-9);
  // Without it: the laser on the robot's centre, said once.
  EXPECT_EQ(none.warnings,
            (std::vector<std::string>{"slam: no base_link -> laser on TF_STATIC within odom_wait_s of its first scan: "
                                      "the sensor_pose setting was used"}));
  EXPECT_GT(largest_difference(first.poses, none.poses).first, 0.05);
}

// A log written in arrival order is not in stamp order: Intel's bag has its odometry and its scans step back up to
// 0.9 s. A scan matched as soon as the odometry had passed its stamp missed the late samples around it, and a late
// scan was matched after newer ones: Intel's bag gave 0.0309 m and the same bag sorted by stamp 0.0320 m (563 and
// 558 closures). Scans wait for the scans before them and for the odometry around them to be final, by how late
// each stream has shown its messages to come: the same path as from the log sorted, once the log has shown it
// (here from the start: the odometry's first late sample comes before the first scan, and the first scan late).
TEST(Slam2d, ALogOutOfStampOrderGivesTheSortedLogsPath) {
  const SquareRoom room;
  // Odometry every 0.2 s from 0.2 s, still for the first second; each a few centimetres off the path (as wheels
  // are), so that a sample missed changes the prediction: interpolated across a missing one on a straight side, the
  // exact odometry would be the same.
  struct Message {
    int64_t stamp;
    bool scan;
    size_t index;
    int64_t arrival;
  };
  std::vector<Message> messages;
  const size_t still = 4;  // samples before the first scan's stamp
  for (size_t k = 0; k < still + room.path.size(); ++k) {
    const int64_t stamp = 200'000 + static_cast<int64_t>(k) * 200'000;
    messages.push_back({stamp, false, k, stamp + (k % 5 == 0 ? 300'000 : 0)});  // one in five 0.3 s late
  }
  for (size_t i = 0; i < room.path.size(); ++i) {
    messages.push_back({SquareRoom::stamp(i), true, i, SquareRoom::stamp(i) + (i % 7 == 0 ? 300'000 : 0)});
  }
  auto deliver = [&](test::FakeBus& bus, bool sorted) {
    std::stable_sort(messages.begin(), messages.end(), [&](const Message& a, const Message& b) {
      return sorted ? std::pair{a.stamp, a.scan} < std::pair{b.stamp, b.scan} : a.arrival < b.arrival;
    });
    for (const Message& m : messages) {
      const Time at = Time::from_us(sorted ? m.stamp : m.arrival);
      if (m.scan) {
        ASSERT_TRUE(bus.deliver_message("SCAN", room.scan(m.index), at).ok());
        continue;
      }
      const size_t i = m.index < still ? 0 : m.index - still;
      const double off = 0.03 * std::sin(1.7 * static_cast<double>(m.index));
      driftlab::odometry_t o{};
      o.header = {static_cast<int32_t>(m.index), m.stamp, "odom"};
      o.child_frame_id = "base_link";
      o.position = {room.path[i].x + off, room.path[i].y - off, 0};
      o.orientation = yaw_quaternion(room.path[i].yaw + off);
      ASSERT_TRUE(bus.deliver_message("ODOM", o, at).ok());
    }
  };
  // With the odometry in the match, as a pose it moves (these exact scans bring ICP to the same pose from any
  // prediction near it: without, a sample missed would not show).
  const RoomRun sorted = run_room([&](test::FakeBus& bus) { deliver(bus, true); }, "true");
  const RoomRun arrived = run_room([&](test::FakeBus& bus) { deliver(bus, false); }, "true");
  ASSERT_EQ(sorted.poses.size(), room.path.size());
  // The same path to the last bits (the odometry's samples in the same buffer, added in another order; a sample
  // missed: 0.08 m and 4 degrees, a scan matched out of order: 0.20 m and 12 degrees).
  const auto [apart, turned] = largest_difference(arrived.poses, sorted.poses);
  EXPECT_LT(apart, 1e-9);
  EXPECT_LT(turned, 1e-9);
}

TEST(Slam2d, TheMapOriginIsWrittenWhole) {
  // The origin was written with 6 significant digits ("-16.03"), which is not the grid's corner: MRPT keeps it in
  // a float, and the number written must read back as exactly that float, so a map server places every cell where
  // the module drew it.
  test::TempDir dir;
  Slam2dConfig config;
  config.odom_channel = "";
  config.map_resolution = 0.07;  // not a metre's divisor: the grid's corner, in whole cells, is no round number
  Slam2d slam{config};
  test::FakeBus bus({.artifact_prefix = dir.file("slam")});
  bus.add(slam);
  ASSERT_TRUE(bus.start().ok());
  feed_far_scanner(bus);
  ASSERT_TRUE(bus.finish().ok());
  for (const auto& r : bus.reports()) {
    for (const auto& w : r.warnings) ADD_FAILURE() << w;
  }
  const std::string yaml = read_text(dir.file("slam-map.yaml"));
  const auto at = yaml.find("origin: [");
  ASSERT_NE(at, std::string::npos) << yaml;
  double x = 0, y = 0;
  ASSERT_EQ(std::sscanf(yaml.c_str() + at, "origin: [%lf, %lf", &x, &y), 2) << yaml;
  // The grid grew west and south to the sensor at -10.43 m (MRPT adds a margin): a corner beyond it, no round number.
  EXPECT_LT(x, -11.43);
  EXPECT_GT(x, -20);
  EXPECT_LT(y, -11.43);
  EXPECT_GT(y, -20);
  EXPECT_EQ(static_cast<double>(static_cast<float>(x)), x) << yaml;  // the float itself, not a decimal near it
  EXPECT_EQ(static_cast<double>(static_cast<float>(y)), y) << yaml;
  EXPECT_NE(yaml.find("resolution: 0.07\n"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("image: slam-map.png\n"), std::string::npos) << yaml;
}

TEST(Slam2d, AMapThatCannotBeWrittenIsAWarningAndLeavesNoPartialFile) {
  // A failed write of the map's PNG was ignored (and its description written beside the missing image). Here a
  // folder stands where the image goes: the write is reported, nothing half-written is left, and no description
  // of a map that is not there is written.
  test::TempDir dir;
  std::filesystem::create_directory(dir.file("slam-map.png"));
  Slam2dConfig config;
  config.odom_channel = "";
  Slam2d slam{config};
  test::FakeBus bus({.artifact_prefix = dir.file("slam")});
  bus.add(slam);
  ASSERT_TRUE(bus.start().ok());
  feed_far_scanner(bus);
  ASSERT_TRUE(bus.finish().ok());
  EXPECT_EQ(bus.published("SLAM_MAP").size(), 1u);  // the map is still published
  std::vector<std::string> warnings;
  for (const auto& r : bus.reports()) warnings.insert(warnings.end(), r.warnings.begin(), r.warnings.end());
  ASSERT_EQ(warnings.size(), 1u) << ::testing::PrintToString(warnings);
  EXPECT_EQ(warnings[0].rfind("slam: " + dir.file("slam-map.png") + ": cannot write: ", 0), 0u) << warnings[0];
  EXPECT_TRUE(std::filesystem::is_directory(dir.file("slam-map.png")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("slam-map.png.partial")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("slam-map.yaml")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("slam-map.yaml.partial")));
}

TEST(Rawlog, ImportExportImportKeepsScansAndOdometry) {
  test::TempDir dir;
  ASSERT_TRUE(import_rawlog(kSena, dir.file("a.lcm")));
  auto exported = export_rawlog(dir.file("a.lcm"), dir.file("a.rawlog"));
  ASSERT_TRUE(exported) << exported.error().message;
  EXPECT_EQ(exported->written.at("CObservation2DRangeScan"), 225);
  EXPECT_EQ(exported->written.at("CObservationOdometry"), 224);
  EXPECT_FALSE(std::filesystem::exists(dir.file("a.rawlog.partial")));
  ASSERT_TRUE(import_rawlog(dir.file("a.rawlog"), dir.file("b.lcm")));
  const auto a = test::read_all(dir.file("a.lcm")), b = test::read_all(dir.file("b.lcm"));
  auto of = [](const std::vector<test::OwnedEvent>& events, const std::string& channel) {
    std::vector<test::OwnedEvent> out;
    for (const auto& e : events) {
      if (e.channel == channel) out.push_back(e);
    }
    return out;
  };
  const auto scans_a = of(a, "SCAN"), scans_b = of(b, "SCAN");
  ASSERT_EQ(scans_a.size(), scans_b.size());
  for (size_t i = 0; i < scans_a.size(); ++i) {
    driftlab::laser_scan_t x, y;
    ASSERT_GE(x.decode(scans_a[i].data.data(), 0, static_cast<int>(scans_a[i].data.size())), 0);
    ASSERT_GE(y.decode(scans_b[i].data.data(), 0, static_cast<int>(scans_b[i].data.size())), 0);
    EXPECT_EQ(scans_a[i].utime, scans_b[i].utime);
    ASSERT_EQ(x.nranges, y.nranges);
    EXPECT_NEAR(x.angle_min, y.angle_min, 1e-6);
    for (int k = 0; k < x.nranges; ++k) {
      if (std::isnan(x.ranges[k])) {
        EXPECT_TRUE(std::isnan(y.ranges[k]));
      } else {
        EXPECT_FLOAT_EQ(x.ranges[k], y.ranges[k]);
      }
    }
  }
  const auto odo_a = of(a, "ODOM"), odo_b = of(b, "ODOM");
  ASSERT_EQ(odo_a.size(), odo_b.size());
  for (size_t i = 0; i < odo_a.size(); ++i) {
    driftlab::odometry_t x, y;
    ASSERT_GE(x.decode(odo_a[i].data.data(), 0, static_cast<int>(odo_a[i].data.size())), 0);
    ASSERT_GE(y.decode(odo_b[i].data.data(), 0, static_cast<int>(odo_b[i].data.size())), 0);
    EXPECT_NEAR(x.position.x, y.position.x, 1e-9);
    EXPECT_NEAR(x.position.y, y.position.y, 1e-9);
    EXPECT_NEAR(yaw_of(x.orientation), yaw_of(y.orientation), 1e-9);
  }
}

TEST(Rawlog, AnExportedSimulatorSessionRunsThroughIcpSlam) {
  test::TempDir dir;
  ASSERT_EQ(test::run(std::string(DRIFTLAB_BIN_DIR) + "/driftlab sim --duration 20 -o " + dir.file("s.lcm") +
                      " >/dev/null"),
            0);
  auto exported = export_rawlog(dir.file("s.lcm"), dir.file("s.rawlog"));
  ASSERT_TRUE(exported) << exported.error().message;
  EXPECT_GT(exported->written.at("CObservation2DRangeScan"), 150);
  EXPECT_GT(exported->written.at("CObservationIMU"), 3000);
  EXPECT_GT(exported->written.at("CObservationRobotPose"), 1500);
  ASSERT_EQ(run_icp_slam(dir, dir.file("s.rawlog")), 0);
  std::ifstream path(dir.file("icp/log_estimated_path.txt"));
  int steps = 0;
  double last_x = 0;
  for (std::string line; std::getline(path, line); ++steps) {
    std::istringstream(line) >> last_x >> last_x;
  }
  EXPECT_GT(steps, 1000);  // scans, odometry, IMU and poses each make a step in an observations-only rawlog
  EXPECT_GT(std::abs(last_x), 1.0);  // the robot drove along the corridor: icp-slam followed it
}

// MRPT 2.5's carmen2rawlog gives every observation the time it ran: such a rawlog is converted (in file order) and
// reported, one line naming the file and the count, exit 2; `info --json` of the log counts the repeated stamps.
// A rawlog with real stamps (SENA) is not.
TEST(Rawlog, OneStampForEveryObservationIsReportedNotAccepted) {
  test::TempDir dir;
  std::string carmen = "# a CARMEN log: odometry and front laser, 10 Hz\n";
  for (int i = 0; i < 8; ++i) {
    const double t = 1000.0 + 0.1 * i, x = 0.05 * i;
    carmen += "ODOM " + std::to_string(x) + " 0 0 0.5 0 0 " + std::to_string(t) + " host " + std::to_string(t) + "\n";
    carmen += "FLASER 180";
    for (int b = 0; b < 180; ++b) carmen += " " + std::to_string(2.0 + 0.01 * b);
    carmen += " " + std::to_string(x) + " 0 0 " + std::to_string(x) + " 0 0 " + std::to_string(t + 0.05) + " host " +
              std::to_string(t + 0.05) + "\n";
  }
  test::write_file(dir.file("run.log"), {carmen.begin(), carmen.end()});
  ASSERT_EQ(test::run("carmen2rawlog -q -w -i '" + dir.file("run.log") + "' -o '" + dir.file("run.rawlog") +
                      "' >/dev/null 2>&1"),
            0);
  auto counts = import_rawlog(dir.file("run.rawlog"), dir.file("api.lcm"));
  ASSERT_TRUE(counts) << counts.error().message;
  ASSERT_GE(counts->observations, 8);
  EXPECT_EQ(counts->one_stamp, counts->observations);

  const std::string driftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
  auto r = test::run_capture(driftlab + " import '" + dir.file("run.rawlog") + "' -o '" + dir.file("run.lcm") + "'");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err.rfind("driftlab: " + dir.file("run.rawlog") + ": warning: all " +
                            std::to_string(counts->observations) + " observations carry one timestamp (",
                        0),
            0u)
      << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  const auto log = test::read_all(dir.file("run.lcm"));  // converted all the same
  EXPECT_EQ(std::count_if(log.begin(), log.end(), [](const auto& e) { return e.channel == "SCAN"; }),
            counts->written.at("SCAN"));
  r = test::run_capture(driftlab + " info --json '" + dir.file("run.lcm") + "'");
  ASSERT_EQ(r.code, 0) << r.err;
  int64_t repeated = 0;
  const auto info = nlohmann::json::parse(r.out);
  for (const auto& c : info.at("channels")) {
    if (c.at("name") == "SCAN") repeated = c.at("stamps_repeated").get<int64_t>();
  }
  EXPECT_EQ(repeated, counts->written.at("SCAN") - 1);

  r = test::run_capture(driftlab + " import '" + kSena + "' -o '" + dir.file("sena.lcm") + "'");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "");
}

TEST(Rawlog, BadInputNamesTheFileAndLeavesNothingBehind) {
  test::TempDir dir;
  const auto sena = test::read_file(kSena);
  test::write_file(dir.file("cut.rawlog"), std::vector<uint8_t>(sena.begin(), sena.begin() + 60000));
  auto cut = import_rawlog(dir.file("cut.rawlog"), dir.file("cut.lcm"));
  ASSERT_FALSE(cut);
  EXPECT_EQ(cut.error().message.rfind(dir.file("cut.rawlog") + ": entry ", 0), 0u) << cut.error().message;
  EXPECT_NE(cut.error().message.find("truncated"), std::string::npos) << cut.error().message;
  EXPECT_FALSE(std::filesystem::exists(dir.file("cut.lcm")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("cut.lcm.partial")));
  test::write_file(dir.file("junk.rawlog"), test::payload(3, 5000));
  auto junk = import_rawlog(dir.file("junk.rawlog"), dir.file("junk.lcm"));
  ASSERT_FALSE(junk);
  EXPECT_EQ(junk.error().message.rfind(dir.file("junk.rawlog") + ": ", 0), 0u) << junk.error().message;
  EXPECT_EQ(junk.error().message.find('\n'), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir.file("junk.lcm")));
  auto missing = import_rawlog(dir.file("none.rawlog"), dir.file("none.lcm"));
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().message, dir.file("none.rawlog") + ": no such rawlog file");
}

TEST(Slam2dConfig, UnknownKeysAndBadValuesNameTheFileLineAndKey) {
  auto bad = parse_slam2d_config(YAML::Load("scan_channel: SCAN\nthreshold_distance: 0.3\n"), "r.yaml");
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message.rfind("r.yaml:2: unknown key 'slam.2d.threshold_distance'", 0), 0u)
      << bad.error().message;
  auto negative = parse_slam2d_config(YAML::Load("threshold_dist: -1\n"), "r.yaml");
  ASSERT_FALSE(negative);
  EXPECT_EQ(negative.error().message, "r.yaml:1: slam.2d.threshold_dist = -1 must be > 0");
  auto ini = parse_slam2d_config(YAML::Load("ini: /nonexistent.ini\n"), "r.yaml");
  ASSERT_FALSE(ini);
  EXPECT_NE(ini.error().message.find("cannot open /nonexistent.ini"), std::string::npos);
}

// An .ini is icp-slam's: MRPT's map builder, from its own library (slam/internal/icp_slam.h), takes one that asks
// for MRPT's Levenberg-Marquardt ICP, which the graph method (icp_align: the classic ICP) does not run; the graph
// method is refused an .ini at all, with the file and the key named.
TEST(Slam2d, AnIniIsForTheIcpSlamMethod) {
  test::TempDir dir;
  const std::string ini = dir.file("lm.ini");
  std::ofstream(ini) << "[ICP]\nICP_algorithm=icpLevenbergMarquardt\n";
  auto graph = parse_slam2d_config(YAML::Load("ini: " + ini + "\nmethod: graph\n"), "r.yaml");
  ASSERT_FALSE(graph);
  EXPECT_EQ(graph.error().message, "r.yaml:1: slam.2d.ini: an icp-slam .ini file is for method icp-slam");

  auto icp_slam = parse_slam2d_config(YAML::Load("ini: " + ini + "\n"), "r.yaml");
  ASSERT_TRUE(icp_slam) << icp_slam.error().message;
  ASSERT_EQ(icp_slam->method, "icp-slam");
  Slam2d taken{*icp_slam};
  test::FakeBus bus;
  bus.add(taken);
  const auto started = bus.start();
  EXPECT_TRUE(started.ok()) << started.message();
}

}  // namespace
}  // namespace driftlab::slam
