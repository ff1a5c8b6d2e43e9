// Writes the sample log logs/sample.lcm and the golden logs of tests/data: a differential-drive robot
// driving a circle for 5 s, with IMU (200 Hz), 2D scans (10 Hz, 360 beams, a round room), wheel odometry
// (50 Hz), ground truth (100 Hz), TF (50 Hz), static TF (1 Hz) and velocity commands (20 Hz). Deterministic: the same
// binary writes the same bytes. The corrupt variants are the clean log with surgical damage.
//   make_sample_log OUT_DIR [SECONDS [turning]]   (default 5 s, a circle; "turning": a weave)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "core/log_writer.h"
#include "tests/test_util.h"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "driftlab/velocity_command_t.hpp"

namespace {

constexpr int64_t kStart = 1763776800000000;  // 2025-11-22 02:00:00 UTC [us]
constexpr double kSpeed = 0.5;                // [m/s]
constexpr double kYawRate = 0.25;             // [rad/s]
constexpr double kRoomRadius = 6.0;           // [m]

template <typename T>
std::vector<uint8_t> encode(const T& msg) {
  std::vector<uint8_t> buf(msg.getEncodedSize());
  msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
  return buf;
}

driftlab::header_t header(int64_t seq, int64_t utime, const char* frame) {
  driftlab::header_t h;
  h.seq = seq;
  h.utime = utime;
  h.frame_id = frame;
  return h;
}

driftlab::quaternion_t yaw_quat(double yaw) {
  driftlab::quaternion_t q;
  q.w = std::cos(yaw / 2);
  q.x = 0;
  q.y = 0;
  q.z = std::sin(yaw / 2);
  return q;
}

struct State {
  double x, y, yaw;
};
State truth_at(double t) {
  // Constant speed and yaw rate: a circle of radius kSpeed / kYawRate starting at the origin.
  const double r = kSpeed / kYawRate;
  const double yaw = kYawRate * t;
  return {r * std::sin(yaw), r * (1 - std::cos(yaw)), yaw};
}

/// The yaw rate [rad/s] at time t: constant (a circle), or, when turning, varying (a weave), which gives
/// `driftlab diagnose` a motion to correlate streams by.
double yaw_rate_at(double t, bool turning) { return turning ? kYawRate + 0.2 * std::sin(0.7 * t) : kYawRate; }

void write_clean(const std::string& path, int64_t duration_us, bool turning) {
  auto w = driftlab::LogWriter::create(path, {.atomic = true});
  if (!w) {
    std::fprintf(stderr, "%s\n", w.error().message.c_str());
    std::exit(1);
  }
  struct Arrival {
    int64_t utime;
    const char* channel;
    std::vector<uint8_t> bytes;
  };
  std::vector<Arrival> arrivals;
  std::mt19937_64 rng(42);
  State weave{0, 0, 0};
  std::normal_distribution<double> noise(0.0, 1.0);
  int64_t seq_imu = 0, seq_scan = 0, seq_odom = 0, seq_gt = 0, seq_tf = 0, seq_cmd = 0, seq_static = 0;
  const int64_t step = 1000;  // 1 ms simulation step [us]
  for (int64_t us = 0; us <= duration_us; us += step) {
    const int64_t t = kStart + us;
    const double ts = static_cast<double>(us) * 1e-6;
    State s = truth_at(ts);
    if (turning) {
      // Integrate the weave (1 ms steps).
      weave.yaw += yaw_rate_at(ts, true) * 1e-3;
      weave.x += kSpeed * std::cos(weave.yaw) * 1e-3;
      weave.y += kSpeed * std::sin(weave.yaw) * 1e-3;
      s = weave;
    }
    const double w = yaw_rate_at(ts, turning);
    // Each stream reaches the logger after its own transport latency: log timestamp = arrival time.
    auto put = [&](const char* channel, std::vector<uint8_t> bytes, int64_t latency_us) {
      arrivals.push_back({t + latency_us, channel, std::move(bytes)});
    };
    if (us % 5000 == 0) {
      driftlab::imu_t m{};
      m.header = header(seq_imu++, t, "imu_link");
      m.orientation = yaw_quat(s.yaw);
      m.angular_velocity = {0.0 + 0.002 * noise(rng), 0.0 + 0.002 * noise(rng), w + 0.002 * noise(rng)};
      // Centripetal acceleration v * omega towards the centre (body +y), plus gravity.
      m.linear_acceleration = {0.02 * noise(rng), kSpeed * w + 0.02 * noise(rng), 9.81 + 0.02 * noise(rng)};
      m.orientation_covariance[0] = -1;
      for (int i = 0; i < 3; ++i) {
        m.angular_velocity_covariance[4 * i] = 4e-6;
        m.linear_acceleration_covariance[4 * i] = 4e-4;
      }
      put("IMU", encode(m), 300);
    }
    if (us % 100000 == 0) {
      driftlab::laser_scan_t m{};
      m.header = header(seq_scan++, t, "laser");
      m.angle_min = static_cast<float>(-M_PI);
      m.angle_increment = static_cast<float>(2 * M_PI / 360);
      m.angle_max = m.angle_min + 359 * m.angle_increment;
      m.time_increment = 0.1f / 360;
      m.scan_time = 0.1f;
      m.range_min = 0.1f;
      m.range_max = 30.0f;
      m.nranges = 360;
      m.ranges.resize(360);
      // Ranges to the wall of a round room of radius kRoomRadius centred at (0, 2).
      for (int i = 0; i < 360; ++i) {
        const double a = s.yaw + m.angle_min + i * m.angle_increment;
        const double px = s.x, py = s.y - 2.0;
        const double b = px * std::cos(a) + py * std::sin(a);
        const double c = px * px + py * py - kRoomRadius * kRoomRadius;
        m.ranges[i] = static_cast<float>(-b + std::sqrt(b * b - c) + 0.01 * noise(rng));
      }
      m.nintensities = 0;
      put("SCAN", encode(m), 4000);
    }
    if (us % 20000 == 0) {
      driftlab::odometry_t m{};
      m.header = header(seq_odom++, t, "odom");
      m.child_frame_id = "base_link";
      m.position = {s.x * 1.01, s.y * 1.01, 0};  // 1% scale error: odometry drifts
      m.orientation = yaw_quat(s.yaw * 1.01);
      m.linear_velocity = {kSpeed * 1.01, 0, 0};
      m.angular_velocity = {0, 0, w * 1.01};
      put("ODOM", encode(m), 800);

      driftlab::tf_t tf{};
      tf.header = header(seq_tf++, t, "odom");
      tf.ntransforms = 1;
      driftlab::transform_t tr{};
      tr.header = header(0, t, "odom");
      tr.child_frame_id = "base_link";
      tr.translation = m.position;
      tr.rotation = m.orientation;
      tf.transforms.push_back(tr);
      put("TF", encode(tf), 900);
    }
    if (us % 1000000 == 0) {
      // The static frames, republished every second: world -> odom, base_link -> imu_link and laser.
      driftlab::tf_t tf{};
      tf.header = header(seq_static++, t, "base_link");
      const std::pair<const char*, const char*> edges[] = {{"world", "odom"}, {"base_link", "imu_link"},
                                                           {"base_link", "laser"}};
      for (const auto& [parent, child] : edges) {
        driftlab::transform_t tr{};
        tr.header = header(0, t, parent);
        tr.child_frame_id = child;
        tr.translation = {std::string(child) == "laser" ? 0.2 : 0.0, 0, std::string(child) == "laser" ? 0.3 : 0.1};
        tr.rotation = yaw_quat(0);
        tf.transforms.push_back(tr);
      }
      tf.ntransforms = static_cast<int32_t>(tf.transforms.size());
      put("TF_STATIC", encode(tf), 500);
    }
    if (us % 10000 == 0) {
      driftlab::pose_t m{};
      m.header = header(seq_gt++, t, "world");
      m.child_frame_id = "base_link";
      m.position = {s.x, s.y, 0};
      m.orientation = yaw_quat(s.yaw);
      put("GROUND_TRUTH", encode(m), 0);
    }
    if (us % 50000 == 0) {
      driftlab::velocity_command_t m{};
      m.header = header(seq_cmd++, t, "base_link");
      m.linear = {kSpeed, 0, 0};
      m.angular = {0, 0, w};
      put("CMD_VEL", encode(m), 200);
    }
  }
  // A logger writes in arrival order.
  std::stable_sort(arrivals.begin(), arrivals.end(),
                   [](const Arrival& a, const Arrival& b) { return a.utime < b.utime; });
  for (const Arrival& a : arrivals) {
    if (auto st = w->write(a.utime, a.channel, a.bytes); !st) {
      std::fprintf(stderr, "%s\n", st.message().c_str());
      std::exit(1);
    }
  }
  if (auto st = w->close(); !st) {
    std::fprintf(stderr, "%s\n", st.message().c_str());
    std::exit(1);
  }
}

/// Offsets of the first n events of a clean log.
std::vector<size_t> event_offsets(const std::vector<uint8_t>& b, size_t n) {
  std::vector<size_t> out;
  size_t pos = 0;
  while (out.size() < n && pos + 28 <= b.size()) {
    out.push_back(pos);
    auto be32 = [&](size_t at) {
      return (uint32_t(b[at]) << 24) | (uint32_t(b[at + 1]) << 16) | (uint32_t(b[at + 2]) << 8) | b[at + 3];
    };
    pos += 28 + be32(pos + 20) + be32(pos + 24);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || argc > 4) {
    std::fprintf(stderr, "usage: make_sample_log OUT_DIR [SECONDS [turning]]\n");
    return 2;
  }
  const std::string dir = argv[1];
  const double seconds = argc >= 3 ? std::atof(argv[2]) : 5.0;
  const bool turning = argc == 4 && std::string(argv[3]) == "turning";
  write_clean(dir + "/sample.lcm", static_cast<int64_t>(seconds * 1e6), turning);
  const auto clean = driftlab::test::read_file(dir + "/sample.lcm");
  const auto ev = event_offsets(clean, 60);

  // Truncated: the last event loses its final 100 bytes.
  driftlab::test::write_file(dir + "/truncated.lcm", {clean.begin(), clean.end() - 100});

  // Garbage: 37 bytes of noise inserted before event 10.
  {
    auto b = clean;
    std::vector<uint8_t> noise(37);
    for (size_t i = 0; i < noise.size(); ++i) noise[i] = static_cast<uint8_t>(i * 73 + 11);
    b.insert(b.begin() + static_cast<long>(ev[10]), noise.begin(), noise.end());
    driftlab::test::write_file(dir + "/garbage.lcm", b);
  }
  // Bad lengths: event 20's data length points past the end of the file; event 30's channel length is absurd.
  {
    auto b = clean;
    b[ev[20] + 24] = 0x7f;
    b[ev[30] + 20] = 0x12;
    driftlab::test::write_file(dir + "/bad_lengths.lcm", b);
  }
  // Not a log at all.
  {
    std::string text = "This is a text file, not an LCM log.\n";
    driftlab::test::write_file(dir + "/not_a_log.txt", {text.begin(), text.end()});
  }
  driftlab::test::write_file(dir + "/empty.lcm", {});
  return 0;
}
