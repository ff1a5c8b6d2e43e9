// parse_scenario / load_scenario: the shipped scenarios, every sensor type's parameters, and one-line errors.
#include "sim/scenario.h"

#include <gtest/gtest.h>

#include <fstream>

#include "tests/test_util.h"

namespace driftlab::sim {
namespace {

const std::string kSim = std::string(DRIFTLAB_SOURCE_DIR) + "/sim";

std::string base(const std::string& sensors, const std::string& extra = "") {
  return "world: worlds/building.yaml\nrobot: {urdf: robots/diffbot.urdf}\nroute: [[0, 0], [1, 0]]\n" + extra +
         "sensors:\n" + sensors;
}

Result<Scenario> parse(const std::string& text) { return parse_scenario(text, "s.yaml", kSim); }

TEST(Scenario, ShippedScenariosLoad) {
  for (const char* name : {"indoor", "indoor_3d", "warehouse"}) {
    auto sc = load_scenario(kSim + "/scenarios/" + name + ".yaml");
    ASSERT_TRUE(sc.ok()) << sc.error().message;
    EXPECT_EQ(sc->name, name);
    EXPECT_FALSE(sc->sensors.empty());
    EXPECT_GE(sc->route.size(), 4u);
  }
  auto d = load_scenario(default_scenario_path());
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->name, "indoor");
  EXPECT_DOUBLE_EQ(d->duration, 600);
  EXPECT_EQ(d->faults.streams.at("IMU").clock_offset_s, 0.015);
  EXPECT_EQ(d->faults.seed, d->seed);  // the run's seed unless the faults name their own
}

TEST(Scenario, EverySensorsParameters) {
  auto sc = parse(base(R"(
  - {type: lidar2d, channel: S, link: laser, rate: 12, beams: 90, fov: 3.0, range_min: 0.2, range_max: 8, range_noise: 0.05}
  - {type: lidar3d, channel: P, link: velodyne, rings: 32, columns: 900, vertical_min: -0.5, vertical_max: 0.2}
  - {type: imu, channel: I, rate: 400, gyro_noise_density: 0.001, accel_random_walk: 0.01, gyro_bias: 0}
  - {type: odometry, channel: O, ticks_per_rev: 100, separation_error: 0.01, slip_noise: 0.02, tf_channel: ""}
  - {type: camera, channel: C, width: 64, height: 48, encoding: png}
  - {type: ground_truth, channel: G}
  - {type: joint_state, channel: J, rate: 5}
)",
                       "duration: 7\nseed: 3\nfaults: {seed: 9, streams: {S: {drop_probability: 0.5}}}\n"));
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  ASSERT_EQ(sc->sensors.size(), 7u);
  EXPECT_EQ(sc->sensors[0].type, SensorType::kLidar2d);
  EXPECT_EQ(sc->sensors[0].lidar2d.beams, 90);
  EXPECT_DOUBLE_EQ(sc->sensors[0].rate, 12);
  EXPECT_EQ(sc->sensors[1].lidar3d.rings, 32);
  EXPECT_DOUBLE_EQ(sc->sensors[1].lidar3d.vertical_min, -0.5);
  EXPECT_DOUBLE_EQ(sc->sensors[2].imu.gyro_noise_density, 0.001);
  EXPECT_DOUBLE_EQ(sc->sensors[2].imu.gyro_bias, 0);
  EXPECT_EQ(sc->sensors[3].odometry.ticks_per_rev, 100);
  EXPECT_EQ(sc->sensors[3].odometry.tf_channel, "");
  EXPECT_EQ(sc->sensors[4].camera.encoding, "png");
  EXPECT_EQ(sc->sensors[6].type, SensorType::kJointState);
  EXPECT_EQ(sc->sensors[6].line, 15);
  EXPECT_EQ(sc->seed, 3u);
  EXPECT_EQ(sc->faults.seed, 9u);
  EXPECT_DOUBLE_EQ(sc->duration, 7);
  EXPECT_EQ(sc->world_path, kSim + "/worlds/building.yaml");
}

