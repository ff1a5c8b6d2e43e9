// The flight stack and the offboard script as modules on the replay host (the fake bus), closed around a rigid-body
// quadrotor that a third module integrates at 1 kHz and reports at 250 Hz: the script streams setpoints, is
// granted offboard and arming, flies the default mission (climb to 2 m, hover, a 4 m square, land) and the vehicle
// disarms on the ground; the vehicle's own path is compared with the setpoints. A stream below 2 Hz is never
// granted offboard (PX4's rule); a stream that stops for a second in flight is an offboard loss: the vehicle holds
// where it was and the script takes it back.
#include "flight/flight_module.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <utility>

#include "driftlab/motor_command_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/trajectory_setpoint_t.hpp"
#include "driftlab/vehicle_status_t.hpp"
#include "flight/offboard_module.h"
#include "runtime/module_input.h"
#include "tests/doc_figures.h"
#include "tests/fakes/fake_bus.h"
#include "tests/flight/rigid_body.h"

namespace driftlab::flight {
namespace {

constexpr int64_t kT0 = 1763776800000000;

/// The world: integrates the body at 1 kHz on the motor commands, publishes its true state at 250 Hz on
/// VEHICLE_ODOM, and relays the script's setpoints (SETPOINT_OUT) to the flight stack (SETPOINT) except in
/// [gap_from, gap_to).
class World final : public Module {
 public:
  World() : body(VehicleModel{}) {}
  std::string name() const override { return "world"; }
  Status start(Bus& bus) override {
    bus.subscribe("MOTOR_CMD", [this](const BusMessage& m) {
      driftlab::motor_command_t c;
      if (!decode_message(m, c)) return;
      body.command(c.armed ? c.control : std::vector<double>(c.control.size(), 0.0));
      if (c.armed) armed_commands++;
    });
    bus.subscribe("SETPOINT_OUT", [this, &bus](const BusMessage& m) {
      driftlab::trajectory_setpoint_t s;
      if (!decode_message(m, s)) return;
      if (bus.now().us() >= gap_from && bus.now().us() < gap_to) return;
      if (hostile()) {  // relayed with a NaN in it
        s.position.x = NAN;
        return bus.publish_message("SETPOINT", s);
      }
      setpoint = Eigen::Vector3d(s.position.x, s.position.y, s.position.z);
      bus.publish(std::string("SETPOINT"), m.data);
    });
    bus.every(Duration::from_us(1000), [this, &bus] {
      body.step(1e-3);
      top = std::max(top, body.p.z());
      if (++ticks % 4 != 0) return;
      driftlab::odometry_t o{};
      o.header.seq = seq++;
      o.header.utime = bus.now().us();
      o.header.frame_id = "odom";
      o.child_frame_id = "base_link";
      o.position = {body.p.x(), body.p.y(), body.p.z()};
      o.orientation = {body.q.w(), body.q.x(), body.q.y(), body.q.z()};
      const Eigen::Vector3d vb = body.q.inverse() * body.v;
      o.linear_velocity = {vb.x(), vb.y(), vb.z()};
      o.angular_velocity = {body.w.x(), body.w.y(), body.w.z()};
      bus.publish_message("VEHICLE_ODOM", o);
      if (hostile()) {  // a peer's estimates beside the true one: an orientation that is no rotation, a wild position
        driftlab::odometry_t bad = o;
        bad.orientation = {0, 0, 0, 0};
        bus.publish_message("VEHICLE_ODOM", bad);
        bad = o;
        bad.position.x = 1e300;
        bus.publish_message("VEHICLE_ODOM", bad);
      }
    });
    now = [&bus] { return bus.now().us(); };
    return {};
  }
  bool hostile() const { return now() >= hostile_from && now() < hostile_to; }

