#include "slam/rawlog.h"

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileOutputStream.h>
#include <mrpt/math/CMatrixF.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/rtti/CObject.h>
#include <mrpt/serialization/CArchive.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>

#include "core/log_reader.h"
#include "core/log_writer.h"
#include "core/time.h"
#include "driftlab/imu_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/planar.h"
#include "lcmtypes/validate.h"
#include "slam/internal/mrpt_scan.h"

namespace driftlab::slam {
namespace {

int64_t to_utime(mrpt::Clock::time_point t) { return Time::from_seconds_rounded(mrpt::Clock::toDouble(t)).us(); }

template <typename T>
Status put(LogWriter& w, int64_t utime, const std::string& channel, const T& msg) {
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return w.write(utime, channel, bytes);
}

/// The most beams a 2D scan in a rawlog may declare. Real scanners give a few thousand (SICK LMS: 181 to 1141,
/// Hokuyo UTM: 1081); a million is far beyond any and still only 9 MB per scan.
constexpr uint32_t kMaxScanBeams = 1u << 20;

/// Where the scan being read sits, for the error (set while a rawlog is imported; one import per thread).
thread_local const mrpt::io::CFileGZInputStream* t_stream = nullptr;
thread_local std::string t_refused;  ///< why a scan was refused ("" when none was)

/// MRPT's CObservation2DRangeScan::serializeFrom resizes the scan to its declared beam count before reading the
/// beams (2^31-1 beams: 18 GB). This reads the same fields in the same order (MRPT 2.5's versions 0 to 7) with
/// MRPT's own readers for everything nested (the sensor pose, the old covariance), but refuses a count over
/// kMaxScanBeams before anything is allocated and reads the beams in blocks, so what is held never exceeds what
/// the stream really carries. It is registered in place of MRPT's class while a rawlog is imported.
class BoundedScan : public mrpt::obs::CObservation2DRangeScan {
 protected:
  void serializeFrom(mrpt::serialization::CArchive& in, uint8_t version) override {
    if (version > 7) {  // not written by MRPT 2.5: its own reader says so
      CObservation2DRangeScan::serializeFrom(in, version);
      return;
    }
    in >> aperture >> rightToLeft >> maxRange >> sensorPose;
    if (version < 6) {  // the sensor pose's covariance, dropped in version 6
      mrpt::math::CMatrixF cov;
      in >> cov;
    }
    const uint64_t at = t_stream != nullptr ? t_stream->getPosition() : 0;
    uint32_t n = 0;
    in >> n;
    if (n > kMaxScanBeams) {
      t_refused = "a 2D laser scan (CObservation2DRangeScan) declaring " + std::to_string(n) +
                  " ranges (its count at byte " + std::to_string(at) + " uncompressed), more than the " +
                  std::to_string(kMaxScanBeams) + " a scan may have";
      throw std::runtime_error(t_refused);
    }
    std::vector<float> ranges;
    std::vector<char> valid;
    constexpr uint32_t kBlock = 1u << 14;
    for (uint32_t done = 0; done < n;) {  // blocks: a count the stream does not carry ends at its end (EOF)
      const uint32_t k = std::min(kBlock, n - done);
      ranges.resize(done + k);
      in.ReadBufferFixEndianness(ranges.data() + done, k);
      done += k;
    }
    if (version >= 1) {
      for (uint32_t done = 0; done < n;) {
        const uint32_t k = std::min(kBlock, n - done);
        valid.resize(done + k);
        in.ReadBuffer(valid.data() + done, k);
        done += k;
      }
    } else {
      valid.resize(n);
      for (uint32_t i = 0; i < n; ++i) valid[i] = ranges[i] < maxRange ? 1 : 0;
    }
    if (version < 4) {
      stdError = 0.01f;
      if (version >= 2) in >> stdError;
      if (version >= 3) in >> timestamp;
      beamAperture = static_cast<float>(0.25 * M_PI / 180);
      deltaPitch = 0;
      sensorLabel = "";
    } else {
      in >> stdError;
      in >> timestamp;
      in >> beamAperture;
      if (version >= 5) {
        in >> sensorLabel;
        in >> deltaPitch;
      } else {
        sensorLabel = "";
        deltaPitch = 0;
      }
    }
    std::vector<int32_t> intensity;
    bool has_intensity = false;
    if (version >= 7) {
      in >> has_intensity;
      for (uint32_t done = 0; has_intensity && done < n;) {
        const uint32_t k = std::min(kBlock, n - done);
        intensity.resize(done + k);
        in.ReadBufferFixEndianness(intensity.data() + done, k);
        done += k;
      }
    }
    loadFromVectors(n, ranges.data(), valid.data());
    setScanHasIntensity(has_intensity);
    for (uint32_t i = 0; has_intensity && i < n; ++i) setScanIntensity(i, intensity[i]);
  }
};

/// While alive, MRPT creates BoundedScan wherever a rawlog holds a CObservation2DRangeScan (also inside sensory
/// frames, which MRPT reads itself); MRPT's own class is registered back afterwards.
class BoundedScanRegistration {
 public:
  explicit BoundedScanRegistration(const mrpt::io::CFileGZInputStream& in) {
    t_stream = &in;
    t_refused.clear();
    static const mrpt::rtti::TRuntimeClassId bounded = [] {
      mrpt::rtti::TRuntimeClassId id = *CLASS_ID(mrpt::obs::CObservation2DRangeScan);
      id.ptrCreateObject = [] { return std::make_shared<BoundedScan>(); };
      return id;
    }();
    quietly_register(&bounded);
  }
  ~BoundedScanRegistration() {
    quietly_register(CLASS_ID(mrpt::obs::CObservation2DRangeScan));
    t_stream = nullptr;
  }
  BoundedScanRegistration(const BoundedScanRegistration&) = delete;

