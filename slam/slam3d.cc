#include "slam/slam3d.h"

#include <pcl/common/transforms.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>
#include <pcl/registration/ndt.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <vector>

#include "core/config.h"
#include "core/time.h"
#include "driftlab/odometry_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/planar.h"
#include "runtime/module_input.h"
#include "slam/internal/odometry_buffer.h"

namespace driftlab::slam {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

// The map as a binary PCD, as pcl::io::savePCDFileBinary writes a PointXYZ cloud (the test compares them byte for
// byte). Written here, not by PCL: libpcl_io links VTK and more, 39 shared libraries that every `driftlab replay`
// would load at start, 2D or 3D, for this one call (docs/benchmarks.md, start-up).
bool write_pcd(const std::string& path, const Cloud& cloud) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.imbue(std::locale::classic());
  const Eigen::Vector4f& o = cloud.sensor_origin_;
  const Eigen::Quaternionf& q = cloud.sensor_orientation_;
  out << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
      << "COUNT 1 1 1\nWIDTH " << cloud.width << "\nHEIGHT " << cloud.height << "\nVIEWPOINT " << o[0] << ' ' << o[1]
      << ' ' << o[2] << ' ' << q.w() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << "\nPOINTS " << cloud.size()
      << "\nDATA binary\n";
  for (const auto& p : cloud) {  // x, y, z of each point, through the stream's buffer (no copy of the map)
    const std::array<float, 3> xyz = {p.x, p.y, p.z};
    out.write(reinterpret_cast<const char*>(xyz.data()), sizeof(xyz));
  }
  out.close();
  return static_cast<bool>(out);
}

Eigen::Isometry3d planar(const Pose2& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translate(Eigen::Vector3d(p.x, p.y, 0));
  t.rotate(Eigen::AngleAxisd(p.yaw, Eigen::Vector3d::UnitZ()));
  return t;
}

/// Fewer returns than this in range and the cloud is not registered.
constexpr size_t kMinPoints = 100;

Cloud::Ptr downsample(const Cloud::ConstPtr& in, double leaf) {
  auto out = std::make_shared<Cloud>();
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setLeafSize(static_cast<float>(leaf), static_cast<float>(leaf), static_cast<float>(leaf));
  grid.setInputCloud(in);
  grid.filter(*out);
  return out;
}

}  // namespace

Result<Slam3dConfig> parse_slam3d_config(const YAML::Node& node, const std::string& origin) {
  return slam3d_config_table().parse(config::Value(node, origin, "slam.3d"));
}

struct Slam3d::Impl {
  Slam3dConfig c;
  std::unique_ptr<pcl::Registration<pcl::PointXYZ, pcl::PointXYZ>> reg;
  std::map<std::string, Eigen::Isometry3d> sensor_on_base;  ///< by cloud frame, from TF_STATIC
  internal::OdometryBuffer odom;
  bool have_pose = false;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();          ///< base in map, at the last cloud
  Eigen::Isometry3d last_motion = Eigen::Isometry3d::Identity();   ///< between the last two clouds
  std::optional<Pose2> odom_at_last;
  Eigen::Isometry3d last_keyframe = Eigen::Isometry3d::Identity();
  std::deque<Cloud::Ptr> local;  ///< recent keyframes in the map frame, at `voxel`
  Cloud::Ptr map = std::make_shared<Cloud>();  ///< every keyframe in the map frame, at about `map_voxel`
  size_t map_filtered = 0;                     ///< map's size after its last voxel filtering
  int64_t clouds = 0, not_clouds = 0, unusable = 0, unconverged = 0, rejected = 0, undecodable = 0;
  int64_t odometry = 0, keyframes = 0, registered = 0, seq = 0;
  double fitness_sum = 0, fitness_max = 0;
  NonFiniteInputs non_finite;
  bool tf_missing_warned = false;
  std::vector<std::string> warnings;

  void set_target() {
    auto target = std::make_shared<Cloud>();
    for (const auto& k : local) *target += *k;
    reg->setInputTarget(downsample(target, c.voxel));
  }

  void on_cloud(Bus& bus, const BusMessage& m);
};

