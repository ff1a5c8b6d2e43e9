#include "sim/simulator.h"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>

#include "core/log_index.h"
#include "core/log_reader.h"
#include "core/log_writer.h"
#include "core/text_file.h"
#include "core/time.h"
#include "driftlab/fault_manifest_t.hpp"
#include "driftlab/physics_step_t.hpp"
#include "driftlab/simulation_t.hpp"
#include "driftlab/tf_t.hpp"
#include "driftlab/velocity_command_t.hpp"
#include "lcmtypes/validate.h"
#include "sim/bullet_world.h"
#include "sim/internal/arm_loop.h"
#include "sim/internal/drone_loop.h"
#include "sim/internal/ground_loop.h"
#include "sim/internal/output.h"
#include "sim/internal/sensors.h"
#include "sim/raycaster.h"

namespace driftlab::sim {

std::string faults_json_path(const std::string& log) {
  std::filesystem::path p(log);
  if (p.extension() == ".lcm") p.replace_extension();
  return p.string() + ".faults.json";
}

namespace {

Status write_faults_json(const std::string& path, const Scenario& sc, int64_t end_utime,
                         const std::vector<driftlab::fault_t>& faults) {
  nlohmann::json j;
  j["scenario"] = sc.path;
  j["seed"] = sc.faults.seed;
  j["start_utime"] = sc.start_utime;
  j["end_utime"] = end_utime;
  j["faults"] = nlohmann::json::array();
  for (const auto& f : faults) {
    nlohmann::json params = nlohmann::json::object();
    for (std::size_t i = 0; i < f.param_names.size(); ++i) params[f.param_names[i]] = f.param_values[i];
    j["faults"].push_back({{"channel", f.channel},
                           {"kind", f.kind},
                           {"start_utime", f.start_utime},
                           {"end_utime", f.end_utime},
                           {"params", params},
                           {"affected_seq", f.affected_seq}});
  }
  return write_file_atomically(path, j.dump(2) + "\n");
}

driftlab::vector3_t vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

/// The static TF at now: the links fixed in the robot's base that carry sensors, the arm's and the drone's fixed
/// joints, and world -> `odom_frame` (the odometry frame at the robot's start pose) when given.
driftlab::tf_t static_tf(const Scenario& sc, const Robot& robot, const std::vector<std::string>& static_links,
                         const ArmLoop* arm, const DroneLoop* drone, const std::string* odom_frame, int64_t now) {
  driftlab::tf_t tf{};
  tf.header.frame_id = robot.base_link();
  for (const std::string& link : static_links) {
    const Eigen::Isometry3d p = *robot.fixed_in_base(link);
    driftlab::transform_t t{};
    t.header.utime = now;
    t.header.frame_id = robot.base_link();
    t.child_frame_id = link;
    t.translation = vec(p.translation());
    const Eigen::Quaterniond q(p.rotation());
    t.rotation = {q.w(), q.x(), q.y(), q.z()};
    tf.transforms.push_back(t);
  }
  if (arm != nullptr) arm->add_static(tf, now);
  if (drone != nullptr) drone->add_static(tf, now);
  if (odom_frame != nullptr) {
    driftlab::transform_t t{};
    t.header.utime = now;
    t.header.frame_id = "world";
    t.child_frame_id = *odom_frame;
    t.translation = {sc.start.x(), sc.start.y(), 0};
    t.rotation = {std::cos(sc.start.z() / 2), 0, 0, std::sin(sc.start.z() / 2)};
    tf.transforms.push_back(t);
  }
  return tf;
}

/// The fault manifest's message: every fault injected, as the log's last event at end_utime.
std::vector<uint8_t> manifest_bytes(const Scenario& sc, const std::vector<driftlab::fault_t>& faults,
                                    int64_t end_utime) {
  driftlab::fault_manifest_t manifest{};
  manifest.header.seq = 0;
  manifest.header.utime = end_utime;
  manifest.header.frame_id = "";
  manifest.seed = static_cast<int64_t>(sc.faults.seed);
  manifest.faults = faults;
  manifest.nfaults = static_cast<int32_t>(faults.size());
  std::vector<uint8_t> bytes(static_cast<std::size_t>(manifest.getEncodedSize()));
  manifest.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

}  // namespace

Result<Scenario> scenario_of_log(const std::string& log) {
  auto reader = LogReader::open(log, {.channels = "SIMULATION"});
  if (!reader) return reader.error();
  Event e;
  driftlab::simulation_t m;
  bool found = false;
  while (!found && reader->next(e)) found = lcmtypes::decode(e.data, m);
  if (!found) {
    return Error{log +
                 ": no SIMULATION message: it was not made by driftlab sim (or by one before the message), so "
                 "there is no simulation to run again"};
  }
  auto sc =
      parse_scenario(m.scenario_yaml, m.scenario_path, std::filesystem::path(m.scenario_path).parent_path().string());
  if (!sc) return Error{log + ": its scenario " + m.scenario_path + ": " + sc.error().message};
  // The duration is the log's word: 1e7 s, NaN or a negative number was obeyed (a closed-loop replay running for
  // months, or not at all). It must be a positive number, and one the log's own span can account for: a simulation
  // of D seconds logs events over about D seconds (a generous bound: twice the span and a minute).
  {
    char said[32];
    std::snprintf(said, sizeof said, "%.6g", m.duration_s);
    if (!std::isfinite(m.duration_s) || m.duration_s <= 0) {
      return Error{log + ": its SIMULATION message's duration_s = " + said +
                   " is not a duration (a positive number of seconds): the message is damaged"};
    }
    auto index = LogIndex::load_or_build(log);
    if (!index) return index.error();
    const double span = static_cast<double>(index->summary().end_utime - index->summary().start_utime) * 1e-6;
    if (m.duration_s > 2 * span + 60) {
      char spans[32];
      std::snprintf(spans, sizeof spans, "%.6g", span);
      return Error{log + ": its SIMULATION message's duration_s = " + said + " s, but the log spans " + spans +
                   " s (a simulation that long would have logged for that long): the message is damaged"};
    }
  }
  sc->duration = m.duration_s;
  sc->seed = static_cast<uint64_t>(m.seed);
  if (!m.faults_yaml.empty()) {
    auto faults = parse_faults(m.faults_yaml, m.faults_path);
    if (!faults) return Error{log + ": its faults: " + faults.error().message};
    sc->faults = std::move(*faults);
    sc->faults_path = m.faults_path;
    sc->faults_text = m.faults_yaml;
  }
  sc->faults.seed = static_cast<uint64_t>(m.faults_seed);
  return sc;
}

struct Simulation::Impl {
  Scenario sc;
  RayBackend rays;
  std::unique_ptr<BulletWorld> physics;
  std::unique_ptr<Robot> robot;
  std::unique_ptr<RayCaster> caster;
  std::unique_ptr<ArmLoop> arm;      // the scenario's `arm:`, when given
  std::unique_ptr<DroneLoop> drone;  // the scenario's `drone:`, when given
  bool has_odometry = false;
};

Simulation::Simulation(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Simulation::~Simulation() = default;

Result<std::unique_ptr<Simulation>> Simulation::create(const Scenario& scenario, RayBackend rays) {
  auto impl = std::make_unique<Impl>();
  impl->sc = scenario;
  impl->rays = rays;
  const Scenario& sc = impl->sc;
  impl->physics = std::make_unique<BulletWorld>(sc.world);
  impl->physics->dynamics().getSolverInfo().m_numIterations = sc.solver_iterations;
  auto robot_or = sc.drone.enabled ? Robot::load_multirotor(sc.urdf_path, impl->physics->dynamics(), sc.start,
                                                            {.rotor_bodies = sc.drone.rotor_bodies})
                                   : Robot::load(sc.urdf_path, impl->physics->dynamics(), sc.start, sc.drive);
  if (!robot_or) return robot_or.error();
  impl->robot = std::move(*robot_or);
  if (sc.drone.enabled) {
    auto drone = DroneLoop::create(sc, *impl->robot);
    if (!drone) return drone.error();
    impl->drone = std::move(*drone);
  }
  if (sc.arm.enabled) {
    auto arm = ArmLoop::create(sc, *impl->robot);
    if (!arm) return arm.error();
    impl->arm = std::move(*arm);
  }
  const Robot& robot = *impl->robot;

  // Every sensor's link must exist; every faulted channel must be published.
  std::set<std::string> channels{sc.tf_static_channel};
  if (sc.physics_cost > 0) channels.insert(sc.physics_channel);
  if (!impl->drone) channels.insert(sc.controller.channel);
  if (impl->arm) {
    for (const std::string& c : impl->arm->channels()) channels.insert(c);
  }
  if (impl->drone) {
    for (const std::string& c : impl->drone->channels()) channels.insert(c);
  }
  for (const SensorConfig& s : sc.sensors) {
    if (!s.link.empty() && !robot.has_link(s.link)) {
      return Error{sc.path + ":" + std::to_string(s.line) + ": sensor " + s.channel + " is on link '" + s.link +
                   "', which robot '" + robot.name() + "' (" + sc.urdf_path + ") does not have"};
    }
    channels.insert(s.channel);
    if (s.type == SensorType::kOdometry && impl->drone) {
      return Error{sc.path + ":" + std::to_string(s.line) + ": sensor " + s.channel +
                   ": wheel odometry needs a wheeled robot, and this one is a drone"};
    }
    if (s.type == SensorType::kOdometry) {
      impl->has_odometry = true;
      if (!s.odometry.tf_channel.empty()) channels.insert(s.odometry.tf_channel);
    }
  }
  for (const auto& [channel, faults] : sc.faults.streams) {
    if (!channels.count(channel)) {
      std::string known;
      for (const auto& c : channels) known += (known.empty() ? "" : ", ") + c;
      return Error{sc.path + ": faults name channel '" + channel + "', which this scenario does not publish (" + known +
                   ")"};
    }
  }

  impl->caster = std::make_unique<RayCaster>(sc.world);
  return std::unique_ptr<Simulation>(new Simulation(std::move(impl)));
}

std::vector<std::string> Simulation::recomputed_channels() const {
  return impl_->drone ? impl_->drone->channels() : std::vector<std::string>{};
}

Result<SimReport> Simulation::run(const SimOptions& options) {
  const Scenario& sc = impl_->sc;
  Robot& robot = *impl_->robot;
  BulletWorld& physics = *impl_->physics;
  const RayCaster& caster = *impl_->caster;
  const bool has_odometry = impl_->has_odometry;
  DroneLoop* drone = impl_->drone.get();
  const bool ground = drone == nullptr;  // a wheeled robot, driven along the route
  auto writer = LogWriter::create(options.out, {.atomic = true});
  if (!writer) return writer.error();
  Output out(*writer, sc.faults, sc.start_utime, options.on_message);
  // A physics update slower than its step: the simulation runs in lockstep slower than real time, and the recorder,
  // on the wall clock, stamps every event that much later.
  const double wall_ratio = std::max(1.0, sc.physics_cost / sc.physics_step);
  const std::function<int64_t(int64_t)> wall_clock = [start = sc.start_utime, wall_ratio](int64_t t) {
    return start + static_cast<int64_t>(std::llround(static_cast<double>(t - start) * wall_ratio));
  };
  if (wall_ratio > 1) out.set_log_clock(wall_clock);
  {  // How this log is made, first: a closed-loop replay runs it again from this.
    driftlab::simulation_t m{};
    m.header.utime = sc.start_utime;
    m.header.frame_id = "";
    m.scenario_path = sc.path;
    m.scenario_yaml = sc.text;
    m.faults_path = sc.faults_path;
    m.faults_yaml = sc.faults_text;
    m.duration_s = sc.duration;
    m.seed = static_cast<int64_t>(sc.seed);
    m.faults_seed = static_cast<int64_t>(sc.faults.seed);
    m.version = options.version;
    std::vector<uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    if (Status s = out.write_now(sc.simulation_channel, sc.start_utime, bytes); !s) {
      writer->discard();
      return s.error();
    }
  }

  RangeFn range;
  if (impl_->rays == RayBackend::kBullet) {
    range = [&physics](const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max) {
      return physics.ray_test(o, d, max).value_or(INFINITY);
    };
  } else {
    range = [&caster](const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max) { return caster.range(o, d, max); };
  }

  // The robot's dead reckoning, which the controller follows (published when the scenario has an odometry sensor).
  OdometryParams hidden;
  double odom_rate = 50;
  for (const SensorConfig& s : sc.sensors) {
    if (s.type == SensorType::kOdometry) {
      hidden = s.odometry;
      odom_rate = s.rate;
    }
  }
  WheelOdometry odometry(hidden, robot, stream_seed(sc.seed, "odometry"));
  std::vector<std::unique_ptr<Sensor>> sensors;
  for (const SensorConfig& s : sc.sensors) sensors.push_back(make_sensor(s, robot, out, sc.seed, &odometry, sc.geo));

  ArmLoop* arm = impl_->arm.get();
  if (arm != nullptr) arm->attach(out, odometry, options.corrections);
  if (drone != nullptr) {
    if (Status s = drone->attach(out, options.corrections.clocks, wall_clock); !s) {
      writer->discard();
      return s.error();
    }
  }
  std::optional<GroundLoop> wheels;  // a wheeled robot, driven along the route
  if (ground) wheels.emplace(sc, robot, caster, out, odometry, has_odometry, odom_rate);
  const int physics_stream = sc.physics_cost > 0 ? out.add_stream(sc.physics_channel) : -1;
  int64_t n_physics = 0, physics_updates = 0;
  const int static_stream = out.add_stream(sc.tf_static_channel);
  std::vector<std::string> static_links;
  for (const SensorConfig& s : sc.sensors) {
    if (!s.link.empty() && s.link != robot.base_link() && robot.fixed_in_base(s.link) &&
        std::find(static_links.begin(), static_links.end(), s.link) == static_links.end()) {
      static_links.push_back(s.link);
    }
  }

  const Duration step = Duration::from_seconds_rounded(sc.physics_step);
  const int64_t step_us = step.us();
  const double dt = step.seconds();
  const int64_t end_us = Duration::from_seconds_rounded(sc.duration).us();
  SimReport report;
  int64_t n_static = 0, next_progress = 0;
  Eigen::Vector3d last_position = robot.link_pose(robot.base_link()).translation();

  int64_t t_us = 0;
  for (; t_us <= end_us; t_us += step_us) {
    if (options.stop != nullptr && options.stop->load(std::memory_order_relaxed)) {
      report.interrupted = true;
      break;
    }
    const int64_t now = sc.start_utime + t_us;
    if (wheels) wheels->advance_odometry(t_us);
    SensorContext ctx{robot, caster, range, out, sc.start_utime, now};
    for (auto& s : sensors) s->step(ctx);

    if (t_us >= due_us(n_static, sc.tf_static_rate)) {
      ++n_static;
      // The odometry frame at the robot's start pose in the ground truth's world frame (with an arm's
      // localization, map -> odom takes its place).
      const bool odom_frame = has_odometry && (arm == nullptr || sc.arm.map_channel.empty());
      driftlab::tf_t tf = static_tf(sc, robot, static_links, arm, drone, odom_frame ? &hidden.frame : nullptr, now);
      tf.ntransforms = static_cast<int32_t>(tf.transforms.size());
      out.publish(static_stream, tf, now, now);
    }

    if (wheels) wheels->control(t_us, now, dt, arm != nullptr && arm->holds_base());

    if (physics_stream >= 0 && t_us >= due_us(n_physics, sc.physics_rate)) {
      // The simulator's own step times, as Gazebo's performance metrics: every update costs physics_cost.
      driftlab::physics_step_t m{};
      m.header.frame_id = "";
      m.updates = static_cast<int32_t>(std::min<int64_t>(physics_updates, INT32_MAX));
      m.sim_step_s = dt;
      m.wall_step_mean_s = m.wall_step_max_s = std::max(dt, sc.physics_cost);
      m.real_time_factor = dt / m.wall_step_mean_s;
      out.publish(physics_stream, m, now, now);
      ++n_physics;
      physics_updates = 0;
    }
    if (arm != nullptr) arm->publish(now);
    if (Status s = out.flush(now); !s) {
      writer->discard();
      return s.error();
    }
    if (arm != nullptr) arm->control(now, dt);
    if (drone != nullptr) drone->control(now, dt);
    if (options.progress && t_us >= next_progress) {
      options.progress(Duration::from_us(t_us).seconds(), sc.duration);
      next_progress += 1000000;
    }

    physics.dynamics().stepSimulation(static_cast<btScalar>(dt), 0);
    ++physics_updates;
    robot.after_step(dt);
    const Eigen::Vector3d position = robot.link_pose(robot.base_link()).translation();
    report.distance_m += (position - last_position).head<2>().norm();
    last_position = position;
  }

  // Deliver what is still in flight, then the manifest, then commit the log.
  const int64_t end_utime = sc.start_utime + std::min(t_us, end_us);
  if (drone != nullptr) {
    if (Status s = drone->finish(end_utime); !s) {
      writer->discard();
      return Error{sc.path + ": drone: " + s.message()};
    }
  }
  if (Status s = out.flush(INT64_MAX); !s) {
    writer->discard();
    return s.error();
  }
  const std::vector<driftlab::fault_t> faults = out.manifest(end_utime);
  if (Status s = out.write_now(sc.faults_channel, end_utime, manifest_bytes(sc, faults, end_utime)); !s) {
    writer->discard();
    return s.error();
  }
  if (Status s = writer->close(); !s) return s.error();
  report.faults_json = faults_json_path(options.out);
  if (Status s = write_faults_json(report.faults_json, sc, end_utime, faults); !s) return s.error();

  report.simulated_s = Duration::from_us(std::min(t_us, end_us)).seconds();
  report.messages = out.written();
  report.laps = wheels ? wheels->laps() : 0;
  if (drone != nullptr) report.notes = drone->summary();
  const Eigen::Vector3d truth = robot.link_pose(robot.base_link()).translation();
  report.odometry_error_m = wheels ? (truth.head<2>() - wheels->odometry_position()).norm() : 0;
  return report;
}

}  // namespace driftlab::sim
