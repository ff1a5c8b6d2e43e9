#include "slam/slam3d.h"

#include <pcl/common/transforms.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>
#include <pcl/registration/ndt.h>

#include <Eigen/Geometry>
#include <cmath>
#include <deque>
#include <map>

#include "core/internal/yaml_fields.h"
#include "driftlab/odometry_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "slam/internal/odometry_buffer.h"
#include "lcmtypes/planar.h"

namespace driftlab::slam {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

Eigen::Isometry3d planar(const internal::Pose2d& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translate(Eigen::Vector3d(p.x, p.y, 0));
  t.rotate(Eigen::AngleAxisd(p.yaw, Eigen::Vector3d::UnitZ()));
  return t;
}

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
  Slam3dConfig c;
  if (!node.IsDefined() || node.IsNull()) return c;
  try {
    Fields f(node, origin, "slam.3d");
    DL_TRY(f.is_map());
    DL_TRY(f.text("cloud_channel", c.cloud_channel));
    DL_TRY(f.text("odom_channel", c.odom_channel));
    DL_TRY(f.text("tf_static_channel", c.tf_static_channel));
    DL_TRY(f.text("pose_channel", c.pose_channel));
    DL_TRY(f.text("base_frame", c.base_frame));
    std::vector<double> pose;
    DL_TRY(f.vector("sensor_pose", pose, 4));
    if (!pose.empty()) c.sensor_pose = {pose[0], pose[1], pose[2], pose[3]};
    DL_TRY(f.text("method", c.method));
    if (c.method != "icp" && c.method != "ndt" && c.method != "gicp") {
      return Error{f.where("method") + " = " + c.method + " must be icp, ndt or gicp"};
    }
    DL_TRY(f.number("min_range", c.min_range, 0, 1e6));
    DL_TRY(f.positive("max_range", c.max_range));
    DL_TRY(f.positive("voxel", c.voxel));
    DL_TRY(f.positive("max_correspondence", c.max_correspondence));
    DL_TRY(f.positive("ndt_resolution", c.ndt_resolution));
    DL_TRY(f.positive("ndt_step", c.ndt_step));
    DL_TRY(f.integer("max_iterations", c.max_iterations, 1, 10000));
    DL_TRY(f.positive("keyframe_distance", c.keyframe_distance));
    DL_TRY(f.positive("keyframe_angle", c.keyframe_angle));
    DL_TRY(f.integer("local_map_keyframes", c.local_map_keyframes, 1, 10000));
    DL_TRY(f.positive("map_voxel", c.map_voxel));
    DL_TRY(f.finish("cloud_channel, odom_channel, tf_static_channel, pose_channel, base_frame, sensor_pose, method, "
                    "min_range, max_range, voxel, max_correspondence, ndt_resolution, ndt_step, max_iterations, "
                    "keyframe_distance, keyframe_angle, local_map_keyframes, map_voxel"));
    if (c.cloud_channel.empty()) return Error{f.where("cloud_channel") + " must not be empty"};
  } catch (const YAML::Exception& e) {
    return Error{origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
  }
  return c;
}

struct Slam3d::Impl {
  Slam3dConfig c;
  std::unique_ptr<pcl::Registration<pcl::PointXYZ, pcl::PointXYZ>> reg;
  std::map<std::string, Eigen::Isometry3d> sensor_on_base;  ///< by cloud frame, from TF_STATIC
  internal::OdometryBuffer odom;
  bool have_pose = false;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();          ///< base in map, at the last cloud
  Eigen::Isometry3d last_motion = Eigen::Isometry3d::Identity();   ///< between the last two clouds
  std::optional<internal::Pose2d> odom_at_last;
  Eigen::Isometry3d last_keyframe = Eigen::Isometry3d::Identity();
  std::deque<Cloud::Ptr> local;       ///< recent keyframes in the map frame
  std::vector<Cloud::Ptr> keyframes;  ///< every keyframe in the map frame (for the final map)
  int64_t clouds = 0, unconverged = 0, undecodable = 0, odometry = 0, seq = 0;
  double fitness_sum = 0;
  bool tf_missing_warned = false;
  std::vector<std::string> warnings;