void Slam3d::Impl::on_cloud(Bus& bus, const BusMessage& m) {
  driftlab::point_cloud_t pc;
  if (!decode_message(m, pc)) return void(++not_clouds);
  ++clouds;
  const int64_t stamp = pc.header.utime;
  Eigen::Isometry3d sensor = Eigen::Isometry3d::Identity();
  sensor.translate(Eigen::Vector3d(c.sensor_pose[0], c.sensor_pose[1], c.sensor_pose[2]));
  sensor.rotate(Eigen::AngleAxisd(c.sensor_pose[3], Eigen::Vector3d::UnitZ()));
  if (auto it = sensor_on_base.find(pc.header.frame_id); it != sensor_on_base.end()) {
    sensor = it->second;
  } else if (!tf_missing_warned && !c.tf_static_channel.empty()) {
    tf_missing_warned = true;
    warnings.push_back("slam3d: no " + c.base_frame + " -> " + pc.header.frame_id + " on " + c.tf_static_channel +
                       " before the first cloud: the sensor_pose setting was used");
  }

  // The base's motion from the stamp to `s` seconds after it, from the wheel odometry, for undoing the motion
  // during the sweep. Without odometry the sweep is left as it is: deskewing with the velocity registration itself
  // found feeds each cloud's error into the next (tried: on the simulated corridor the pose then oscillated from
  // cloud to cloud, growing until registration failed).
  const auto odo = odom.at(stamp);
  auto motion_after = [&](double s) -> Eigen::Isometry3d {
    int64_t at = 0;  // saturated: a hostile stamp near the end of int64_t must not overflow
    if (__builtin_add_overflow(stamp, Duration::from_seconds_rounded(s).us(), &at)) at = s > 0 ? INT64_MAX : INT64_MIN;
    return planar(*odo).inverse() * planar(*odom.at(at));
  };

  // The returns within range, in the base frame at the stamp. An organised cloud is walked column by column, so
  // the points of one column (one time offset) share one transform.
  const size_t n = std::min({pc.x.size(), pc.y.size(), pc.z.size()});
  const bool deskew = c.deskew && odo && pc.time_offsets.size() == n;
  const size_t rows = pc.height > 1 ? static_cast<size_t>(pc.height) : 1;
  const size_t cols = pc.width > 0 ? static_cast<size_t>(pc.width) : 0;
  const bool organised = rows > 1 && rows * cols == n;
  auto raw = std::make_shared<Cloud>();
  raw->reserve(n);
  Eigen::Matrix4f to_base = sensor.matrix().cast<float>();
  float offset = 0;
  bool have_offset = false;
  const double min2 = c.min_range * c.min_range, max2 = c.max_range * c.max_range;
  for (size_t k = 0; k < n; ++k) {
    const size_t i = organised ? (k % rows) * cols + k / rows : k;
    const float x = pc.x[i], y = pc.y[i], z = pc.z[i];
    const double r2 = double(x) * x + double(y) * y + double(z) * z;
    if (!std::isfinite(r2) || r2 < min2 || r2 > max2) continue;
    if (deskew) {
      // Offsets beyond a second are not a sweep: they are treated as 0 rather than trusted.
      float s = pc.time_offsets[i];
      if (!std::isfinite(s) || std::abs(s) > 1) s = 0;
      if (!have_offset || s != offset) {
        have_offset = true;
        offset = s;
        to_base = (motion_after(s) * sensor).matrix().cast<float>();
      }
    }
    const Eigen::Vector4f p = to_base * Eigen::Vector4f(x, y, z, 1);
    raw->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  }
  if (raw->size() < kMinPoints) return void(++unusable);
  Cloud::Ptr scan = downsample(raw, c.voxel);

  // The prior: the odometry's motion since the last cloud, else the last motion again.
  Eigen::Isometry3d motion = last_motion;
  if (odo && odom_at_last) motion = planar(*odom_at_last).inverse() * planar(*odo);
  bool matched = true;
  if (!have_pose) {
    have_pose = true;  // the first cloud's base is the map's origin
  } else {
    const Eigen::Isometry3d guess = pose * motion;
    reg->setInputSource(scan);
    Cloud aligned;
    reg->align(aligned, guess.matrix().cast<float>());
    Eigen::Isometry3d found = guess;
    if (!reg->hasConverged() || !reg->getFinalTransformation().allFinite()) {
      ++unconverged;
      matched = false;
    } else {
      // Over the points within max_correspondence of the map only: a cloud that sees a room the map has not seen
      // yet (through a door) is not a bad match, and counting those points rejected good registrations.
      const double fitness = reg->getFitnessScore(c.max_correspondence);
      if (!(fitness <= c.max_fitness)) {
        ++rejected;
        matched = false;
      } else {
        found.matrix() = reg->getFinalTransformation().cast<double>();
        // PCL works in float: re-orthonormalise the rotation so the error does not pile up pose after pose.
        found.linear() = Eigen::Quaterniond(found.rotation()).normalized().toRotationMatrix();
        ++registered;
        fitness_sum += fitness;
        fitness_max = std::max(fitness_max, fitness);
      }
    }
    last_motion = pose.inverse() * found;
    pose = found;
  }
  if (odo) odom_at_last = odo;

  // A keyframe after enough motion (from matched clouds only): it joins the local map (the registration target)
  // and the final map.
  const Eigen::Isometry3d since = last_keyframe.inverse() * pose;
  const double angle = Eigen::AngleAxisd(since.rotation()).angle() * 180 / M_PI;
  if (matched &&
      (keyframes == 0 || since.translation().norm() > c.keyframe_distance || angle > c.keyframe_angle)) {
    ++keyframes;
    const Eigen::Matrix4f to_map = pose.matrix().cast<float>();
    auto in_map = std::make_shared<Cloud>();
    pcl::transformPointCloud(*scan, *in_map, to_map);
    local.push_back(in_map);
    while (static_cast<int>(local.size()) > c.local_map_keyframes) local.pop_front();
    last_keyframe = pose;
    set_target();
    // The map keeps finer points than registration needs, filtered again whenever it has doubled.
    Cloud fine;
    pcl::transformPointCloud(c.map_voxel < c.voxel ? *downsample(raw, c.map_voxel) : *scan, fine, to_map);
    *map += fine;
    if (map->size() > 2 * map_filtered + 100000) {
      map = downsample(map, c.map_voxel);
      map_filtered = map->size();
    }
  }

  driftlab::pose_t p{};
  p.header.seq = seq++;
  p.header.utime = stamp;
  p.header.frame_id = "map";
  p.child_frame_id = c.base_frame;
  p.position = {pose.translation().x(), pose.translation().y(), pose.translation().z()};
  const Eigen::Quaterniond q(pose.rotation());
  p.orientation = {q.w(), q.x(), q.y(), q.z()};
  for (double& v : p.covariance) v = 0;
  bus.publish_message(c.pose_channel, p);
}

