#include "sim/scenario.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

#include "core/check.h"
#include "core/config.h"
#include "core/install_layout.h"
#include "core/text_file.h"
#include "core/time.h"

namespace driftlab::sim {
namespace {

struct TypeName {
  SensorType type;
  const char* name;
};
constexpr TypeName kSensorTypes[] = {
    {SensorType::kLidar2d, "lidar2d"},
    {SensorType::kLidar3d, "lidar3d"},
    {SensorType::kImu, "imu"},
    {SensorType::kOdometry, "odometry"},
    {SensorType::kCamera, "camera"},
    {SensorType::kGroundTruth, "ground_truth"},
    {SensorType::kJointState, "joint_state"},
    {SensorType::kBarometer, "barometer"},
    {SensorType::kGnss, "gnss"},
    {SensorType::kMagnetometer, "magnetometer"},
};

std::string resolve(const std::string& base_dir, const std::string& path) {
  if (path.empty() || path[0] == '/' || base_dir.empty()) return path;
  return (std::filesystem::path(base_dir) / path).lexically_normal().string();
}

const config::Table<Lidar2dParams>& lidar2d_table() {
  using P = Lidar2dParams;
  using config::between;
  static const auto t =
      config::Table<P>()
          .integer("beams", &P::beams, between(1, 1 << 20), "", "returns per scan")
          .number("fov", &P::fov, config::above(0, 6.3), "rad", "field of view, centred on the link's x axis")
          .number("range_min", &P::range_min, between(0, 1e6), "m", "nearer returns are none")
          .number("range_max", &P::range_max, config::above(0, 1e6), "m", "farther returns are none")
          .number("range_noise", &P::range_noise, between(0, 1e3), "m", "standard deviation of a range")
          .check([](const config::Value& v, P& p) -> Status {
            if (p.range_min >= p.range_max) return v["range_max"].error("must exceed range_min");
            return {};
          });
  return t;
}

const config::Table<Lidar3dParams>& lidar3d_table() {
  using P = Lidar3dParams;
  using config::between;
  static const auto t =
      config::Table<P>()
          .integer("rings", &P::rings, between(1, 4096), "", "rows of the organised cloud")
          .integer("columns", &P::columns, between(1, 1 << 16), "", "returns per ring and sweep")
          .number("vertical_min", &P::vertical_min, between(-1.5708, 1.5708), "rad", "elevation of the lowest ring")
          .number("vertical_max", &P::vertical_max, between(-1.5708, 1.5708), "rad", "elevation of the highest ring")
          .number("range_min", &P::range_min, between(0, 1e6), "m", "nearer returns are none")
          .number("range_max", &P::range_max, config::above(0, 1e6), "m", "farther returns are none")
          .number("range_noise", &P::range_noise, between(0, 1e3), "m", "standard deviation of a range")
          .check([](const config::Value& v, P& p) -> Status {
            if (p.vertical_min > p.vertical_max) return v["vertical_max"].error("must not be below vertical_min");
            if (p.range_min >= p.range_max) return v["range_max"].error("must exceed range_min");
            return {};
          });
  return t;
}

const config::Table<ImuParams>& imu_table() {
  using P = ImuParams;
  const auto r = config::between(0, 1e3);
  static const auto t =
      config::Table<P>()
          .number("gyro_noise_density", &P::gyro_noise_density, r, "rad/s/sqrt(Hz)", "gyro white noise (Kalibr's)")
          .number("gyro_random_walk", &P::gyro_random_walk, r, "rad/s^2/sqrt(Hz)", "gyro bias random walk")
          .number("accel_noise_density", &P::accel_noise_density, r, "m/s^2/sqrt(Hz)", "accelerometer white noise")
          .number("accel_random_walk", &P::accel_random_walk, r, "m/s^3/sqrt(Hz)", "accelerometer bias random walk")
          .number("gyro_bias", &P::gyro_bias, r, "rad/s", "standard deviation of each axis' initial gyro bias")
          .number("accel_bias", &P::accel_bias, r, "m/s^2",
                  "standard deviation of each axis' initial accelerometer bias");
  return t;
}

const config::Table<OdometryParams>& odometry_table() {
  using P = OdometryParams;
  using config::between;
  static const auto t =
      config::Table<P>()
          .integer("ticks_per_rev", &P::ticks_per_rev, between(1, 1 << 30), "", "encoder ticks per wheel turn")
          .number("left_radius_error", &P::left_radius_error, between(-0.5, 0.5), "",
                  "the odometry's belief of the left wheel radius is off by this fraction")
          .number("right_radius_error", &P::right_radius_error, between(-0.5, 0.5), "", "... and the right's")
          .number("separation_error", &P::separation_error, between(-0.5, 0.5), "", "... and the wheel separation's")
          .number("slip_noise", &P::slip_noise, between(0, 1), "",
                  "random slip: each wheel increment is off by this fraction (standard deviation)")
          .text("frame", &P::frame, "the odometry frame")
          .text("tf_channel", &P::tf_channel, "where odom -> base link also goes; \"\" for none");
  return t;
}

const config::Table<CameraParams>& camera_table() {
  using P = CameraParams;
  using config::between;
  static const auto t = config::Table<P>()
                            .integer("width", &P::width, between(8, 8192), "px", "image width")
                            .integer("height", &P::height, between(8, 8192), "px", "image height")
                            .number("hfov", &P::hfov, between(0.01, 3.1), "rad", "horizontal field of view")
                            .number("max_range", &P::max_range, config::above(0, 1e6), "m", "farther is sky")
                            .choice("encoding", &P::encoding, {"jpeg", "png"}, "image encoding")
                            .integer("quality", &P::quality, between(1, 100), "", "JPEG quality");
  return t;
}

const config::Table<BarometerParams>& barometer_table() {
  using P = BarometerParams;
  using config::between;
  static const auto t =
      config::Table<P>()
          .number("noise", &P::noise, between(0, 1e4), "Pa", "standard deviation of a reading (1 Pa: about 8 cm)")
          .number("offset_walk", &P::offset_walk, between(0, 1e3), "Pa/sqrt(s)", "random walk of the offset")
          .number("offset", &P::offset, between(-1e4, 1e4), "Pa", "initial offset of every reading")
          .number("temperature", &P::temperature, between(-100, 100), "degC", "reported air temperature");
  return t;
}

const config::Table<GnssParams>& gnss_table() {
  using P = GnssParams;
  using config::between;
  static const auto t =
      config::Table<P>()
          .number("horizontal_noise", &P::horizontal_noise, between(0, 1e4), "m",
                  "white noise of east and north, standard deviation")
          .number("vertical_noise", &P::vertical_noise, between(0, 1e4), "m", "... of the altitude")
          .number("horizontal_drift", &P::horizontal_drift, between(0, 1e4), "m",
                  "the slow wander of east and north (first-order Gauss-Markov), standard deviation")
          .number("vertical_drift", &P::vertical_drift, between(0, 1e4), "m", "... of the altitude")
          .number("correlation_time", &P::correlation_time, between(0, 1e5), "s", "of the wander; 0: none")
          .number("velocity_noise", &P::velocity_noise, between(0, 1e3), "m/s",
                  "white noise of each velocity component")
          .integer("satellites", &P::satellites, between(0, 200), "", "reported satellites");
  return t;
}

const config::Table<MagnetometerParams>& magnetometer_table() {
  using P = MagnetometerParams;
  static const auto t =
      config::Table<P>().number("noise", &P::noise, config::between(0, 1), "T", "standard deviation per axis");
  return t;
}

const config::Table<GeoConfig>& geo_table() {
  using G = GeoConfig;
  using config::between;
  static const auto t =
      config::Table<G>()
          .number("latitude", &G::latitude, between(-89, 89), "deg", "of the world's origin (WGS-84)")
          .number("longitude", &G::longitude, between(-180, 180), "deg", "of the world's origin (WGS-84)")
          .number("altitude", &G::altitude, between(-500, 9000), "m", "of the world's z = 0 above mean sea level")
          .number("declination", &G::declination, between(-M_PI, M_PI), "rad", "magnetic north east of true north")
          .number("inclination", &G::inclination, between(-M_PI / 2, M_PI / 2), "rad",
                  "the magnetic field's dip below the horizontal")
          .number("field", &G::field, config::above(0, 1e-3), "T", "the magnetic field's strength");
  return t;
}

std::vector<std::pair<std::string, SensorType>> sensor_types() {
  std::vector<std::pair<std::string, SensorType>> out;
  for (const TypeName& t : kSensorTypes) out.emplace_back(t.name, t.type);
  return out;
}

/// The keys every sensor has.
config::Table<SensorConfig> sensor_common_table() {
  using S = SensorConfig;
  return config::Table<S>()
      .choice("type", &S::type, sensor_types(), "what the sensor is (the sections below)")
      .required()
      .text("channel", &S::channel, "where its messages go", config::Text::kNonEmpty)
      .required()
      .text("link", &S::link, "the URDF link it sits on; \"\": the base link")
      .number("rate", &S::rate, config::above(0, 1e4), "Hz", "samples per second (at most one per physics step)");
}

/// The keys of a sensor of one type: the common ones and the type's.
const config::Table<SensorConfig>& sensor_table(SensorType type) {
  using S = SensorConfig;
  static const auto common = sensor_common_table();
  static const auto lidar2d = sensor_common_table().include(&S::lidar2d, lidar2d_table());
  static const auto lidar3d = sensor_common_table().include(&S::lidar3d, lidar3d_table());
  static const auto imu = sensor_common_table().include(&S::imu, imu_table());
  static const auto odometry = sensor_common_table().include(&S::odometry, odometry_table());
  static const auto camera = sensor_common_table().include(&S::camera, camera_table());
  static const auto barometer = sensor_common_table().include(&S::barometer, barometer_table());
  static const auto gnss = sensor_common_table().include(&S::gnss, gnss_table());
  static const auto magnetometer = sensor_common_table().include(&S::magnetometer, magnetometer_table());
  switch (type) {
    case SensorType::kLidar2d: return lidar2d;
    case SensorType::kLidar3d: return lidar3d;
    case SensorType::kImu: return imu;
    case SensorType::kOdometry: return odometry;
    case SensorType::kCamera: return camera;
    case SensorType::kBarometer: return barometer;
    case SensorType::kGnss: return gnss;
    case SensorType::kMagnetometer: return magnetometer;
    case SensorType::kGroundTruth:
    case SensorType::kJointState: return common;
  }
  driftlab::internal_error(__FILE__, __LINE__, "not a SensorType");
}

/// The `sensors:` list: each a map whose keys depend on its type; messages name a sensor by its channel.
Status read_sensors(const config::Value& v, std::vector<SensorConfig>& out) {
  if (!v.node().IsSequence()) return v.error("must be a list of sensors");
  std::vector<SensorConfig> sensors;
  for (std::size_t i = 0; i < v.node().size(); ++i) {
    const config::Value item = v[i];
    const YAML::Node& node = item.node();
    if (!node.IsMap()) return Error{item.place() + ": a sensor must be a map with type, channel, rate, ..."};
    const config::Value type = item["type"], channel = item["channel"];
    if (!type.given()) return Error{item.place() + ": a sensor needs a 'type'"};
    auto name = type.text();
    if (!name) return name.error();
    const auto types = sensor_types();
    auto known = std::find_if(types.begin(), types.end(), [&](const auto& t) { return t.first == *name; });
    if (known == types.end()) {
      std::string list;
      for (const auto& t : types) list += (list.empty() ? "" : ", ") + t.first;
      return Error{type.place() + ": unknown sensor type '" + *name + "' (known: " + list + ")"};
    }
    if (!channel.given()) return Error{item.place() + ": the " + *name + " sensor needs a 'channel'"};
    auto channel_name = channel.text();
    if (!channel_name) return channel_name.error();
    SensorConfig s;
    s.line = node.Mark().line + 1;
    if (Status st = sensor_table(known->second).read(config::Value(node, v.file(), *channel_name), s); !st) {
      return st;
    }
    sensors.push_back(std::move(s));
  }
  out = std::move(sensors);
  return {};
}

const config::Table<DriveOptions>& drive_table() {
  using D = DriveOptions;
  static const auto t =
      config::Table<D>()
          .text("left_wheel_joint", &D::left_joint, "continuous joint of the left drive wheel", config::Text::kNonEmpty)
          .text("right_wheel_joint", &D::right_joint, "... and of the right", config::Text::kNonEmpty)
          .number("max_wheel_torque", &D::max_wheel_torque, config::above(0, 1e4), "N*m",
                  "motor torque limit per wheel")
          .number("wheel_friction", &D::wheel_friction, config::between(0, 10), "",
                  "friction of the wheels (multiplied with the floor's)")
          .number("body_friction", &D::body_friction, config::between(0, 10), "",
                  "friction of every other body (casters slide)")
          .number("caster_deflection", &D::caster_deflection, config::between(0, 1), "m",
                  "the robot's weight compresses its casters this far when they and the wheels stand on 4+ points "
                  "(springs: the wheels keep the load); 0: rigid");
  return t;
}

const config::Table<ControllerConfig>& controller_table() {
  using C = ControllerConfig;
  static const auto t =
      config::Table<C>()
          .number("rate", &C::rate, config::between(0.1, 1000), "Hz", "commands per second")
          .text("channel", &C::channel, "driftlab.velocity_command_t out", config::Text::kNonEmpty)
          .number("footprint_radius", &C::footprint_radius, config::above(0, 100), "m",
                  "the robot's footprint, for the reactive obstacle avoidance")
          .include(&C::pursuit, controller::pure_pursuit_table());
  return t;
}

std::string show_route(const std::vector<controller::Point2>& r) { return std::to_string(r.size()) + " points"; }

}  // namespace

const char* sensor_type_name(SensorType type) {
  for (const TypeName& t : kSensorTypes) {
    if (t.type == type) return t.name;
  }
  return "?";
}

const config::Table<Scenario>& scenario_table() {
  using S = Scenario;
  using config::Text;
  static const auto robot =
      config::Table<S>()
          .text("urdf", &S::urdf_path, "the robot's URDF file (relative to the scenario)", Text::kNonEmpty)
          .required()
          .numbers("start", &S::start, config::between(-1e6, 1e6), "m, m, rad",
                   "x, y, yaw of the base link in the world at the start")
          .include(&S::drive, drive_table());
  static const auto tf = config::Table<S>()
                             .text("static_channel", &S::tf_static_channel, "driftlab.tf_t of the fixed frames")
                             .number("static_rate", &S::tf_static_rate, config::above(0, 1000), "Hz",
                                     "how often the fixed frames are published");
  static const auto t =
      config::Table<S>()
          .text("name", &S::name, "the scenario's name, for messages")
          .number("duration", &S::duration, config::above(0, 1e7), "s", "simulated time")
          .integer("seed", &S::seed, config::at_least(0), "",
                   "noise and faults; the same scenario and seed give a byte-identical log")
          .custom<int64_t>(
              "start_time", &S::start_utime, "number", "s", "0..4e+09", "true time of the first step, since the epoch",
              [](const config::Value& v, int64_t& utime) -> Status {
                auto s = v.number(config::between(0, 4e9), "s");
                if (!s) return s.error();
                utime = Time::from_seconds_rounded(*s).us();
                return {};
              },
              [](const int64_t& utime) { return config::format_number(Time::from_us(utime).seconds()); })
          .number("physics_step", &S::physics_step, config::between(1e-5, 0.02), "s", "the physics time step")
          .integer("solver_iterations", &S::solver_iterations, config::between(1, 1000), "",
                   "Bullet's constraint solver iterations per step")
          .number("physics_cost", &S::physics_cost, config::between(0, 10), "s",
                  "wall-clock time a physics update takes: above physics_step, the simulation runs slower than real "
                  "time, and the log's times (and a wall-clock offboard script) see it; 0: free")
          .text("physics_channel", &S::physics_channel,
                "driftlab.physics_step_t of the simulator's own step times (with physics_cost)", Text::kNonEmpty)
          .number("physics_rate", &S::physics_rate, config::above(0, 1000), "Hz", "physics_step_t per second")
          .text("world", &S::world_path, "the world file (relative to the scenario; docs/worlds.md)", Text::kNonEmpty)
          .required()
          .section("robot", robot, "the robot: its URDF, start pose and drive")
          .required()
          .section("controller", &S::controller, controller_table(),
                   "the path follower, closed loop on the robot's own wheel odometry")
          .custom<std::vector<controller::Point2>>("route", &S::route, "list of [x, y]", "m", "at least 2 points",
                                                   "driven in order; with loop, it closes on itself",
                                                   controller::read_route, show_route)
          .shown_default("required unless drone")
          .section("tf", tf, "the fixed frames")
          .text("faults_channel", &S::faults_channel, "driftlab.fault_manifest_t of the injected faults (truth)")
          .text("simulation_channel", &S::simulation_channel,
                "driftlab.simulation_t: the scenario as run, for driftlab replay --closed-loop (truth)")
          .custom<std::vector<SensorConfig>>(
              "sensors", &S::sensors, "list of sensors", "", "", "each a map of the keys below", read_sensors,
              [](const std::vector<SensorConfig>& s) { return std::to_string(s.size()) + " sensors"; })
          .required()
          .section("faults", &S::faults, fault_config_table(),
                   "the faults injected, as a fault description (below); without seed: the scenario's")
          .brief()
          .section("arm", &S::arm, arm_table(),
                   "an arm on the robot: its joint trajectory controller and commander (docs/simulator.md)")
          .section("drone", &S::drone, drone_table(),
                   "the robot is a multirotor flown by its flight stack on board (docs/simulator.md)")
          .section("geo", &S::geo, geo_table(), "where the world is on Earth (GNSS, barometer, magnetometer)")
          .check([](const config::Value& v, S& sc) -> Status {
            sc.drone.enabled = v["drone"].given();
            if (sc.drone.enabled && v["arm"].given()) return v["arm"].error("cannot be on a drone");
            if (!sc.drone.enabled && !v["route"].given()) {
              return Error{v.place() + ": missing key 'route' (driven in order; a drone's scenario has none)"};
            }
            std::set<std::string> channels{sc.controller.channel, sc.tf_static_channel, sc.faults_channel,
                                           sc.simulation_channel};
            for (std::size_t i = 0; i < sc.sensors.size(); ++i) {
              if (!channels.insert(sc.sensors[i].channel).second) {
                return Error{v["sensors"][i].place() + ": channel '" + sc.sensors[i].channel + "' is used twice"};
              }
            }
            if (!v["faults"]["seed"].given()) sc.faults.seed = sc.seed;
            sc.arm.enabled = v["arm"].given();
            return {};
          });
  return t;
}

std::string scenario_reference() {
  std::string out = scenario_table().reference();
  out += "\n### Sensors\n\nEvery sensor has these keys:\n\n" + sensor_table(SensorType::kGroundTruth).reference();
  struct Section {
    const char* type;
    std::string table;
  };
  const Section sections[] = {
      {"lidar2d", lidar2d_table().reference()}, {"lidar3d", lidar3d_table().reference()},
      {"imu", imu_table().reference()},         {"odometry", odometry_table().reference()},
      {"camera", camera_table().reference()},   {"barometer", barometer_table().reference()},
      {"gnss", gnss_table().reference()},       {"magnetometer", magnetometer_table().reference()}};
  for (const Section& sec : sections) out += std::string("\nand with `type: ") + sec.type + "`:\n\n" + sec.table;
  out += "\n`ground_truth` and `joint_state` have no keys of their own.\n";
  return out;
}

Result<Scenario> parse_scenario(const std::string& text, const std::string& origin, const std::string& base_dir) {
  auto root = config::parse_yaml(text, origin);
  if (!root) return root.error();
  if (!root->IsMap()) return Error{origin + ":1: a scenario must be a map (name, world, robot, sensors, ...)"};
  const config::Value doc(*root, origin);
  Scenario sc;
  sc.path = origin;
  sc.text = text;
  // The world first: its own errors come before those of the keys after it.
  if (const config::Value world = doc["world"]; world.given()) {
    auto path = world.text();
    if (!path) return path.error();
    // A world that is not there is named where the scenario gives it; a world's own errors name its file.
    const std::string file = resolve(base_dir, *path);
    if (std::error_code ec; !std::filesystem::is_regular_file(file, ec)) {
      return world.error("= " + *path + ": no such world file (" + file + ")");
    }
    auto w = load_world(file);
    if (!w) return w.error();
    sc.world = std::move(*w);
  }
  if (Status s = scenario_table().read(doc, sc); !s) return s.error();
  sc.world_path = resolve(base_dir, sc.world_path);
  sc.urdf_path = resolve(base_dir, sc.urdf_path);
  return sc;
}

Result<Scenario> load_scenario(const std::string& path) {
  auto text = read_text_file(path, "scenario file");
  if (!text) return text.error();
  return parse_scenario(*text, path, std::filesystem::path(path).parent_path().string());
}

Status apply_overrides(Scenario& scenario, const ScenarioOverrides& o) {
  if (o.duration > 0) scenario.duration = o.duration;
  if (o.seed >= 0) {
    scenario.seed = static_cast<uint64_t>(o.seed);
    scenario.faults.seed = static_cast<uint64_t>(o.seed);
  }
  if (o.faults_path.empty()) return {};
  auto text = read_text_file(o.faults_path, "fault description");
  if (!text) return text.error();
  auto faults = parse_faults(*text, o.faults_path);
  if (!faults) return faults.error();
  scenario.faults_path = o.faults_path;
  scenario.faults_text = std::move(*text);
  const bool own_seed = faults->seed != 0;
  scenario.faults = std::move(*faults);
  if (!own_seed) scenario.faults.seed = scenario.seed;
  return {};
}

std::string default_scenario_path() { return data_path("scenarios/indoor.yaml").string(); }

}  // namespace driftlab::sim