  void set_target() {
    auto target = std::make_shared<Cloud>();
    for (const auto& k : local) *target += *k;
    reg->setInputTarget(downsample(target, c.voxel));
  }
};

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
  } else {
    auto ndt = std::make_unique<pcl::NormalDistributionsTransform<pcl::PointXYZ, pcl::PointXYZ>>();
    ndt->setResolution(static_cast<float>(c.ndt_resolution));
    ndt->setStepSize(c.ndt_step);
    d.reg = std::move(ndt);
  }
  d.reg->setMaximumIterations(c.max_iterations);
  d.reg->setTransformationEpsilon(1e-6);

  if (!c.tf_static_channel.empty()) {
    bus.subscribe(c.tf_static_channel, [this](const BusMessage& m) {
      driftlab::tf_t tf;
      if (!decode_message(m, tf)) return void(++impl_->undecodable);
      for (const auto& t : tf.transforms) {
        if (t.header.frame_id != impl_->c.base_frame) continue;
        Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
        x.translate(Eigen::Vector3d(t.translation.x, t.translation.y, t.translation.z));
        x.rotate(Eigen::Quaterniond(t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z).normalized());
        impl_->sensor_on_base[t.child_frame_id] = x;
      }
    });
  }
  if (!c.odom_channel.empty()) {
    bus.subscribe(c.odom_channel, [this](const BusMessage& m) {
      driftlab::odometry_t o;
      if (!decode_message(m, o)) return void(++impl_->undecodable);
      ++impl_->odometry;
      impl_->odom.add(o.header.utime, {o.position.x, o.position.y, yaw_of(o.orientation)});
    });
  }
  bus.subscribe(c.cloud_channel, [this, &bus](const BusMessage& m) {
    Impl& d = *impl_;
    driftlab::point_cloud_t pc;
    if (!decode_message(m, pc)) return void(++d.undecodable);
    ++d.clouds;
    Eigen::Isometry3d sensor = Eigen::Isometry3d::Identity();
    sensor.translate(Eigen::Vector3d(d.c.sensor_pose[0], d.c.sensor_pose[1], d.c.sensor_pose[2]));
    sensor.rotate(Eigen::AngleAxisd(d.c.sensor_pose[3], Eigen::Vector3d::UnitZ()));
    if (auto it = d.sensor_on_base.find(pc.header.frame_id); it != d.sensor_on_base.end()) {
      sensor = it->second;
    } else if (!d.tf_missing_warned && !d.c.tf_static_channel.empty()) {
      d.tf_missing_warned = true;
      d.warnings.push_back("slam: no " + d.c.base_frame + " -> " + pc.header.frame_id + " on " +
                           d.c.tf_static_channel + " before the first cloud: the sensor_pose setting was used");
    }
    // The returns within range, in the base frame.
    auto raw = std::make_shared<Cloud>();
    raw->reserve(pc.x.size());
    const Eigen::Matrix4f to_base = sensor.matrix().cast<float>();
    const double min2 = d.c.min_range * d.c.min_range, max2 = d.c.max_range * d.c.max_range;
    for (size_t i = 0; i < pc.x.size(); ++i) {
      const float x = pc.x[i], y = pc.y[i], z = pc.z[i];
      const double r2 = double(x) * x + double(y) * y + double(z) * z;
      if (!std::isfinite(r2) || r2 < min2 || r2 > max2) continue;
      const Eigen::Vector4f p = to_base * Eigen::Vector4f(x, y, z, 1);
      raw->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
    }
    if (raw->size() < 100) return void(++d.unconverged);
    Cloud::Ptr scan = downsample(raw, d.c.voxel);

    // The prior: the odometry's motion since the last cloud, else the last motion again.
    Eigen::Isometry3d motion = d.last_motion;
    const auto odo = d.odom.at(pc.header.utime);
    if (odo && d.odom_at_last) motion = planar(*d.odom_at_last).inverse() * planar(*odo);
    if (odo) d.odom_at_last = odo;

    if (!d.have_pose) {
      d.have_pose = true;
    } else {
      const Eigen::Isometry3d guess = d.pose * motion;
      d.reg->setInputSource(scan);
      Cloud aligned;
      d.reg->align(aligned, guess.matrix().cast<float>());
      Eigen::Isometry3d found = guess;
      if (d.reg->hasConverged()) {
        found.matrix() = d.reg->getFinalTransformation().cast<double>();
        d.fitness_sum += d.reg->getFitnessScore();
      } else {
        ++d.unconverged;
      }
      d.last_motion = d.pose.inverse() * found;
      d.pose = found;
    }
    // A keyframe after enough motion: it joins the local map (the registration target) and the final map.
    const Eigen::Isometry3d since = d.last_keyframe.inverse() * d.pose;
    const double angle = Eigen::AngleAxisd(since.rotation()).angle() * 180 / M_PI;
    if (d.keyframes.empty() || since.translation().norm() > d.c.keyframe_distance || angle > d.c.keyframe_angle) {
      auto in_map = std::make_shared<Cloud>();
      pcl::transformPointCloud(*scan, *in_map, d.pose.matrix().cast<float>());
      d.keyframes.push_back(in_map);
      d.local.push_back(in_map);
      while (static_cast<int>(d.local.size()) > d.c.local_map_keyframes) d.local.pop_front();
      d.last_keyframe = d.pose;
      d.set_target();
    }
    driftlab::pose_t p{};
    p.header.seq = d.seq++;
    p.header.utime = pc.header.utime;
    p.header.frame_id = "map";
    p.child_frame_id = d.c.base_frame;
    p.position = {d.pose.translation().x(), d.pose.translation().y(), d.pose.translation().z()};
    const Eigen::Quaterniond q(d.pose.rotation());
    p.orientation = {q.w(), q.x(), q.y(), q.z()};
    for (int i = 0; i < 36; ++i) p.covariance[i] = 0;
    bus.publish_message(d.c.pose_channel, p);
  });
  return {};
}