Slam3d::Slam3d(Slam3dConfig config) : impl_(std::make_unique<Impl>()) { impl_->c = std::move(config); }
Slam3d::~Slam3d() = default;

Status Slam3d::start(Bus& bus) {
  Impl& d = *impl_;
  const Slam3dConfig& c = d.c;
  if (c.method == "icp") {
    auto icp = std::make_unique<pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>>();
    icp->setMaxCorrespondenceDistance(c.max_correspondence);
    d.reg = std::move(icp);
  } else if (c.method == "gicp") {
    auto gicp = std::make_unique<pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>>();
    gicp->setMaxCorrespondenceDistance(c.max_correspondence);
    d.reg = std::move(gicp);
  } else if (c.method == "ndt") {
    auto ndt = std::make_unique<pcl::NormalDistributionsTransform<pcl::PointXYZ, pcl::PointXYZ>>();
    ndt->setResolution(static_cast<float>(c.ndt_resolution));
    ndt->setStepSize(c.ndt_step);
    d.reg = std::move(ndt);
  } else {
    return Error{"slam3d: method = " + c.method + " must be icp, ndt or gicp"};
  }
  d.reg->setMaximumIterations(c.max_iterations);
  d.reg->setTransformationEpsilon(1e-6);

  if (!c.tf_static_channel.empty()) {
    bus.subscribe(c.tf_static_channel, [this](const BusMessage& m) {
      driftlab::tf_t tf;
      if (!decode_message(m, tf)) return void(++impl_->undecodable);
      auto& in = impl_->non_finite;
      if (!in.finite(m)) return;
      for (const auto& t : tf.transforms) {
        if (t.header.frame_id != impl_->c.base_frame) continue;
        if (!in.plausible(m.channel, "translation.x", t.translation.x) ||
            !in.plausible(m.channel, "translation.y", t.translation.y) ||
            !in.plausible(m.channel, "translation.z", t.translation.z)) {
          return;
        }
        Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
        x.translate(Eigen::Vector3d(t.translation.x, t.translation.y, t.translation.z));
        x.rotate(Eigen::Quaterniond(t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z).normalized());
        impl_->sensor_on_base[t.child_frame_id] = x;
      }
    });
  }
  if (!c.odom_channel.empty()) {
    bus.subscribe(c.odom_channel, [this](const BusMessage& m) {
      const auto o = internal::planar_odometry(m, impl_->non_finite, &impl_->undecodable);
      if (!o) return;
      ++impl_->odometry;
      impl_->odom.add(o->first, o->second);
    });
  }
  bus.subscribe(c.cloud_channel, [this, &bus](const BusMessage& m) { impl_->on_cloud(bus, m); });
  return {};
}