 private:
  /// MRPT's registry warns on std::cerr when a name is registered again: that is the point here, not news.
  static void quietly_register(const mrpt::rtti::TRuntimeClassId* id) {
    std::streambuf* err = std::cerr.rdbuf(nullptr);
    mrpt::rtti::registerClass(id);
    std::cerr.rdbuf(err);
    std::cerr.clear();
  }
  BoundedScanRegistration& operator=(const BoundedScanRegistration&) = delete;
};

/// Writes one rawlog's observations into a log.
class Importer {
 public:
  Importer(LogWriter& w, RawlogCounts& counts) : w_(w), counts_(counts) {}

  /// Whether two observations read so far carry different timestamps.
  bool stamps_differ() const { return stamps_differ_; }

  Status observation(const mrpt::obs::CObservation& o) {
    using namespace mrpt::obs;
    const int64_t t = to_utime(o.timestamp);
    last_utime_ = t;
    if (counts_.observations++ == 0) {
      counts_.one_stamp_us = t;
    } else if (t != counts_.one_stamp_us) {
      stamps_differ_ = true;
    }
    if (const auto* scan = dynamic_cast<const CObservation2DRangeScan*>(&o)) {
      const std::string frame = o.sensorLabel.empty() ? "laser" : o.sensorLabel;
      const mrpt::poses::CPose3D& p = scan->sensorPose;
      auto known = sensors_.find(frame);
      if (known == sensors_.end() || !(known->second == p)) {
        sensors_[frame] = p;
        driftlab::tf_t tf{};
        tf.header.seq = seq_["TF_STATIC"]++;
        tf.header.utime = t;
        tf.header.frame_id = "base_link";
        for (const auto& [name, pose] : sensors_) {
          driftlab::transform_t x{};
          x.header.utime = t;
          x.header.frame_id = "base_link";
          x.child_frame_id = name;
          x.translation = {pose.x(), pose.y(), pose.z()};
          x.rotation = yaw_quaternion(pose.yaw());
          tf.transforms.push_back(x);
        }
        tf.ntransforms = static_cast<int32_t>(tf.transforms.size());
        if (Status s = emit(t, "TF_STATIC", tf); !s) return s;
      }
      driftlab::laser_scan_t s = internal::from_mrpt(*scan);
      s.header.utime = t;
      s.header.frame_id = frame;
      return emit(t, "SCAN", s);
    }
    if (const auto* odo = dynamic_cast<const CObservationOdometry*>(&o)) {
      return odometry(t, odo->odometry, odo->hasVelocities ? odo->velocityLocal.vx : 0.0,
                      odo->hasVelocities ? odo->velocityLocal.omega : 0.0);
    }
    if (const auto* imu = dynamic_cast<const CObservationIMU*>(&o)) {
      driftlab::imu_t m{};
      m.header.utime = t;
      m.header.frame_id = o.sensorLabel.empty() ? "imu" : o.sensorLabel;
      m.orientation = {1, 0, 0, 0};
      m.orientation_covariance[0] = -1;  // not provided
      auto get = [&](TIMUDataIndex i) { return imu->has(i) ? imu->get(i) : 0.0; };
      m.angular_velocity = {get(IMU_WX), get(IMU_WY), get(IMU_WZ)};
      m.linear_acceleration = {get(IMU_X_ACC), get(IMU_Y_ACC), get(IMU_Z_ACC)};
      return emit(t, "IMU", m);
    }
    if (const auto* gt = dynamic_cast<const CObservationRobotPose*>(&o)) {
      driftlab::pose_t m{};
      m.header.utime = t;
      m.header.frame_id = "world";
      m.child_frame_id = "base_link";
      const mrpt::poses::CPose3D& p = gt->pose.mean;
      m.position = {p.x(), p.y(), p.z()};
      mrpt::math::CQuaternionDouble q;
      p.getAsQuaternion(q);
      m.orientation = {q.r(), q.x(), q.y(), q.z()};
      return emit(t, "GROUND_TRUTH", m);
    }
    ++counts_.skipped[o.GetRuntimeClass()->className];
    return {};
  }