void Slam3d::finish(Bus& bus) {
  Impl& d = *impl_;
  const std::string prefix = bus.artifact_prefix();
  if (d.keyframes.empty() || prefix.empty()) return;
  auto all = std::make_shared<Cloud>();
  for (const auto& k : d.keyframes) *all += *k;
  Cloud::Ptr map = downsample(all, d.c.map_voxel);
  if (pcl::io::savePCDFileBinary(prefix + "-map.pcd", *map) != 0) {
    d.warnings.push_back("slam: cannot write " + prefix + "-map.pcd");
  }
}

ModuleCounters Slam3d::counters() const {
  const Impl& d = *impl_;
  ModuleCounters c;
  c.dropped = d.undecodable + d.unconverged;
  c.warnings = d.warnings;
  if (d.clouds == 0) {
    c.warnings.push_back("slam: no driftlab.point_cloud_t on " + d.c.cloud_channel + ": no map built");
  } else if (!d.c.odom_channel.empty() && d.odometry == 0) {
    c.warnings.push_back("slam: no driftlab.odometry_t on " + d.c.odom_channel + ": registered without a prior");
  }
  const int64_t registered = d.clouds - d.unconverged - (d.have_pose ? 1 : 0);
  c.metrics = {{"clouds", static_cast<double>(d.clouds)},
               {"unconverged", static_cast<double>(d.unconverged)},
               {"keyframes", static_cast<double>(d.keyframes.size())},
               {"mean_fitness_m2", registered > 0 ? d.fitness_sum / static_cast<double>(registered) : 0.0}};
  return c;
}

}  // namespace driftlab::slam
