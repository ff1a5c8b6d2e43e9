// A simulation scenario (YAML, docs/simulator.md): the world, the robot and its drive, the route the controller
// follows, the sensors with their rates and noise models, the faults and the duration.
// Thread-safety: plain values; the functions are reentrant.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "controller/pure_pursuit.h"
#include "core/result.h"
#include "faults/faults.h"
#include "sim/arm_config.h"
#include "sim/drone_config.h"
#include "sim/robot.h"
#include "sim/world.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::sim {

enum class SensorType {
  kLidar2d,
  kLidar3d,
  kImu,
  kOdometry,
  kCamera,
  kGroundTruth,
  kJointState,
  kBarometer,
  kGnss,
  kMagnetometer
};

struct Lidar2dParams {
  int beams = 360;
  double fov = 2 * M_PI;      ///< [rad], centred on the link's x axis
  double range_min = 0.1;     ///< [m]
  double range_max = 30;      ///< [m]
  double range_noise = 0.01;  ///< standard deviation [m]
};

struct Lidar3dParams {
  int rings = 16;
  int columns = 1800;
  double vertical_min = -0.2618;  ///< elevation of the lowest ring [rad]
  double vertical_max = 0.2618;   ///< elevation of the highest ring [rad]
  double range_min = 0.3;         ///< [m]
  double range_max = 100;         ///< [m]
  double range_noise = 0.02;      ///< standard deviation [m]
};

/// Noise densities as in Kalibr's IMU model: white noise [unit/sqrt(Hz)] and bias random walk [unit/s/sqrt(Hz)].
struct ImuParams {
  double gyro_noise_density = 1.7e-4;    ///< [rad/s/sqrt(Hz)]
  double gyro_random_walk = 2.0e-5;      ///< [rad/s^2/sqrt(Hz)]
  double accel_noise_density = 2.0e-3;   ///< [m/s^2/sqrt(Hz)]
  double accel_random_walk = 3.0e-4;     ///< [m/s^3/sqrt(Hz)]
  double gyro_bias = 0.002;              ///< standard deviation of each axis' initial gyro bias [rad/s]
  double accel_bias = 0.02;              ///< standard deviation of each axis' initial accelerometer bias [m/s^2]
};

struct OdometryParams {
  int ticks_per_rev = 4096;       ///< encoder resolution [ticks per wheel turn]
  double left_radius_error = 0;   ///< the odometry's belief of the left wheel radius is off by this fraction
  double right_radius_error = 0;  ///< ... and the right's
  double separation_error = 0;    ///< ... and of the wheel separation
  double slip_noise = 0.01;       ///< random slip: each wheel increment is off by this fraction (std. deviation)
  std::string frame = "odom";
  std::string tf_channel = "TF";  ///< also publish odom -> base link there ("" to disable)
};

struct CameraParams {
  int width = 320;
  int height = 240;
  double hfov = 1.2;        ///< horizontal field of view [rad]
  double max_range = 20;    ///< [m]
  std::string encoding = "jpeg";  ///< "jpeg" or "png"
  int quality = 80;         ///< JPEG quality, 1..100
};

/// A static pressure sensor: the standard atmosphere at the link's altitude (the world's z = 0 is at geo.altitude),
/// with white noise and a slowly wandering offset.
struct BarometerParams {
  double noise = 1.0;        ///< standard deviation of a reading [Pa] (1 Pa is about 8 cm)
  double offset_walk = 0.1;  ///< random walk of the offset [Pa/sqrt(s)]
  double offset = 0;         ///< initial offset of every reading [Pa]
  double temperature = 15;   ///< reported air temperature [degrees Celsius]
};

/// A GNSS receiver: the link's position as latitude, longitude and altitude about the world's geodetic origin
/// (geo:), and its velocity east-north-up. A receiver's position error is mostly a slow wander (atmosphere,
/// multipath; a first-order Gauss-Markov process here) under a little white noise; the accuracy it reports
/// (eph, epv) is their total standard deviation.
struct GnssParams {
  double horizontal_noise = 0.05;  ///< white noise of east and north, standard deviation [m]
  double vertical_noise = 0.1;     ///< ... of the altitude [m]
  double horizontal_drift = 0.2;   ///< the wander of east and north, standard deviation [m]
  double vertical_drift = 0.3;     ///< ... of the altitude [m]
  double correlation_time = 60;    ///< of the wander [s]; 0: none
  double velocity_noise = 0.05;    ///< white noise of each velocity component [m/s]
  int satellites = 12;             ///< reported [count]
};

/// A 3-axis magnetometer: the world's magnetic field (geo:) in the link's frame, with white noise.
struct MagnetometerParams {
  double noise = 2e-7;  ///< standard deviation per axis [tesla]
};