  /// Action/sensory-frame rawlogs: the odometry increments are integrated and stamped with the frame's time.
  Status frame(const mrpt::obs::CActionCollection* actions, const mrpt::obs::CSensoryFrame& sf) {
    std::optional<int64_t> t;
    for (const auto& o : sf) {
      if (o) t = t ? std::min(*t, to_utime(o->timestamp)) : to_utime(o->timestamp);
    }
    if (actions != nullptr) {
      if (auto move = actions->getBestMovementEstimation()) {
        odom_ = odom_ + move->poseChange->getMeanVal();
        if (Status s = odometry(t.value_or(last_utime_), odom_, 0, 0); !s) return s;
      }
    }
    for (const auto& o : sf) {
      if (!o) continue;
      if (Status s = observation(*o); !s) return s;
    }
    return {};
  }

 private:
  Status odometry(int64_t t, const mrpt::poses::CPose2D& pose, double v, double w) {
    driftlab::odometry_t m{};
    m.header.utime = t;
    m.header.frame_id = "odom";
    m.child_frame_id = "base_link";
    m.position = {pose.x(), pose.y(), 0};
    m.orientation = yaw_quaternion(pose.phi());
    m.linear_velocity = {v, 0, 0};
    m.angular_velocity = {0, 0, w};
    return emit(t, "ODOM", m);
  }

  template <typename T>
  Status emit(int64_t t, const std::string& channel, T& msg) {
    msg.header.seq = seq_[channel]++;
    ++counts_.written[channel];
    return put(w_, t, channel, msg);
  }

