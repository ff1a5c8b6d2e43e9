#include "sim/scenario.h"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

#include "core/internal/faults_yaml.h"
#include "core/internal/yaml_fields.h"

namespace driftlab::sim {
namespace {

struct TypeName {
  SensorType type;
  const char* name;
};
constexpr TypeName kSensorTypes[] = {
    {SensorType::kLidar2d, "lidar2d"},         {SensorType::kLidar3d, "lidar3d"},
    {SensorType::kImu, "imu"},                 {SensorType::kOdometry, "odometry"},
    {SensorType::kCamera, "camera"},           {SensorType::kGroundTruth, "ground_truth"},
    {SensorType::kJointState, "joint_state"},
};

std::string resolve(const std::string& base_dir, const std::string& path) {
  if (path.empty() || path[0] == '/' || base_dir.empty()) return path;
  return (std::filesystem::path(base_dir) / path).lexically_normal().string();
}

Status parse_sensor(const YAML::Node& node, const std::string& origin, SensorConfig& s) {
  if (!node.IsMap()) return Error{at(origin, node) + ": a sensor must be a map with type, channel, rate, ..."};
  s.line = node.Mark().line + 1;
  std::string type;
  if (!node["type"].IsDefined()) return Error{at(origin, node) + ": a sensor needs a 'type'"};
  type = node["type"].as<std::string>();
  bool found = false;
  std::string known_types;
  for (const TypeName& t : kSensorTypes) {
    known_types += (known_types.empty() ? "" : ", ") + std::string(t.name);
    if (type == t.name) {
      s.type = t.type;
      found = true;
    }
  }
  if (!found) {
    return Error{at(origin, node["type"]) + ": unknown sensor type '" + type + "' (known: " + known_types + ")"};
  }
  if (!node["channel"].IsDefined()) return Error{at(origin, node) + ": the " + type + " sensor needs a 'channel'"};
  const std::string channel = node["channel"].as<std::string>();
  Fields f(node, origin, channel);
  f.node("type");
  DL_TRY(f.text("channel", s.channel));
  if (s.channel.empty()) return Error{at(origin, node) + ": a sensor's channel must not be empty"};
  DL_TRY(f.text("link", s.link));
  DL_TRY(f.positive("rate", s.rate));
  std::string known = "type, channel, link, rate";
  switch (s.type) {
    case SensorType::kLidar2d: {
      auto& p = s.lidar2d;
      DL_TRY(f.integer("beams", p.beams, 1, 1 << 20));
      DL_TRY(f.positive("fov", p.fov));
      DL_TRY(f.number("range_min", p.range_min, 0, 1e6));
      DL_TRY(f.positive("range_max", p.range_max));
      DL_TRY(f.number("range_noise", p.range_noise, 0, 1e3));
      known += ", beams, fov, range_min, range_max, range_noise";
      if (p.range_min >= p.range_max) return Error{f.where("range_max") + " must exceed range_min"};
      break;
    }
    case SensorType::kLidar3d: {
      auto& p = s.lidar3d;
      DL_TRY(f.integer("rings", p.rings, 1, 4096));
      DL_TRY(f.integer("columns", p.columns, 1, 1 << 16));
      DL_TRY(f.number("vertical_min", p.vertical_min, -M_PI / 2, M_PI / 2));
      DL_TRY(f.number("vertical_max", p.vertical_max, -M_PI / 2, M_PI / 2));
      DL_TRY(f.number("range_min", p.range_min, 0, 1e6));
      DL_TRY(f.positive("range_max", p.range_max));
      DL_TRY(f.number("range_noise", p.range_noise, 0, 1e3));
      known += ", rings, columns, vertical_min, vertical_max, range_min, range_max, range_noise";
      if (p.vertical_min > p.vertical_max) return Error{f.where("vertical_max") + " must not be below vertical_min"};
      if (p.range_min >= p.range_max) return Error{f.where("range_max") + " must exceed range_min"};
      break;
    }
    case SensorType::kImu: {
      auto& p = s.imu;
      DL_TRY(f.number("gyro_noise_density", p.gyro_noise_density, 0, 1e3));
      DL_TRY(f.number("gyro_random_walk", p.gyro_random_walk, 0, 1e3));
      DL_TRY(f.number("accel_noise_density", p.accel_noise_density, 0, 1e3));
      DL_TRY(f.number("accel_random_walk", p.accel_random_walk, 0, 1e3));
      DL_TRY(f.number("gyro_bias", p.gyro_bias, 0, 1e3));
      DL_TRY(f.number("accel_bias", p.accel_bias, 0, 1e3));
      known += ", gyro_noise_density, gyro_random_walk, accel_noise_density, accel_random_walk, gyro_bias, accel_bias";
      break;
    }
    case SensorType::kOdometry: {
      auto& p = s.odometry;
      DL_TRY(f.integer("ticks_per_rev", p.ticks_per_rev, 1, 1 << 30));
      DL_TRY(f.number("left_radius_error", p.left_radius_error, -0.5, 0.5));
      DL_TRY(f.number("right_radius_error", p.right_radius_error, -0.5, 0.5));
      DL_TRY(f.number("separation_error", p.separation_error, -0.5, 0.5));
      DL_TRY(f.number("slip_noise", p.slip_noise, 0, 1));
      DL_TRY(f.text("frame", p.frame));
      DL_TRY(f.text("tf_channel", p.tf_channel));
      known += ", ticks_per_rev, left_radius_error, right_radius_error, separation_error, slip_noise, frame, tf_channel";
      break;
    }
    case SensorType::kCamera: {
      auto& p = s.camera;
      DL_TRY(f.integer("width", p.width, 8, 8192));
      DL_TRY(f.integer("height", p.height, 8, 8192));
      DL_TRY(f.number("hfov", p.hfov, 0.01, 3.1));
      DL_TRY(f.positive("max_range", p.max_range));
      DL_TRY(f.text("encoding", p.encoding));
      DL_TRY(f.integer("quality", p.quality, 1, 100));
      known += ", width, height, hfov, max_range, encoding, quality";
      if (p.encoding != "jpeg" && p.encoding != "png") {
        return Error{f.where("encoding") + " = " + p.encoding + " must be jpeg or png"};
      }
      break;
    }
    case SensorType::kGroundTruth:
    case SensorType::kJointState:
      break;
  }
  return f.finish(known);
}

}  // namespace

const char* sensor_type_name(SensorType type) {
  for (const TypeName& t : kSensorTypes) {
    if (t.type == type) return t.name;
  }
  return "?";
}

Result<Scenario> parse_scenario(const std::string& text, const std::string& origin, const std::string& base_dir) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    return Error{origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
  }
  Scenario sc;
  sc.path = origin;
  if (!root.IsMap()) return Error{origin + ":1: a scenario must be a map (name, world, robot, sensors, ...)"};
  try {
    Fields top(root, origin, "");
    DL_TRY(top.text("name", sc.name));
    DL_TRY(top.positive("duration", sc.duration));
    if (top.has("seed")) {
      try {
        sc.seed = top.node("seed").as<uint64_t>();
      } catch (const YAML::Exception&) {
        return Error{top.where("seed") + " must be a non-negative integer"};
      }
    }
    double start_time = static_cast<double>(sc.start_utime) * 1e-6;
    DL_TRY(top.number("start_time", start_time, 0, 4e9));
    sc.start_utime = static_cast<int64_t>(std::llround(start_time * 1e6));
    DL_TRY(top.positive("physics_step", sc.physics_step));
    if (sc.physics_step > 0.02) return Error{top.where("physics_step") + " must be at most 0.02 s"};
    DL_TRY(top.integer("solver_iterations", sc.solver_iterations, 1, 1000));

    if (!top.has("world")) return Error{origin + ": the scenario needs a 'world' (a world file)"};
    DL_TRY(top.text("world", sc.world_path));
    sc.world_path = resolve(base_dir, sc.world_path);
    auto world = load_world(sc.world_path);
    if (!world) return world.error();
    sc.world = std::move(*world);

    if (!top.has("robot")) return Error{origin + ": the scenario needs a 'robot' (urdf, start, drive joints)"};
    {
      Fields r(top.node("robot"), origin, "robot");
      DL_TRY(r.is_map());
      if (!r.has("urdf")) return Error{at(origin, root["robot"]) + ": robot needs a 'urdf' file"};
      DL_TRY(r.text("urdf", sc.urdf_path));
      sc.urdf_path = resolve(base_dir, sc.urdf_path);
      std::vector<double> start;
      DL_TRY(r.vector("start", start, 3));
      if (!start.empty()) sc.start = Eigen::Vector3d(start[0], start[1], start[2]);
      DL_TRY(r.text("left_wheel_joint", sc.drive.left_joint));
      DL_TRY(r.text("right_wheel_joint", sc.drive.right_joint));
      DL_TRY(r.positive("max_wheel_torque", sc.drive.max_wheel_torque));
      DL_TRY(r.number("wheel_friction", sc.drive.wheel_friction, 0, 10));
      DL_TRY(r.number("body_friction", sc.drive.body_friction, 0, 10));
      DL_TRY(r.finish("urdf, start, left_wheel_joint, right_wheel_joint, max_wheel_torque, wheel_friction, body_friction"));
    }

    if (top.has("controller")) {
      Fields c(top.node("controller"), origin, "controller");
      DL_TRY(c.is_map());
      auto& p = sc.controller.pursuit;
      DL_TRY(c.positive("rate", sc.controller.rate));
      DL_TRY(c.text("channel", sc.controller.channel));
      DL_TRY(c.positive("lookahead", p.lookahead));
      DL_TRY(c.positive("speed", p.speed));
      DL_TRY(c.positive("max_angular", p.max_angular));
      DL_TRY(c.positive("max_accel", p.max_accel));
      DL_TRY(c.positive("turn_in_place", p.turn_in_place));
      DL_TRY(c.positive("goal_tolerance", p.goal_tolerance));
      DL_TRY(c.boolean("loop", p.loop));
      DL_TRY(c.positive("footprint_radius", sc.controller.footprint_radius));
      DL_TRY(c.finish("rate, channel, lookahead, speed, max_angular, max_accel, turn_in_place, goal_tolerance, loop, "
                      "footprint_radius"));
    }

    if (!top.has("route")) return Error{origin + ": the scenario needs a 'route' (a list of [x, y] points)"};
    {
      const YAML::Node route = top.node("route");
      if (!route.IsSequence() || route.size() < 2) {
        return Error{at(origin, route) + ": route must be a list of at least two [x, y] points"};
      }
      double length = 0;
      for (const auto& p : route) {
        if (!p.IsSequence() || p.size() != 2) return Error{at(origin, p) + ": a route point must be [x, y]"};
        try {
          sc.route.push_back({p[0].as<double>(), p[1].as<double>()});
        } catch (const YAML::Exception&) {
          return Error{at(origin, p) + ": a route point must be two numbers [x, y]"};
        }
        if (!std::isfinite(sc.route.back().x) || !std::isfinite(sc.route.back().y)) {
          return Error{at(origin, p) + ": a route point must be finite"};
        }
        if (sc.route.size() > 1) {
          const auto& a = sc.route[sc.route.size() - 2];
          length += std::hypot(sc.route.back().x - a.x, sc.route.back().y - a.y);
        }
      }
      if (!(length > 0)) return Error{at(origin, route) + ": the route has no length (its points are all the same)"};
    }

    if (top.has("tf")) {
      Fields t(top.node("tf"), origin, "tf");
      DL_TRY(t.is_map());
      DL_TRY(t.text("static_channel", sc.tf_static_channel));
      DL_TRY(t.positive("static_rate", sc.tf_static_rate));
      DL_TRY(t.finish("static_channel, static_rate"));
    }
    DL_TRY(top.text("faults_channel", sc.faults_channel));

    if (!top.has("sensors")) return Error{origin + ": the scenario needs 'sensors'"};
    {
      const YAML::Node sensors = top.node("sensors");
      if (!sensors.IsSequence()) return Error{at(origin, sensors) + ": sensors must be a list"};
      std::set<std::string> channels{sc.controller.channel, sc.tf_static_channel, sc.faults_channel};
      for (const auto& node : sensors) {
        SensorConfig s;
        DL_TRY(parse_sensor(node, origin, s));
        if (!channels.insert(s.channel).second) {
          return Error{at(origin, node) + ": channel '" + s.channel + "' is used twice"};
        }
        sc.sensors.push_back(std::move(s));
      }
    }

    if (top.has("faults")) {
      auto faults = parse_faults(top.node("faults"), origin);
      if (!faults) return Error{faults.error()};
      sc.faults = std::move(*faults);
      if (!root["faults"]["seed"].IsDefined()) sc.faults.seed = sc.seed;
    } else {
      sc.faults.seed = sc.seed;
    }
    DL_TRY(top.finish("name, duration, seed, start_time, physics_step, solver_iterations, world, robot, controller, route, tf, "
                      "faults_channel, sensors, faults"));
  } catch (const YAML::Exception& e) {
    // A key of the wrong shape (e.g. a map where a string belongs) that the checks above did not anticipate.
    return Error{origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
  }
  return sc;
}

Result<Scenario> load_scenario(const std::string& path) {
  std::ifstream f(path);
  if (!f) return Error{path + ": cannot open the scenario file"};
  std::stringstream text;
  text << f.rdbuf();
  return parse_scenario(text.str(), path, std::filesystem::path(path).parent_path().string());
}

std::string default_scenario_path() { return std::string(DRIFTLAB_SOURCE_DIR) + "/sim/scenarios/indoor.yaml"; }

}  // namespace driftlab::sim