struct SensorConfig {
  SensorType type = SensorType::kGroundTruth;
  std::string channel;
  std::string link;  ///< URDF link the sensor sits on (the base link when not given)
  double rate = 10;  ///< [Hz]
  int line = 0;      ///< in the scenario file, for messages
  Lidar2dParams lidar2d;
  Lidar3dParams lidar3d;
  ImuParams imu;
  OdometryParams odometry;
  CameraParams camera;
  BarometerParams barometer;
  GnssParams gnss;
  MagnetometerParams magnetometer;
};

/// Where the world is on Earth, for the GNSS, barometer and magnetometer: its origin (x = y = z = 0; x east, y north,
/// z up) and the Earth's magnetic field there. The defaults are PX4 SITL's home (Zurich).
struct GeoConfig {
  double latitude = 47.397742;  ///< [degrees, WGS-84]
  double longitude = 8.545594;  ///< [degrees, WGS-84]
  double altitude = 488;        ///< of the world's z = 0 above mean sea level [m]
  double declination = 0.047;   ///< magnetic north east of true north [rad]
  double inclination = 1.11;    ///< the field's dip below the horizontal [rad]
  double field = 4.8e-5;        ///< the field's strength [tesla]
};

struct ControllerConfig {
  double rate = 20;  ///< [Hz]
  std::string channel = "CMD";
  double footprint_radius = 0.2;  ///< for the reactive obstacle avoidance [m]
  controller::PurePursuitOptions pursuit;
};

struct Scenario {
  std::string path;  ///< the scenario file
  std::string text;  ///< its YAML, as read
  /// A fault description that replaced the scenario's `faults:` (`driftlab sim --faults`): its file and YAML.
  std::string faults_path, faults_text;
  std::string name;
  double duration = 600;                       ///< [s]
  uint64_t seed = 1;
  int64_t start_utime = 1763776800000000;      ///< true time of the first step [us since the epoch]
  double physics_step = 0.001;                 ///< [s]
  /// The wall-clock time one physics update takes [s] (a heavy collision mesh): above physics_step the simulation
  /// runs in lockstep slower than real time, by physics_step / physics_cost, and what is on the wall clock sees it
  /// so: the log's recorder (event times) and an offboard script on the wall clock. 0: updates cost nothing.
  double physics_cost = 0;
  std::string physics_channel = "PHYSICS";     ///< driftlab.physics_step_t, when physics_cost is given
  double physics_rate = 1;                     ///< [Hz of simulated time]
  int solver_iterations = 6;                   ///< Bullet's constraint solver iterations per step
  std::string world_path;
  World world;
  std::string urdf_path;
  Eigen::Vector3d start = Eigen::Vector3d::Zero();  ///< x, y [m], yaw [rad]
  DriveOptions drive;
  ControllerConfig controller;
  std::vector<controller::Point2> route;
  std::string tf_static_channel = "TF_STATIC";
  double tf_static_rate = 1;                   ///< [Hz]
  std::string faults_channel = "FAULTS";       ///< the fault manifest (a truth channel)
  std::string simulation_channel = "SIMULATION";  ///< driftlab.simulation_t: how the log was made (a truth channel)
  std::vector<SensorConfig> sensors;
  FaultConfig faults;
  ArmConfig arm;      ///< an arm on the robot (`arm:`; enabled when given)
  DroneConfig drone;  ///< the robot is a multirotor with its flight stack on board (`drone:`; enabled when given)
  GeoConfig geo;
};

/// The keys of a scenario file, with units, ranges and defaults (core/config.h); `sensors` and `faults` have tables
/// of their own (the sensors' depend on their type).
const config::Table<Scenario>& scenario_table();
/// The reference of a scenario file: its keys, every sensor type's, as markdown tables.
std::string scenario_reference();

/// Parses a scenario; relative paths (world, URDF) are resolved against `base_dir`. Errors: "ORIGIN:LINE: ..."
/// naming the key (unknown keys, wrong types, negative rates, unknown sensor types, a malformed world file).
/// The URDF is only read when the simulation starts (links are checked there).
Result<Scenario> parse_scenario(const std::string& yaml_text, const std::string& origin, const std::string& base_dir);
Result<Scenario> load_scenario(const std::string& path);

/// What `driftlab sim`'s options change of a scenario.
struct ScenarioOverrides {
  double duration = 0;      ///< [s]; 0 keeps the scenario's
  int64_t seed = -1;        ///< -1 keeps the scenario's
  std::string faults_path;  ///< a fault description replacing the scenario's `faults:`; empty keeps them
};
/// Applies them: a seed seeds the faults too; a fault description is kept (its path and text, for the log's
/// SIMULATION message) and seeded with the scenario's seed unless it gives its own. Errors: the fault file's.
Status apply_overrides(Scenario& scenario, const ScenarioOverrides& overrides);

/// The scenario used when none is given: scenarios/indoor.yaml in the data folder (core/install_layout.h).
std::string default_scenario_path();

const char* sensor_type_name(SensorType type);

}  // namespace driftlab::sim
