// libFuzzer target: the processing modules (the estimator, the controller, the 2D and 3D SLAM, and the drone's
// estimator, flight stack and offboard script) fed well-formed
// messages carrying hostile values (NaN, infinities, huge, tiny and denormal numbers, zero-length and odd-sized
// arrays, stamps and log times at the ends of int64_t and running backwards) through the fake bus of the tests
// (tests/fakes/fake_bus.h: the replay host itself on its virtual clock, timers included). No module may throw
// (the host would count and skip it), crash or trip a sanitizer, and every message a module publishes must be
// well-formed with every number finite (lcmtypes::non_finite): a NaN that gets in must never come out.
// Input: a byte picking the module, then messages, each a kind byte and the values FuzzedDataProvider draws.
#include <fuzzer/FuzzedDataProvider.h>

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "controller/controller_module.h"
#include "core/log_format.h"
#include "core/time.h"
#include "driftlab/barometer_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "driftlab/trajectory_setpoint_t.hpp"
#include "driftlab/vehicle_command_t.hpp"
#include "driftlab/vehicle_status_t.hpp"
#include "driftlab/velocity_command_t.hpp"
#include "estimator/drone_estimator_module.h"
#include "estimator/estimator_module.h"
#include "flight/flight_module.h"
#include "flight/offboard_module.h"
#include "lcmtypes/schema.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"
#include "runtime/bus.h"
#include "slam/slam2d.h"
#include "slam/slam3d.h"
#include "tests/fakes/fake_bus.h"

namespace {

/// Prints the messages of an input as they are delivered (DRIFTLAB_FUZZ_VERBOSE=1), to read a crash's input.
void describe(const std::string& channel, int64_t t, std::span<const uint8_t> bytes) {
  const char* type = driftlab::lcmtypes::type_name(driftlab::logfmt::fingerprint(bytes));
  std::string s = type != nullptr ? type : "?";
  if (type != nullptr) {
    driftlab::lcmtypes::flatten(*driftlab::lcmtypes::find_struct(type), bytes,
                                [&](const std::string& k, const std::string& v) { s += " " + k + "=" + v; });
  }
  std::fprintf(stderr, "%s at %lld: %s\n", channel.c_str(), static_cast<long long>(t), s.c_str());
}

[[noreturn]] void fail(const std::string& what) {
  std::fprintf(stderr, "%s\n", what.c_str());
  std::abort();
}

double hostile_double(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange<int>(0, 15)) {
    case 0: return std::numeric_limits<double>::quiet_NaN();
    case 1: return INFINITY;
    case 2: return -INFINITY;
    case 3: return DBL_MAX;
    case 4: return -1e300;
    case 5: return DBL_MIN;
    case 6: return 4.9e-324;  // the smallest denormal
    case 7: return 0.0;
    case 8: return -0.0;
    case 9: return 1e15;
    case 10: return in.ConsumeFloatingPoint<double>();
    default: return in.ConsumeFloatingPointInRange<double>(-20, 20);  // ordinary values, most of the time
  }
}

float hostile_float(FuzzedDataProvider& in) {
  const double d = hostile_double(in);
  if (std::isnan(d)) return NAN;
  if (std::abs(d) > FLT_MAX) return d > 0 ? INFINITY : -INFINITY;
  return static_cast<float>(d);
}

int64_t hostile_stamp(FuzzedDataProvider& in, int64_t& clock) {
  switch (in.ConsumeIntegralInRange<int>(0, 9)) {
    case 0: return std::numeric_limits<int64_t>::min();
    case 1: return std::numeric_limits<int64_t>::max();
    case 2: return 0;
    case 3: return in.ConsumeIntegral<int64_t>();
    case 4: return clock - in.ConsumeIntegralInRange<int64_t>(0, 2000000);   // late
    default: return clock += in.ConsumeIntegralInRange<int64_t>(0, 100000);  // in order, up to 0.1 s apart
  }
}

driftlab::header_t header(FuzzedDataProvider& in, int64_t stamp, const char* frame) {
  return {in.ConsumeIntegral<int64_t>(), stamp, in.ConsumeBool() ? frame : "odom"};
}