  LogWriter& w_;
  RawlogCounts& counts_;
  std::map<std::string, int64_t> seq_;
  std::map<std::string, mrpt::poses::CPose3D> sensors_;
  mrpt::poses::CPose2D odom_;
  int64_t last_utime_ = 0;
  bool stamps_differ_ = false;
};

}  // namespace

Result<RawlogCounts> import_rawlog(const std::string& rawlog, const std::string& out_log) {
  if (!std::filesystem::is_regular_file(rawlog)) return Error{rawlog + ": no such rawlog file"};
  mrpt::io::CFileGZInputStream in;
  if (!in.open(rawlog)) return Error{rawlog + ": cannot open the rawlog"};
  const uint64_t compressed = std::filesystem::file_size(rawlog);
  auto w = LogWriter::create(out_log, {.atomic = true});
  if (!w) return w.error();
  RawlogCounts counts;
  Importer importer(*w, counts);
  auto archive = mrpt::serialization::archiveFrom(in);
  const BoundedScanRegistration bounded_scans(in);
  mrpt::obs::CActionCollection::Ptr pending_actions;
  for (size_t entry = 0;; ++entry) {
    mrpt::serialization::CSerializable::Ptr object;
    const uint64_t before = in.getPosition();
    try {
      archive >> object;
    } catch (const mrpt::serialization::CExceptionEOF&) {
      if (in.getPosition() == before) break;  // the end, between entries
      w->discard();
      return Error{rawlog + ": entry " + std::to_string(entry) + " (byte " + std::to_string(before) +
                   " uncompressed) is cut off: the rawlog is truncated"};
    } catch (const std::exception& e) {
      w->discard();
      if (!t_refused.empty()) {
        return Error{rawlog + ": entry " + std::to_string(entry) + " (byte " + std::to_string(before) +
                     " uncompressed): " + t_refused};
      }
      if (in.getPosition() >= compressed && entry > 0 && before > 0 && in.checkEOF()) {
        return Error{rawlog + ": entry " + std::to_string(entry) + " is cut off: the rawlog is truncated"};
      }
      return Error{rawlog + ": entry " + std::to_string(entry) + " (byte " + std::to_string(before) +
                   " uncompressed): not an MRPT object: " + one_line(e.what())};
    }
    Status s;
    if (auto actions = std::dynamic_pointer_cast<mrpt::obs::CActionCollection>(object)) {
      pending_actions = actions;
    } else if (auto sf = std::dynamic_pointer_cast<mrpt::obs::CSensoryFrame>(object)) {
      s = importer.frame(pending_actions.get(), *sf);
      pending_actions.reset();
    } else if (auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(object)) {
      s = importer.observation(*obs);
    } else if (object) {
      ++counts.skipped[object->GetRuntimeClass()->className];
    }
    if (!s) {
      (void)w->close();
      return s.error();
    }
  }
  if (Status s = w->close(); !s) return s.error();
  if (counts.observations >= 2 && !importer.stamps_differ()) counts.one_stamp = counts.observations;
  if (counts.written.empty()) {
    std::filesystem::remove(out_log);
    return Error{rawlog + ": no observations driftlab can convert (2D scans, odometry, IMU, robot poses)"};
  }
  return counts;
}

Result<RawlogCounts> export_rawlog(const std::string& log, const std::string& out_rawlog) {
  auto reader = LogReader::open(log);
  if (!reader) return reader.error();
  const std::string tmp = out_rawlog + ".partial";
  RawlogCounts counts;
  try {
    mrpt::io::CFileOutputStream out;
    if (!out.open(tmp)) return Error{out_rawlog + ": cannot create the rawlog", ErrorCode::kCannotWrite};
    auto archive = mrpt::serialization::archiveFrom(out);
    std::map<std::string, mrpt::poses::CPose2D> sensors;  // base_link -> frame, from TF_STATIC
    Event e;
    while (reader->next(e)) {
      const std::string channel(e.channel);
      const std::span<const uint8_t> data = e.data;
      driftlab::laser_scan_t scan;
      driftlab::odometry_t odo;
      driftlab::imu_t imu;
      driftlab::pose_t pose;
      driftlab::tf_t tf;
      if (lcmtypes::decode(data, tf)) {
        for (const auto& t : tf.transforms) {
          if (t.header.frame_id == "base_link") {
            sensors[t.child_frame_id] = mrpt::poses::CPose2D(t.translation.x, t.translation.y, yaw_of(t.rotation));
          }
        }
        continue;
      }
      if (lcmtypes::decode(data, scan) && scan.nranges >= 2) {
        auto it = sensors.find(scan.header.frame_id);
        auto obs = internal::to_mrpt(scan, it != sensors.end() ? it->second : mrpt::poses::CPose2D());
        obs->sensorLabel = channel;
        archive << *obs;
        ++counts.written["CObservation2DRangeScan"];
      } else if (lcmtypes::decode(data, odo)) {
        mrpt::obs::CObservationOdometry obs;
        obs.timestamp = mrpt::Clock::fromDouble(Time::from_us(odo.header.utime).seconds());
        obs.sensorLabel = channel;
        obs.odometry = mrpt::poses::CPose2D(odo.position.x, odo.position.y, yaw_of(odo.orientation));
        obs.hasVelocities = true;
        obs.velocityLocal = {odo.linear_velocity.x, odo.linear_velocity.y, odo.angular_velocity.z};
        archive << obs;
        ++counts.written["CObservationOdometry"];
      } else if (lcmtypes::decode(data, imu)) {
        mrpt::obs::CObservationIMU obs;
        obs.timestamp = mrpt::Clock::fromDouble(Time::from_us(imu.header.utime).seconds());
        obs.sensorLabel = channel;
        obs.set(mrpt::obs::IMU_WX, imu.angular_velocity.x);
        obs.set(mrpt::obs::IMU_WY, imu.angular_velocity.y);
        obs.set(mrpt::obs::IMU_WZ, imu.angular_velocity.z);
        obs.set(mrpt::obs::IMU_X_ACC, imu.linear_acceleration.x);
        obs.set(mrpt::obs::IMU_Y_ACC, imu.linear_acceleration.y);
        obs.set(mrpt::obs::IMU_Z_ACC, imu.linear_acceleration.z);
        archive << obs;
        ++counts.written["CObservationIMU"];
      } else if (channel == "GROUND_TRUTH" && lcmtypes::decode(data, pose)) {
        mrpt::obs::CObservationRobotPose obs;
        obs.timestamp = mrpt::Clock::fromDouble(Time::from_us(pose.header.utime).seconds());
        obs.sensorLabel = channel;
        const auto& q = pose.orientation;
        obs.pose.mean = mrpt::poses::CPose3D(mrpt::math::CQuaternionDouble(q.w, q.x, q.y, q.z), pose.position.x,
                                             pose.position.y, pose.position.z);
        archive << obs;
        ++counts.written["CObservationRobotPose"];
      } else {
        ++counts.skipped[channel];
      }
    }
  } catch (const std::exception& e) {
    std::filesystem::remove(tmp);
    return Error{out_rawlog + ": cannot write the rawlog: " + one_line(e.what()), ErrorCode::kCannotWrite};
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out_rawlog, ec);
  if (ec) {
    return Error{out_rawlog + ": cannot rename " + tmp + " into place: " + ec.message(), ErrorCode::kCannotWrite};
  }
  return counts;
}

}  // namespace driftlab::slam