  test::RigidBody body;
  Eigen::Vector3d setpoint = Eigen::Vector3d::Zero();
  int64_t gap_from = 0, gap_to = 0, ticks = 0, seq = 0, armed_commands = 0;
  int64_t hostile_from = 0, hostile_to = 0;  ///< setpoints relayed with a NaN, hostile estimates published
  std::function<int64_t()> now;
  double top = 0;
};

FlightConfig flight_config() {
  FlightConfig c;
  c.estimate_channel = "VEHICLE_ODOM";
  c.setpoint_channel = "SETPOINT";
  c.command_channel = "VEHICLE_CMD";
  c.motor_channel = "MOTOR_CMD";
  c.status_channel = "VEHICLE_STATUS";
  c.logged_motor_channel = "";
  return c;
}

OffboardConfig offboard_config() {
  OffboardConfig c;
  c.estimate_channel = "VEHICLE_ODOM";
  c.status_channel = "VEHICLE_STATUS";
  c.setpoint_channel = "SETPOINT_OUT";
  c.command_channel = "VEHICLE_CMD";
  return c;
}

std::vector<std::string> modes(const driftlab::test::FakeBus& bus) {
  std::vector<std::string> out;
  for (const auto& e : bus.published("VEHICLE_STATUS")) {
    driftlab::vehicle_status_t s;
    if (s.decode(e.data.data(), 0, static_cast<int>(e.data.size())) < 0) continue;
    if (out.empty() || out.back() != s.mode) out.push_back(s.mode);
  }
  return out;
}

/// The world, the flight stack and the script on one bus, started.
struct Stack {
  explicit Stack(OffboardConfig script = offboard_config()) : flight(flight_config()), offboard(std::move(script)) {
    bus.add(world);
    bus.add(flight);
    bus.add(offboard);
  }
  World world;
  FlightModule flight;
  OffboardModule offboard;
  driftlab::test::FakeBus bus;
};

TEST(FlightModule, FliesTheMissionAndLands) {
  Stack stack;
  auto& [world, flight, offboard, bus] = stack;
  ASSERT_TRUE(bus.start());
  double sum = 0, hover_worst = 0;
  int n = 0;
  int64_t mission_start = 0;
  for (int64_t t = kT0; t < kT0 + 55000000; t += 20000) {
    ASSERT_TRUE(bus.advance(Time::from_us(t)));
    if (offboard.phase() != OffboardModule::Phase::kMission) continue;
    if (mission_start == 0) mission_start = t;
    const double err = (world.body.p - world.setpoint).norm();
    sum += err * err;
    ++n;
    // The hover at 2 m: the setpoint climbs for 2 s and rests there for 5 s; the last 3 s of it, settled.
    const double since = static_cast<double>(t - mission_start) * 1e-6;
    if (since > 4 && since < 7) hover_worst = std::max(hover_worst, (world.body.p - Eigen::Vector3d(0, 0, 2)).norm());
  }
  EXPECT_EQ(offboard.phase(), OffboardModule::Phase::kDone) << flight.commander().reason();
  EXPECT_FALSE(flight.commander().armed());
  RecordProperty("hover_worst_m", std::to_string(hover_worst));
  RecordProperty("tracking_rms_m", std::to_string(std::sqrt(sum / std::max(n, 1))));
  RecordProperty("top_m", std::to_string(world.top));
  driftlab::test::expect_doc_text_figures("docs/flight.md", "mission topped out at ", " m RMS.",
                                          {world.top, hover_worst, std::sqrt(sum / std::max(n, 1))});
  EXPECT_GT(world.top, 1.95);
  EXPECT_LT(world.top, 2.25);  // the climb stops at 1 m/s: a 10% overshoot at most
  EXPECT_LT(hover_worst, 0.1);
  ASSERT_GT(n, 1000);
  EXPECT_LT(std::sqrt(sum / n), 0.3) << "tracking RMS over " << n << " ticks";
  EXPECT_LT(world.body.p.z(), 0.01);
  EXPECT_LT(world.body.p.head<2>().norm(), 0.3);  // landed where it started: the square closes there
  EXPECT_EQ(flight.commander().offboard_losses(), 0);
  const std::vector<std::string> expected = {"hold", "offboard", "land"};
  EXPECT_EQ(modes(bus), expected);
}

TEST(FlightModule, AStreamBelowTwoHertzIsNeverGrantedOffboard) {
  OffboardConfig o = offboard_config();
  o.mission.stream_rate = 1.5;
  Stack stack(o);
  auto& [world, flight, offboard, bus] = stack;
  ASSERT_TRUE(bus.start());
  for (int64_t t = kT0; t < kT0 + 10000000; t += 20000) ASSERT_TRUE(bus.advance(Time::from_us(t)));
  EXPECT_EQ(offboard.phase(), OffboardModule::Phase::kEngaging);
  EXPECT_FALSE(flight.commander().armed());
  EXPECT_NE(flight.commander().reason().find("setpoints must stream first"), std::string::npos)
      << flight.commander().reason();
  EXPECT_EQ(world.armed_commands, 0);
}

TEST(FlightModule, ASetpointGapInFlightIsAnOffboardLossAndTheVehicleHolds) {
  Stack stack;
  auto& [world, flight, offboard, bus] = stack;
  world.gap_from = kT0 + 9000000;  // in the hover at 2 m
  world.gap_to = kT0 + 10000000;
  ASSERT_TRUE(bus.start());
  double lowest_in_gap = 10;
  for (int64_t t = kT0; t < kT0 + 12000000; t += 20000) {
    ASSERT_TRUE(bus.advance(Time::from_us(t)));
    if (t > world.gap_from && t < world.gap_to + 500000) lowest_in_gap = std::min(lowest_in_gap, world.body.p.z());
  }
  EXPECT_EQ(flight.commander().offboard_losses(), 1);
  EXPECT_GT(lowest_in_gap, 1.8);                          // held, not dropped
  EXPECT_EQ(flight.commander().mode(), Mode::kOffboard);  // the script asked again once the stream was back
  const std::vector<std::string> expected = {"hold", "offboard", "hold", "offboard"};
  EXPECT_EQ(modes(bus), expected);
  bool warned = false;
  for (const auto& w : flight.counters().warnings) warned |= w.find("offboard lost 1 times") != std::string::npos;
  EXPECT_TRUE(warned);
}

// A peer on the bus sends, for 0.3 s of the hover (less than the offboard timeout), setpoints with a NaN in them and
// estimates that are no pose (a zero quaternion, x = 1e300). The flight stack and the script drop them, count them
// and fly on the good ones: every motor command stays finite and the vehicle holds its hover. Before, the NaN
// setpoint went into the position controller and every motor command after it was NaN.
TEST(FlightModule, HostileSetpointsAndEstimatesAreDroppedAndCounted) {
  Stack stack;
  auto& [world, flight, offboard, bus] = stack;
  world.hostile_from = kT0 + 9000000;
  world.hostile_to = kT0 + 9300000;
  ASSERT_TRUE(bus.start());
  double lowest_after = 10;
  for (int64_t t = kT0; t < kT0 + 11000000; t += 20000) {
    ASSERT_TRUE(bus.advance(Time::from_us(t)));
    if (t > world.hostile_from) lowest_after = std::min(lowest_after, world.body.p.z());
  }
  for (const auto& e : bus.published("MOTOR_CMD")) {
    const auto bad = lcmtypes::non_finite(e.data);
    ASSERT_FALSE(bad) << "at " << e.utime << ": " << *bad;
  }
  EXPECT_GT(lowest_after, 1.8);
  EXPECT_EQ(flight.commander().offboard_losses(), 0);
  const std::vector<std::string> expected = {"hold", "offboard"};
  EXPECT_EQ(modes(bus), expected);
  // 6 setpoints at 20 Hz and 2 x 75 estimates at 250 Hz in 0.3 s, to the tick.
  EXPECT_NEAR(static_cast<double>(flight.counters().dropped), 6 + 150, 2);
  bool warned = false;
  for (const auto& w : flight.counters().warnings) warned |= w.find("dropped (first: ") != std::string::npos;
  EXPECT_TRUE(warned);
  // The script lays out its mission from the estimate: both hostile estimates are dropped there too.
  EXPECT_NEAR(static_cast<double>(offboard.counters().dropped), 150, 2);
}

TEST(OffboardModule, AnEstimateAtInfinityIsNotFlownTo) {
  driftlab::test::FakeBus bus;
  OffboardModule offboard(offboard_config());
  bus.add(offboard);
  ASSERT_TRUE(bus.start());
  driftlab::odometry_t o{};
  o.header.utime = kT0;
  o.header.frame_id = "odom";
  o.child_frame_id = "base_link";
  o.orientation = {1, 0, 0, 0};
  o.position = {INFINITY, 0, 0};
  ASSERT_TRUE(bus.deliver_message("VEHICLE_ODOM", o, Time::from_us(kT0)));
  o.position = {1e300, 0, 0};
  ASSERT_TRUE(bus.deliver_message("VEHICLE_ODOM", o, Time::from_us(kT0 + 1000)));
  o.position = {0, 0, 0};
  o.orientation = {1e300, 1e300, 1e300, 1e300};  // finite, but no rotation
  ASSERT_TRUE(bus.deliver_message("VEHICLE_ODOM", o, Time::from_us(kT0 + 2000)));
  ASSERT_TRUE(bus.advance(Time::from_us(kT0 + 500000)));
  EXPECT_EQ(offboard.phase(), OffboardModule::Phase::kWaiting);  // nothing usable yet
  EXPECT_TRUE(bus.published("SETPOINT_OUT").empty());
  o.position = {1, 2, 0};
  o.orientation = {1, 0, 0, 0};
  ASSERT_TRUE(bus.deliver_message("VEHICLE_ODOM", o, Time::from_us(kT0 + 600000)));
  ASSERT_TRUE(bus.advance(Time::from_us(kT0 + 1000000)));
  const auto setpoints = bus.published("SETPOINT_OUT");
  ASSERT_FALSE(setpoints.empty());
  for (const auto& e : setpoints) {
    driftlab::trajectory_setpoint_t sp;
    ASSERT_GT(sp.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
    EXPECT_EQ(sp.position.x, 1);
    EXPECT_EQ(sp.position.y, 2);
  }
  EXPECT_EQ(offboard.counters().dropped, 3);
  ASSERT_FALSE(offboard.counters().warnings.empty());
  EXPECT_NE(offboard.counters().warnings.back().find("VEHICLE_ODOM: position.x = inf"), std::string::npos)
      << offboard.counters().warnings.back();
}

}  // namespace
}  // namespace driftlab::flight