void Slam3d::finish(Bus& bus) {
  Impl& d = *impl_;
  const std::string prefix = bus.artifact_prefix();
  if (d.map->empty() || prefix.empty()) return;
  d.map = downsample(d.map, d.c.map_voxel);
  d.map_filtered = d.map->size();
  // Written aside and renamed, so a failed write leaves no half a map behind.
  const std::string path = prefix + "-map.pcd", partial = path + ".partial";
  std::error_code ec;
  if (!write_pcd(partial, *d.map)) {
    std::filesystem::remove(partial, ec);
    d.warnings.push_back("slam3d: cannot write " + partial);
  } else if (std::filesystem::rename(partial, path, ec); ec) {
    std::filesystem::remove(partial, ec);
    d.warnings.push_back("slam3d: cannot rename " + partial + " to " + path);
  }
}

ModuleCounters Slam3d::counters() const {
  const Impl& d = *impl_;
  ModuleCounters c;
  c.dropped = d.not_clouds + d.undecodable + d.unusable + d.unconverged + d.rejected + d.non_finite.dropped();
  c.warnings = d.warnings;
  if (auto w = d.non_finite.warning("slam3d")) c.warnings.push_back(*w);
  if (d.clouds == 0) {
    std::string w = "slam3d: no driftlab.point_cloud_t on " + d.c.cloud_channel;
    if (d.not_clouds > 0) w += " (" + std::to_string(d.not_clouds) + " messages of another type)";
    c.warnings.push_back(w + ": no poses, no map");
  } else {
    if (d.unusable == d.clouds) {
      c.warnings.push_back("slam3d: no cloud on " + d.c.cloud_channel + " had " + std::to_string(kMinPoints) +
                           " returns within [min_range, max_range]: no poses, no map");
    }
    if (!d.c.odom_channel.empty() && d.odometry == 0) {
      c.warnings.push_back("slam3d: no odometry (driftlab.odometry_t or pose_t) on " + d.c.odom_channel +
                           ": registered without a prior");
    }
  }
  c.metrics = {{"clouds", static_cast<double>(d.clouds)},
               {"unusable", static_cast<double>(d.unusable)},
               {"unconverged", static_cast<double>(d.unconverged)},
               {"rejected", static_cast<double>(d.rejected)},
               {"keyframes", static_cast<double>(d.keyframes)},
               {"map_points", static_cast<double>(d.map->size())},
               {"mean_fitness_m2", d.registered > 0 ? d.fitness_sum / static_cast<double>(d.registered) : 0.0},
               {"max_fitness_m2", d.fitness_max}};
  return c;
}

Result<std::unique_ptr<Module>> make_slam3d(const YAML::Node& config, const std::string& origin) {
  auto c = parse_slam3d_config(config, origin);
  if (!c) return c.error();
  return std::unique_ptr<Module>(std::make_unique<Slam3d>(std::move(*c)));
}

}  // namespace driftlab::slam