TEST(Scenario, ErrorsNameTheLineAndTheKey) {
  auto err = [](const std::string& text) {
    auto sc = parse(text);
    return sc.ok() ? std::string("ok") : sc.error().message;
  };
  EXPECT_EQ(err(base("  - {type: imu, channel: I, rate: 0}")), "s.yaml:5: I.rate = 0 must be > 0");
  EXPECT_EQ(err(base("  - {type: imu, channel: I, beams: 3}")).substr(0, 31), "s.yaml:5: unknown key 'I.beams'");
  EXPECT_EQ(err(base("  - {type: camera, channel: C, encoding: gif}")), "s.yaml:5: C.encoding = gif must be jpeg or png");
  EXPECT_EQ(err(base("  - {type: lidar2d, channel: S, range_min: 5, range_max: 2}")),
            "s.yaml:5: S.range_max must exceed range_min");
  EXPECT_EQ(err(base("  - {type: imu, channel: A}\n  - {type: imu, channel: A}")),
            "s.yaml:6: channel 'A' is used twice");
  EXPECT_EQ(err(base("  - {channel: A}")), "s.yaml:5: a sensor needs a 'type'");
  EXPECT_EQ(err("world: worlds/building.yaml\nrobot: {urdf: r.urdf}\nroute: [[1, 1], [1, 1]]\nsensors: []\n"),
            "s.yaml:3: route has no length (its points are all the same)");
  EXPECT_EQ(err("world: nowhere.yaml\n"),
            "s.yaml:1: world = nowhere.yaml: no such world file (" + kSim + "/nowhere.yaml)");
  EXPECT_EQ(err("world: [\n"), "s.yaml:2: end of sequence flow not found");
  EXPECT_EQ(err("- 1\n"), "s.yaml:1: a scenario must be a map (name, world, robot, sensors, ...)");
  EXPECT_EQ(err(base("  - {type: imu, channel: I}", "physics_step: 0.5\n")),
            "s.yaml:4: physics_step = 0.5 is outside 1e-05..0.02 s");
}

TEST(Scenario, OverridesFromTheCommandLine) {
  test::TempDir dir;
  auto sc = load_scenario(default_scenario_path());
  ASSERT_TRUE(sc.ok());
  // A seed seeds the faults too; a duration replaces the scenario's.
  ASSERT_TRUE(apply_overrides(*sc, {.duration = 30, .seed = 9}).ok());
  EXPECT_DOUBLE_EQ(sc->duration, 30);
  EXPECT_EQ(sc->seed, 9u);
  EXPECT_EQ(sc->faults.seed, 9u);
  // A fault description replaces `faults:`, is kept for the log's SIMULATION message, and takes the run's seed
  // unless it gives its own.
  const std::string path = dir.file("faults.yaml");
  std::ofstream(path) << "streams:\n  SCAN: {latency_s: 0.05}\n";
  ASSERT_TRUE(apply_overrides(*sc, {.faults_path = path}).ok());
  EXPECT_EQ(sc->faults_path, path);
  EXPECT_EQ(sc->faults_text, "streams:\n  SCAN: {latency_s: 0.05}\n");
  EXPECT_EQ(sc->faults.streams.count("IMU"), 0u);
  EXPECT_DOUBLE_EQ(sc->faults.streams.at("SCAN").latency_s, 0.05);
  EXPECT_EQ(sc->faults.seed, 9u);
  std::ofstream(path) << "seed: 3\nstreams:\n  SCAN: {latency_s: 0.05}\n";
  ASSERT_TRUE(apply_overrides(*sc, {.faults_path = path}).ok());
  EXPECT_EQ(sc->faults.seed, 3u);
  // A fault file that is not one: its own error, naming it; the scenario keeps what it had.
  std::ofstream(path) << "streams:\n  SCAN: {latency_s: -1}\n";
  Status bad = apply_overrides(*sc, {.faults_path = path});
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.message().rfind(path + ":", 0), 0u) << bad.message();
  EXPECT_EQ(sc->faults.seed, 3u);
  EXPECT_FALSE(apply_overrides(*sc, {.faults_path = dir.file("absent.yaml")}).ok());
}

}  // namespace
}  // namespace driftlab::sim