template <typename T>
std::vector<uint8_t> encode(const T& m) {
  std::vector<uint8_t> bytes(static_cast<size_t>(m.getEncodedSize()));
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

template <size_t N>
void fill(FuzzedDataProvider& in, double (&a)[N]) {
  for (double& v : a) v = in.ConsumeBool() ? hostile_double(in) : 0.0;
}

void put_quaternion(FuzzedDataProvider& in, driftlab::quaternion_t& q) {
  if (in.ConsumeBool()) {  // a unit quaternion of a yaw
    const double yaw = hostile_double(in);
    q = {std::cos(yaw / 2), 0, 0, std::sin(yaw / 2)};
  } else {
    q = {hostile_double(in), hostile_double(in), hostile_double(in), hostile_double(in)};
  }
}

void put_vector(FuzzedDataProvider& in, driftlab::vector3_t& v) {
  v = {hostile_double(in), hostile_double(in), hostile_double(in)};
}

std::unique_ptr<driftlab::Module> make_module(int which) {
  using namespace driftlab;
  switch (which) {
    case 0: return std::make_unique<estimator::EstimatorModule>(estimator::EstimatorConfig{});
    case 1: {
      controller::ControllerConfig c;
      c.route = {{0, 0}, {5, 0}, {5, 5}, {0, 5}};
      return std::make_unique<controller::ControllerModule>(c);
    }
    case 2: return std::make_unique<slam::Slam2d>(slam::Slam2dConfig{});
    case 3: return std::make_unique<slam::Slam3d>(slam::Slam3dConfig{});
    case 4: return std::make_unique<estimator::DroneEstimatorModule>(estimator::DroneEstimatorConfig{});
    case 5: return std::make_unique<flight::FlightModule>(flight::FlightConfig{});
    default: return std::make_unique<flight::OffboardModule>(flight::OffboardConfig{});
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider in(data, size);
  const int which = in.ConsumeIntegralInRange<int>(0, 6);
  auto module = make_module(which);
  driftlab::test::FakeBus bus;  // the replay host itself, on its virtual clock
  bus.add(*module);
  if (!bus.start().ok()) std::abort();  // the defaults always start
  const bool verbose = std::getenv("DRIFTLAB_FUZZ_VERBOSE") != nullptr;
  auto deliver = [&](const std::string& channel, int64_t t, const std::vector<uint8_t>& bytes) {
    if (verbose) describe(channel, t, bytes);
    if (!bus.deliver(channel, bytes, driftlab::Time::from_us(t)).ok()) std::abort();  // no output log to fail
  };
  // SLAM does real work per scan or cloud: fewer messages keep each input fast.
  const int max_messages = which == 2 || which == 3 ? 24 : 200;
  // The drone's modules read the vehicle's estimate where the flight stack and the offboard script expect it.
  const char* odometry_channel = which == 5 ? "VEHICLE_ODOM_REPLAY" : which == 6 ? "VEHICLE_ODOM" : "ODOM";
  int64_t clock = 1'000'000;
  for (int n = 0; n < max_messages && in.remaining_bytes() > 0; ++n) {
    const int64_t stamp = hostile_stamp(in, clock);
    const int64_t arrival = in.ConsumeBool() ? clock : stamp;
    switch (in.ConsumeIntegralInRange<int>(0, 12)) {
      case 0: {
        driftlab::imu_t m{};
        m.header = header(in, stamp, "imu");
        put_quaternion(in, m.orientation);
        fill(in, m.orientation_covariance);
        put_vector(in, m.angular_velocity);
        fill(in, m.angular_velocity_covariance);
        put_vector(in, m.linear_acceleration);
        fill(in, m.linear_acceleration_covariance);
        deliver("IMU", arrival, encode(m));
        break;
      }
      case 1: {
        driftlab::odometry_t m{};
        m.header = header(in, stamp, "odom");
        m.child_frame_id = "base_link";
        put_vector(in, m.position);
        put_quaternion(in, m.orientation);
        fill(in, m.pose_covariance);
        put_vector(in, m.linear_velocity);
        put_vector(in, m.angular_velocity);
        fill(in, m.twist_covariance);
        deliver(odometry_channel, arrival, encode(m));
        break;
      }
      case 2: {
        driftlab::pose_t m{};
        m.header = header(in, stamp, "map");
        m.child_frame_id = "base_link";
        put_vector(in, m.position);
        put_quaternion(in, m.orientation);
        fill(in, m.covariance);
        deliver("SLAM_POSE", arrival, encode(m));
        break;
      }
      case 3: {
        driftlab::laser_scan_t m{};
        m.header = header(in, stamp, "laser");
        m.nranges = in.ConsumeIntegralInRange<int32_t>(0, 90);
        const bool plain = in.ConsumeBool();  // an ordinary fan, hostile ranges only
        m.angle_min = plain ? -1.5f : hostile_float(in);
        m.angle_increment = plain ? 3.0f / 90 : hostile_float(in);
        m.angle_max = m.angle_min + m.angle_increment * static_cast<float>(m.nranges);
        m.range_min = plain ? 0.1f : hostile_float(in);
        m.range_max = plain ? 30.0f : hostile_float(in);
        m.time_increment = hostile_float(in);
        m.scan_time = hostile_float(in);
        for (int i = 0; i < m.nranges; ++i) {
          m.ranges.push_back(in.ConsumeBool() ? in.ConsumeFloatingPointInRange<float>(0, 10) : hostile_float(in));
        }
        m.nintensities = in.ConsumeBool() ? m.nranges : 0;
        m.intensities.assign(static_cast<size_t>(m.nintensities), 1.0f);
        deliver("SCAN", arrival, encode(m));
        break;
      }
      case 4: {
        driftlab::point_cloud_t m{};
        m.header = header(in, stamp, "lidar");
        m.npoints = in.ConsumeIntegralInRange<int32_t>(0, 400);
        m.height = in.ConsumeBool() ? 1 : in.ConsumeIntegral<int32_t>();
        m.width = in.ConsumeBool() ? m.npoints : in.ConsumeIntegral<int32_t>();
        const double spread = in.ConsumeFloatingPointInRange<double>(0.1, 30);
        for (int i = 0; i < m.npoints; ++i) {
          const bool ordinary = in.ConsumeProbability<double>() < 0.9;
          m.x.push_back(ordinary ? static_cast<float>(spread * std::cos(i * 0.7)) : hostile_float(in));
          m.y.push_back(ordinary ? static_cast<float>(spread * std::sin(i * 0.7)) : hostile_float(in));
          m.z.push_back(ordinary ? static_cast<float>((i % 7) * 0.3) : hostile_float(in));
        }
        m.nintensities = 0;
        m.ntimes = in.ConsumeBool() ? m.npoints : 0;
        for (int i = 0; i < m.ntimes; ++i) m.time_offsets.push_back(in.ConsumeBool() ? i * 1e-4f : hostile_float(in));
        deliver("POINTS", arrival, encode(m));
        break;
      }
      case 5: {
        driftlab::tf_t m{};
        m.header = header(in, stamp, "");
        m.ntransforms = in.ConsumeIntegralInRange<int32_t>(0, 3);
        for (int i = 0; i < m.ntransforms; ++i) {
          driftlab::transform_t t{};
          t.header = {0, stamp, "base_link"};
          t.child_frame_id = in.ConsumeBool() ? "laser" : "lidar";
          put_vector(in, t.translation);
          put_quaternion(in, t.rotation);
          m.transforms.push_back(t);
        }
        deliver("TF_STATIC", arrival, encode(m));
        break;
      }
      case 6: {
        driftlab::gnss_t m{};
        m.header = header(in, stamp, "gnss");
        m.fix_type = in.ConsumeBool() ? 3 : in.ConsumeIntegral<int32_t>();
        m.satellites = in.ConsumeIntegral<int32_t>();
        m.latitude_deg = in.ConsumeBool() ? 47.4 + hostile_double(in) * 1e-5 : hostile_double(in);
        m.longitude_deg = in.ConsumeBool() ? 8.5 + hostile_double(in) * 1e-5 : hostile_double(in);
        m.altitude_m = hostile_double(in);
        m.eph_m = hostile_double(in);
        m.epv_m = hostile_double(in);
        put_vector(in, m.velocity);
        m.speed_accuracy_m_s = hostile_double(in);
        deliver("GNSS", arrival, encode(m));
        break;
      }
      case 7: {
        driftlab::barometer_t m{};
        m.header = header(in, stamp, "baro");
        m.pressure_pa = in.ConsumeBool() ? 101325 + hostile_double(in) : hostile_double(in);
        m.temperature_c = hostile_double(in);
        m.pressure_variance = hostile_double(in);
        deliver("BARO", arrival, encode(m));
        break;
      }
      case 8: {
        driftlab::magnetometer_t m{};
        m.header = header(in, stamp, "mag");
        put_vector(in, m.magnetic_field);
        fill(in, m.magnetic_field_covariance);
        deliver("MAG", arrival, encode(m));
        break;
      }
      case 9: {
        driftlab::trajectory_setpoint_t m{};
        m.header = header(in, stamp, "map");
        put_vector(in, m.position);
        put_vector(in, m.velocity);
        put_vector(in, m.acceleration);
        m.yaw = hostile_double(in);
        deliver("SETPOINT", arrival, encode(m));
        break;
      }
      case 10: {
        driftlab::vehicle_command_t m{};
        m.header = header(in, stamp, "");
        static const char* const kCommands[] = {"arm", "disarm", "offboard", "land", "hold", "", "takeoff"};
        m.command = kCommands[in.ConsumeIntegralInRange<int>(0, 6)];
        deliver("VEHICLE_CMD", arrival, encode(m));
        break;
      }
      case 11: {
        driftlab::vehicle_status_t m{};
        m.header = header(in, stamp, "");
        m.armed = in.ConsumeBool();
        m.landed = in.ConsumeBool();
        static const char* const kModes[] = {"hold", "offboard", "land", ""};
        m.mode = kModes[in.ConsumeIntegralInRange<int>(0, 3)];
        m.offboard_losses = in.ConsumeIntegral<int32_t>();
        m.setpoint_age_s = hostile_double(in);
        deliver("VEHICLE_STATUS", arrival, encode(m));
        break;
      }
      default: {
        driftlab::velocity_command_t m{};
        m.header = header(in, stamp, "base_link");
        put_vector(in, m.linear);
        put_vector(in, m.angular);
        deliver("CMD", arrival, encode(m));
        break;
      }
    }
  }
  if (!bus.finish().ok()) std::abort();
  // The host catches what a module throws, and counts it: here a throw is a hole in the module's own checks.
  for (const auto& r : bus.reports()) {
    for (const auto& w : r.warnings) {
      if (w.find("failed on and skipped") != std::string::npos) fail(r.name + ": " + w);
    }
  }
  for (const auto& e : bus.published()) {
    if (const auto why = driftlab::lcmtypes::layout_problem(e.data)) fail("malformed on " + e.channel + ": " + *why);
    if (const auto what = driftlab::lcmtypes::non_finite(e.data)) fail("non-finite on " + e.channel + ": " + *what);
  }
  return 0;
}
