#include "slam/slam2d.h"

#include <dlfcn.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose3DPDF.h>

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>

#include "core/config.h"
#include "core/install_layout.h"
#include "core/number_text.h"
#include "core/text_file.h"
#include "core/time.h"
#include "driftlab/image_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/loop_closure_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/planar.h"
#include "runtime/module_input.h"
#include "slam/internal/icp_slam.h"
#include "slam/internal/mrpt_scan.h"
#include "slam/internal/no_return.h"
#include "slam/internal/odometry_buffer.h"
#include "slam/internal/point_maps.h"
#include "slam/internal/scan_graph.h"

namespace driftlab::slam {
namespace {

/// The largest occupancy map drawn at the end [cells]: 100 MB, 500 m x 500 m at 5 cm.
constexpr double kMaxMapCells = 1e8;

/// v in the fewest digits that read back as exactly v (std::to_chars): a map origin at 1234.567 m is not 1234.57.
std::string exact(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

/// An MRPT icp-slam configuration from ours: [MappingApplication] (map building, a single planar point map, as in
/// icp-slam_demo_classic.ini) and [ICP]. With an .ini file, its values replace the defaults, and the keys given
/// in YAML replace those.
std::string ini_text(const Slam2dConfig& c, const std::set<std::string>& given, const std::string& base) {
  std::ostringstream s;
  auto put = [&](const char* ours, const char* key, double value) {
    if (base.empty() || given.count(ours)) s << key << "=" << value << "\n";
  };
  s << "[MappingApplication]\n";
  if (base.empty()) {
    s << "matchAgainstTheGrid=0\noccupancyGrid_count=0\ngasGrid_count=0\nlandmarksMap_count=0\nbeaconMap_count=0\n"
         "pointsMap_count=1\nlikelihoodMapSelection=-1\n";
  }
  put("insertion_lin_distance", "insertionLinDistance", c.insertion_lin_distance);
  put("insertion_ang_distance", "insertionAngDistance", c.insertion_ang_distance);
  put("localization_lin_distance", "localizationLinDistance", c.localization_lin_distance);
  put("localization_ang_distance", "localizationAngDistance", c.localization_ang_distance);
  put("min_icp_goodness", "minICPgoodnessToAccept", c.min_icp_goodness);
  s << "[MappingApplication_pointsMap_00_insertOpts]\n";
  put("min_dist_between_points", "minDistBetweenLaserPoints", c.min_dist_between_points);
  if (base.empty() || given.count("fuse_points")) s << "fuseWithExisting=" << (c.fuse_points ? "true" : "false") << "\n";
  if (base.empty()) s << "isPlanarMap=1\n";
  s << "[ICP]\n";
  put("max_iterations", "maxIterations", c.max_iterations);
  put("threshold_dist", "thresholdDist", c.threshold_dist);
  put("threshold_ang", "thresholdAng_DEG", c.threshold_ang);
  put("alfa", "ALFA", c.alfa);
  put("smallest_threshold_dist", "smallestThresholdDist", c.smallest_threshold_dist);
  put("decimation", "corresponding_points_decimation", c.decimation);
  if (base.empty()) {
    s << "minAbsStep_trans=1e-6\nminAbsStep_rot=1e-6\nonlyClosestCorrespondences=true\nonlyUniqueRobust=true\n"
         "ICP_algorithm=icpClassic\n";
  }
  return s.str();
}

}  // namespace

Result<Slam2dConfig> parse_slam2d_config(const YAML::Node& node, const std::string& origin) {
  return slam2d_config_table().parse(config::Value(node, origin, "slam.2d"));
}

struct Slam2d::Impl {
  Slam2dConfig c;
  std::unique_ptr<internal::ScanGraph> graph;  ///< method graph
  std::unique_ptr<internal::IcpSlamBuilder> builder;  ///< method icp-slam
  mrpt::obs::CActionRobotMovement2D::TMotionModelOptions motion;
  std::map<std::string, mrpt::poses::CPose2D> sensor_on_base;  ///< by scan frame, from TF_STATIC
  internal::OdometryBuffer odom;
  std::optional<mrpt::poses::CPose2D> last_odom_at_scan;
  int64_t scans = 0, odometry = 0, undecodable = 0, seq = 0, keyframes = 0, before_odometry = 0, loop_seq = 0;
  int64_t first_scan = -1;  ///< stamp of the first scan [us]
  int64_t first_odometry = std::numeric_limits<int64_t>::max();  ///< the earliest odometry stamp [us]
  NonFiniteInputs non_finite;
  internal::NoReturnCode no_return;  ///< found in the readings when max_range is 0
  int64_t found_after = 0;           ///< the scans it took
  bool tf_missing_warned = false;
  std::vector<std::string> warnings;
  // Method graph: scans wait, in stamp order, for the odometry at their stamps (odom_wait_s).
  std::multimap<int64_t, mrpt::obs::CObservation2DRangeScan::Ptr> waiting;
  /// Method graph: the first scans that came before their frame's mounting on TF_STATIC, with the sensor_pose
  /// they took. They wait for it as for the odometry: a bag sorted by stamp may hold the first scan before
  /// /tf_static of the same stamp (ricoslam's sorted bag of the Freiburg clinic), and that scan on the robot's centre
  /// put the laser 0.22 m off on the map's first keyframe. Once a scan has waited out, scans no longer wait.
  struct Unmounted {
    std::string frame;
    mrpt::poses::CPose2D fallback;
  };
  std::map<const mrpt::obs::CObservation2DRangeScan*, Unmounted> unmounted;
  bool mount_waited_out = false;
  int64_t newest_odometry = std::numeric_limits<int64_t>::min(), newest_scan = std::numeric_limits<int64_t>::min();
  int64_t waited_out = 0;  ///< scans matched before their odometry arrived (the wait ran out)
  /// How far back in stamps a scan, and an odometry message, has arrived after a newer one of its kind, at most
  /// odom_wait_s [us]: a log written in arrival order is not in stamp order (Intel's bag: scans and odometry step
  /// back up to 0.9 s; a CARMEN log's laser lines, in the logger's order with the odometry on each). Scans wait
  /// this long (in scan stamps) for the scans before them, and for the odometry around their stamps to be final
  /// (`OdometryBuffer::settled`), so that they are matched in stamp order and predicted from the odometry the log
  /// sorted by stamp gives, once it has shown how late its messages come. In order, nothing waits for them.
  int64_t reorder = 0, odom_reorder = 0;
  int64_t odometry_of_sensor = 0;  ///< odometry messages that gave a sensor's pose, turned into the robot's
  // match_odometry auto: two graphs match each scan, one without the odometry weighed in (`graph`) and one with it
  // (`weighed_graph`), until kDecideChecks scans have been checked against the odometry; then the weighed one goes
  // on if the odometry's heading agrees with the matches (odometry_heading_q90, from the graph without it, at most
  // kAutoAgrees), else the other. Meanwhile the poses published are the other's (where it goes on, the run is the
  // one match_odometry false gives, in every message), and the loop records wait in both graphs; only the chosen
  // one's are published. Where the weighed one goes on, the poses published jump to it, as a loop closure moves
  // them, and from then on they, the trajectory, the loop records and the map are the ones true gives.
  static constexpr size_t kDecideChecks = 600;
  static constexpr int64_t kDecideScans = 3 * static_cast<int64_t>(kDecideChecks);  ///< no checks by then: off
  static constexpr double kAutoAgrees = 2.2;
  std::unique_ptr<internal::ScanGraph> weighed_graph;  ///< auto, until decided
  std::optional<bool> auto_on;                         ///< auto: what was decided
  std::optional<double> auto_q90;  ///< auto: odometry_heading_q90 when it was decided (with the checks in)

  /// match_odometry auto: decides once the checks are in (or the scans are, or the log ends: off).
  void decide(bool at_end) {
    const size_t checks = graph->odometry_heading_checks();
    if (!at_end && checks < kDecideChecks && graph->stats().scans < kDecideScans) return;
    if (checks >= kDecideChecks) auto_q90 = graph->odometry_heading_q90();
    auto_on = auto_q90 && *auto_q90 <= kAutoAgrees;
    if (*auto_on) graph = std::move(weighed_graph);
    weighed_graph.reset();
    keyframes = graph->stats().keyframes;
  }
  /// Whether the odometry was weighed into the matches.
  bool weighed() const { return c.match_odometry == "true" || auto_on.value_or(false); }

  /// Whether a scan stamp is within the first second of the first scan's (or before it).
  bool in_first_second(int64_t stamp) const { return stamp < first_scan || us_after(first_scan, stamp) < 1000000; }

  /// Matches one scan (method graph) and publishes its pose.
  void process(Bus& bus, int64_t stamp, const mrpt::obs::CObservation2DRangeScan::Ptr& obs) {
    if (!c.odom_channel.empty() && (odom.empty() || stamp < first_odometry) && in_first_second(stamp)) {
      --scans;  // before the odometry, in the first second: left out (the map starts where the odometry does)
      ++before_odometry;
      return;
    }
    driftlab::pose_t p{};
    p.header.seq = seq++;
    p.header.utime = stamp;
    p.header.frame_id = "map";
    p.child_frame_id = c.base_frame;
    std::optional<mrpt::poses::CPose2D> odometry;
    if (auto at = odom.at(stamp)) odometry = mrpt::poses::CPose2D(at->x, at->y, at->yaw);
    mrpt::math::CMatrixDouble33 cov;
    const mrpt::poses::CPose2D pose = graph->add(stamp, obs, odometry, &cov);
    keyframes = graph->stats().keyframes;
    if (weighed_graph) {
      weighed_graph->add(stamp, obs, odometry, nullptr);
      decide(false);
    }
    p.position = {pose.x(), pose.y(), 0};
    p.orientation = yaw_quaternion(pose.phi());
    const int ours[3] = {0, 1, 5};  // x, y, yaw in our x, y, z, roll, pitch, yaw
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) p.covariance[ours[i] * 6 + ours[j]] = cov(i, j);
    }
    bus.publish_message(c.pose_channel, p);
    if (!weighed_graph) publish_loops(bus);
  }

  /// The loop tests decided since the last call, on loops_channel.
  void publish_loops(Bus& bus) {
    const auto& keyframes = graph->keyframes();
    for (const auto& r : graph->take_loop_records()) {
      if (c.loops_channel.empty()) continue;
      driftlab::loop_closure_t m{};
      m.header.seq = loop_seq++;
      m.header.utime = keyframes[r.keyframe].stamp;
      m.header.frame_id = "map";
      m.old_utime = keyframes[r.old_keyframe].stamp;
      m.keyframe = static_cast<int32_t>(r.keyframe);
      m.old_keyframe = static_cast<int32_t>(r.old_keyframe);
      m.search = r.rescued ? "near-far" : r.far ? "far" : "near";
      m.radius_m = r.radius;
      m.outcome = internal::outcome_name(r.outcome);
      m.reason = r.reason;
      m.correction[0] = r.correction.x(), m.correction[1] = r.correction.y(), m.correction[2] = r.correction.phi();
      m.measured[0] = r.measured.x(), m.measured[1] = r.measured.y(), m.measured[2] = r.measured.phi();
      m.overlap = r.overlap;
      m.pairs = static_cast<int32_t>(std::min<int64_t>(r.pairs, std::numeric_limits<int32_t>::max()));
      m.chi2 = r.chi2;
      bus.publish_message(c.loops_channel, m);
    }
  }

  /// Puts a scan that came before its frame's mounting where TF_STATIC has put that frame since, or says that it
  /// stays at sensor_pose.
  void mount(mrpt::obs::CObservation2DRangeScan& obs, const Unmounted& u) {
    const auto it = sensor_on_base.find(u.frame);
    if (it == sensor_on_base.end()) {
      mount_waited_out = true;
      warn_unmounted(u.frame, "within odom_wait_s of its first scan");
      return;
    }
    const mrpt::poses::CPose2D& m = it->second;  // the yaw keeps the scan's centre angle to_mrpt added
    obs.sensorPose = mrpt::poses::CPose3D(m.x(), m.y(), 0, obs.sensorPose.yaw() - u.fallback.phi() + m.phi(), 0, 0);
  }

  void warn_unmounted(const std::string& frame, const std::string& when) {
    if (tf_missing_warned) return;
    tf_missing_warned = true;
    warnings.push_back("slam: no " + c.base_frame + " -> " + frame + " on " + c.tf_static_channel + " " + when +
                       ": the sensor_pose setting was used");
  }

  /// Widens `late` to how far back in stamps `stamp` came after `newest`, at most odom_wait_s.
  void widen(int64_t& late, int64_t stamp, int64_t newest) const {
    if (stamp >= newest) return;
    const auto wait = static_cast<uint64_t>(Duration::from_seconds_truncated(c.odom_wait_s).us());
    late = std::max(late, static_cast<int64_t>(std::min(us_after(stamp, newest), wait)));
  }

  /// Matches the waiting scans the odometry has caught up with, and those that waited odom_wait_s (by the scans'
  /// stamps) or, with `all`, every one.
  void drain(Bus& bus, bool all = false) {
    const int64_t wait = Duration::from_seconds_truncated(c.odom_wait_s).us();
    while (!waiting.empty()) {
      const auto it = waiting.begin();
      // the odometry past its stamp; and around it final (none of it still to come), or the log at its end
      const bool past = c.odom_channel.empty() || it->first <= newest_odometry;
      const bool covered =
          c.odom_channel.empty() ||
          (past && (all || odom.settled(it->first, newest_odometry, static_cast<uint64_t>(odom_reorder))));
      // newest_scan is the largest stamp waiting or gone; unsigned, as hostile stamps may be far apart
      const uint64_t behind = us_after(it->first, newest_scan);
      const bool in_order = behind >= static_cast<uint64_t>(reorder);
      const auto un = unmounted.find(it->second.get());
      const bool mounted = un == unmounted.end() || sensor_on_base.contains(un->second.frame);
      if (!all && (((!covered || !mounted) && behind < static_cast<uint64_t>(wait)) || !in_order)) break;
      if (!past) ++waited_out;  // predicted from the odometry before it (a sample late around it: not counted)
      if (un != unmounted.end()) {
        mount(*it->second, un->second);
        unmounted.erase(un);
      }
      process(bus, it->first, it->second);
      waiting.erase(it);
    }
  }
};

Slam2d::Slam2d(Slam2dConfig config) : impl_(std::make_unique<Impl>()) { impl_->c = std::move(config); }
Slam2d::~Slam2d() = default;

Status Slam2d::start(Bus& bus) {
  Impl& d = *impl_;
  const Slam2dConfig& c = d.c;
  try {
    std::string base;
    if (!c.ini.empty()) {
      std::ifstream in(c.ini);
      std::stringstream text;
      text << in.rdbuf();
      base = text.str();
    }
    mrpt::config::CConfigFileMemory cfg(base.empty() ? ini_text(c, c.given, "") : base);
    if (!base.empty()) {  // the YAML keys given override the .ini file's
      mrpt::config::CConfigFileMemory overrides(ini_text(c, c.given, base));
      for (const char* section : {"MappingApplication", "MappingApplication_pointsMap_00_insertOpts", "ICP"}) {
        std::vector<std::string> keys;
        overrides.getAllKeys(section, keys);
        for (const auto& k : keys) cfg.write(section, k, overrides.read_string(section, k, ""));
      }
    }
    if (c.method == "graph") {
      internal::ScanGraphOptions o;
      o.icp.load(cfg, "ICP");
      o.min_icp_goodness = c.min_icp_goodness;
      o.min_dist_between_points = c.min_dist_between_points;
      o.keyframe_distance = c.keyframe_distance;
      o.keyframe_angle = c.keyframe_angle * M_PI / 180;
      o.local_map_keyframes = c.local_map_keyframes;
      o.loop_closure = c.loop_closure;
      o.loop_min_travel = c.loop_min_travel;
      o.loop_radius = c.loop_radius;
      o.loop_drift = c.loop_drift;
      o.loop_max_radius = c.loop_max_radius;
      o.loop_min_goodness = c.loop_min_goodness;
      o.loop_rescue_near = c.loop_rescue_near;
      o.loop_seen_only = c.loop_seen_only;
      o.match_odometry = c.match_odometry == "true";
      o.match_sigma = c.match_sigma;
      o.odometry_noise = c.odometry_noise;
      d.graph = std::make_unique<internal::ScanGraph>(o);
      if (c.match_odometry == "auto") {
        o.match_odometry = true;
        d.weighed_graph = std::make_unique<internal::ScanGraph>(o);
      }
    } else {
      const auto factory = internal::icp_slam_factory();
      if (!factory) return factory.error();
      d.builder.reset(factory.value()(&cfg));
    }
  } catch (const std::exception& e) {
    return Error{(c.ini.empty() ? std::string("slam.2d") : c.ini) + ": bad ICP settings: " + one_line(e.what())};
  }

  if (!c.tf_static_channel.empty()) {
    bus.subscribe(c.tf_static_channel, [this](const BusMessage& m) {
      driftlab::tf_t tf;
      if (!decode_message(m, tf)) return void(++impl_->undecodable);
      if (!impl_->non_finite.finite(m)) return;
      for (const auto& t : tf.transforms) {
        if (t.header.frame_id != impl_->c.base_frame) continue;
        const double yaw = yaw_of(t.rotation);  // NaN for a quaternion of huge numbers
        if (!std::isfinite(yaw)) return impl_->non_finite.count(m.channel, "the yaw of " + t.child_frame_id + " = nan");
        auto& in = impl_->non_finite;
        if (!in.plausible(m.channel, "translation.x", t.translation.x) ||
            !in.plausible(m.channel, "translation.y", t.translation.y)) {
          return;
        }
        impl_->sensor_on_base[t.child_frame_id] = mrpt::poses::CPose2D(t.translation.x, t.translation.y, yaw);
      }
    });
  }
  if (!c.odom_channel.empty()) {
    bus.subscribe(c.odom_channel, [this, &bus](const BusMessage& m) {
      std::string frame;
      const auto o = internal::planar_odometry(m, impl_->non_finite, &impl_->undecodable, &frame);
      if (!o) return;
      ++impl_->odometry;
      // The pose of a sensor mounted on the robot (a CARMEN laser line's laser pose, its mounting on TF_STATIC):
      // the robot's is that pose with the mounting taken off. Taken as the robot's, a turn on the spot would read
      // as the robot driving the mounting's arc.
      Pose2 pose = o->second;
      const auto mount = impl_->sensor_on_base.find(frame);
      if (frame != impl_->c.base_frame && mount != impl_->sensor_on_base.end() &&
          !(mount->second.x() == 0 && mount->second.y() == 0 && mount->second.phi() == 0)) {
        mrpt::poses::CPose2D off = mount->second;  // sensor = robot (+) mounting, so robot = sensor (+) mounting^-1
        off.inverse();
        const mrpt::poses::CPose2D robot = mrpt::poses::CPose2D(pose.x, pose.y, pose.yaw) + off;
        pose = Pose2{robot.x(), robot.y(), robot.phi()};
        ++impl_->odometry_of_sensor;
      }
      impl_->odom.add(o->first, pose);
      impl_->first_odometry = std::min(impl_->first_odometry, o->first);
      if (impl_->graph) {
        impl_->widen(impl_->odom_reorder, o->first, impl_->newest_odometry);
        impl_->newest_odometry = std::max(impl_->newest_odometry, o->first);
        impl_->drain(bus);
      }
    });
  }
  bus.subscribe(c.scan_channel, [this, &bus](const BusMessage& m) {
    Impl& d = *impl_;
    driftlab::laser_scan_t scan;
    if (!decode_message(m, scan) || scan.nranges < 2) return void(++d.undecodable);
    // A scan whose geometry is NaN or infinite cannot be placed (MRPT's grid asserts on it): left out, counted.
    if (!d.non_finite.finite(m)) return;
    if (!std::isfinite(scan.angle_increment * static_cast<float>(scan.nranges - 1))) {
      return d.non_finite.count(m.channel, "angle_increment * (nranges - 1) = inf");
    }
    // With odometry configured, the map starts where the odometry does (as icp-slam starts at its first
    // odometry/scan pair): scans in the first second before any odometry are counted and left out.
    if (d.first_scan < 0) d.first_scan = scan.header.utime;
    // (Method graph: the scan waits for the odometry at its stamp like any other, and process() decides: a pose
    // that rides on its scan, as a CARMEN log's laser lines carry theirs, comes just after it.)
    if (!d.graph && !d.c.odom_channel.empty() && d.odom.empty() && d.in_first_second(scan.header.utime)) {
      ++d.before_odometry;
      return;
    }
    ++d.scans;
    mrpt::poses::CPose2D sensor(d.c.sensor_pose[0], d.c.sensor_pose[1], d.c.sensor_pose[2]);
    const auto mount = d.sensor_on_base.find(scan.header.frame_id);
    const bool unmounted = mount == d.sensor_on_base.end() && !d.c.tf_static_channel.empty();
    if (mount != d.sensor_on_base.end()) {
      sensor = mount->second;
    } else if (unmounted && (!d.graph || d.mount_waited_out)) {
      d.warn_unmounted(scan.header.frame_id, "before the first scan");
    }
    float no_return_from = INFINITY;
    if (d.c.max_range > 0) {
      no_return_from = static_cast<float>(d.c.max_range);
    } else {
      if (!d.no_return.from()) {
        d.no_return.observe(scan.ranges, scan.range_min, scan.range_max);
        if (d.no_return.from()) d.found_after = d.scans;
      }
      no_return_from = d.no_return.from().value_or(INFINITY);
    }
    auto obs = internal::to_mrpt(scan, sensor, no_return_from);
    obs->sensorLabel = m.channel;

    if (d.graph) {
      if (unmounted && !d.mount_waited_out) d.unmounted[obs.get()] = {scan.header.frame_id, sensor};
      d.waiting.emplace(scan.header.utime, obs);
      d.widen(d.reorder, scan.header.utime, d.newest_scan);
      d.newest_scan = std::max(d.newest_scan, scan.header.utime);
      d.drain(bus);
      return;
    }
    driftlab::pose_t p{};
    p.header.seq = d.seq++;
    p.header.utime = scan.header.utime;
    p.header.frame_id = "map";
    p.child_frame_id = d.c.base_frame;
    mrpt::obs::CActionCollection actions;
    if (auto at = d.odom.at(scan.header.utime)) {
      const mrpt::poses::CPose2D now(at->x, at->y, at->yaw);
      if (d.last_odom_at_scan) {
        mrpt::obs::CActionRobotMovement2D act;
        act.computeFromOdometry(now - *d.last_odom_at_scan, d.motion);
        act.timestamp = obs->timestamp;
        actions.insert(act);
      }
      d.last_odom_at_scan = now;
    }
    mrpt::obs::CSensoryFrame frame;
    frame.insert(obs);
    d.keyframes = static_cast<int64_t>(d.builder->process(actions, frame));

    mrpt::math::CMatrixDouble66 cov;
    mrpt::poses::CPose3D mean;
    d.builder->estimate(cov, mean);
    p.position = {mean.x(), mean.y(), 0};
    p.orientation = yaw_quaternion(mean.yaw());
    // MRPT orders (x, y, z, yaw, pitch, roll); ours (x, y, z, roll, pitch, yaw).
    const int ours[6] = {0, 1, 2, 5, 4, 3};
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) p.covariance[ours[i] * 6 + ours[j]] = cov(i, j);
    }
    bus.publish_message(d.c.pose_channel, p);
  });
  return {};
}

void Slam2d::finish(Bus& bus) {
  Impl& d = *impl_;
  if (d.graph) d.drain(bus, true);
  if (d.scans == 0) return;
  // The keyframes' scans where the map places them (the graph's as last optimised).
  std::vector<std::pair<mrpt::obs::CObservation2DRangeScan::Ptr, mrpt::poses::CPose3D>> placed;
  if (d.graph) {
    if (d.weighed_graph) d.decide(true);
    d.graph->finish();
    d.publish_loops(bus);
    // The trajectory as last optimised: a pose per scan, published now with the scans' stamps.
    int64_t seq = 0;
    if (!d.c.trajectory_channel.empty()) {
      for (const auto& [stamp, pose] : d.graph->trajectory()) {
        driftlab::pose_t p{};
        p.header.seq = seq++;
        p.header.utime = stamp;
        p.header.frame_id = "map";
        p.child_frame_id = d.c.base_frame;
        p.position = {pose.x(), pose.y(), 0};
        p.orientation = yaw_quaternion(pose.phi());
        bus.publish_message(d.c.trajectory_channel, p);
      }
    }
    const auto& keyframes = d.graph->keyframes();
    for (size_t i = 0; i < keyframes.size(); ++i) {
      placed.emplace_back(keyframes[i].scan, mrpt::poses::CPose3D(d.graph->keyframe_pose(i)));
    }
  } else {
    mrpt::maps::CSimpleMap keyframes;
    d.builder->keyframes(keyframes);
    for (size_t i = 0; i < keyframes.size(); ++i) {
      mrpt::poses::CPose3DPDF::Ptr pose;
      mrpt::obs::CSensoryFrame::Ptr frame;
      keyframes.get(i, pose, frame);
      for (const auto& obs : *frame) {
        if (auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(obs)) {
          placed.emplace_back(scan, pose->getMeanVal());
        }
      }
    }
  }
  // MRPT grows the grid to every scan it inserts, to at most maxDistanceInsertion around the sensor. Scans placed
  // absurdly far apart (a scanner 1e15 m from the base in a hostile log), or a tiny map_resolution, would ask it for
  // more cells than memory holds, or than an int counts: past kMaxMapCells the map is not drawn, and the warning
  // says how to draw it.
  double x0 = -10, x1 = 10, y0 = -10, y1 = 10;
  const double reach = mrpt::maps::COccupancyGridMap2D::TInsertionOptions().maxDistanceInsertion;
  for (const auto& [scan, pose] : placed) {
    const mrpt::poses::CPose3D at = pose + scan->sensorPose;
    x0 = std::min(x0, at.x() - reach), x1 = std::max(x1, at.x() + reach);
    y0 = std::min(y0, at.y() - reach), y1 = std::max(y1, at.y() + reach);
  }
  const double cells = (x1 - x0) / d.c.map_resolution * ((y1 - y0) / d.c.map_resolution);
  if (!(cells <= kMaxMapCells)) {
    char what[200];
    std::snprintf(what, sizeof(what),
                  "slam: the map would span %.3g m x %.3g m, %.3g cells at map_resolution %g m: "
                  "not drawn (a coarser map_resolution draws it)",
                  x1 - x0, y1 - y0, cells, d.c.map_resolution);
    d.warnings.push_back(what);
    return;
  }
  mrpt::maps::COccupancyGridMap2D grid(-10, 10, -10, 10, static_cast<float>(d.c.map_resolution));
  for (const auto& [scan, pose] : placed) {
    // MRPT 2.5 grows the grid to a scan's points but ray-traces from the sensor's cell: a sensor outside the grid
    // (a scanner mounted metres off the base, beams ending inside the map) reads outside it. The grid is grown to
    // the sensor first (found by the modules fuzzer).
    const mrpt::poses::CPose3D at = pose + scan->sensorPose;
    const auto x = static_cast<float>(at.x()), y = static_cast<float>(at.y());
    if (x <= grid.getXMin() || x >= grid.getXMax() || y <= grid.getYMin() || y >= grid.getYMax()) {
      grid.resizeGrid(std::min(grid.getXMin(), x - 1), std::max(grid.getXMax(), x + 1), std::min(grid.getYMin(), y - 1),
                      std::max(grid.getYMax(), y + 1));
    }
    grid.insertObservation(*scan, pose);
  }
  // Free space white, obstacles black, unknown grey; north up.
  const int w = static_cast<int>(grid.getSizeX()), h = static_cast<int>(grid.getSizeY());
  cv::Mat img(h, w, CV_8UC1);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) img.at<uint8_t>(h - 1 - y, x) = static_cast<uint8_t>(std::lround(grid.getCell(x, y) * 255));
  }
  std::vector<uint8_t> png;
  if (!cv::imencode(".png", img, png)) png.clear();
  driftlab::image_t m{};
  m.header.utime = bus.now().us();
  m.header.frame_id = "map";
  m.width = w;
  m.height = h;
  m.encoding = "png";
  m.data = png;
  m.size = static_cast<int32_t>(png.size());
  bus.publish_message(d.c.map_channel, m);
  const std::string prefix = bus.artifact_prefix();
  if (!prefix.empty()) {
    // The image first: a description of a map whose image could not be written would describe nothing (or an
    // older image). The origin is the grid's own number (a float), written whole, not to 6 digits.
    const std::string image = prefix + "-map.png";
    if (png.empty()) {
      d.warnings.push_back("slam: cannot write " + image + ": the PNG encoder failed");
      return;
    }
    if (Status s = write_file_atomically(image, {reinterpret_cast<const char*>(png.data()), png.size()}); !s) {
      d.warnings.push_back("slam: " + s.message());
      return;
    }
    const std::string yaml = "image: " + image.substr(image.rfind('/') + 1) +
                             "\nresolution: " + exact(d.c.map_resolution) + "\norigin: [" + exact(grid.getXMin()) +
                             ", " + exact(grid.getYMin()) +
                             ", 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
    if (Status s = write_file_atomically(prefix + "-map.yaml", yaml); !s) d.warnings.push_back("slam: " + s.message());
  }
}

ModuleCounters Slam2d::counters() const {
  const Impl& d = *impl_;
  ModuleCounters c;
  c.dropped = d.undecodable + d.non_finite.dropped();
  c.warnings = d.warnings;
  if (auto w = d.non_finite.warning("slam")) c.warnings.push_back(*w);
  if (auto from = d.no_return.from()) {
    c.warnings.push_back(
        "slam: readings on " + d.c.scan_channel + " at " + short_number(std::round(*from * 100) / 100) +
        " m or more are the scanner's no-return code, not echoes (" + thousands(d.no_return.pile()) +
        " of them by scan " + thousands(d.found_after) + "): left out; set slam.2d.max_range to choose");
  }
  if (d.scans == 0) {
    c.warnings.push_back("slam: no driftlab.laser_scan_t on " + d.c.scan_channel + ": no map built");
  } else if (!d.c.odom_channel.empty() && d.odometry == 0) {
    c.warnings.push_back("slam: no odometry (driftlab.odometry_t or pose_t) on " + d.c.odom_channel +
                         ": scans matched without a prior");
  }
  c.metrics = {{"scans", static_cast<double>(d.scans)},
               {"scans_before_odometry", static_cast<double>(d.before_odometry)},
               {"keyframes", static_cast<double>(d.keyframes)}};
  if (d.graph) {
    const auto& s = d.graph->stats();
    c.metrics.insert(c.metrics.end(), {{"unmatched", static_cast<double>(s.unmatched)},
                                       {"scans_still", static_cast<double>(s.still)},
                                       {"scans_waited_out", static_cast<double>(d.waited_out)},
                                       {"loop_tests", static_cast<double>(s.loop_tests)},
                                       {"loop_closures", static_cast<double>(s.loop_closures)},
                                       {"loop_rejected_goodness", static_cast<double>(s.loop_rejected_goodness)},
                                       {"loop_rejected_unique", static_cast<double>(s.loop_rejected_unique)},
                                       {"loop_rejected_chi2", static_cast<double>(s.loop_rejected_chi2)},
                                       {"loop_undone", static_cast<double>(s.loop_undone)},
                                       {"loop_unconfirmed", static_cast<double>(s.loop_unconfirmed)},
                                       {"optimisations", static_cast<double>(s.optimisations)}});
    if (d.auto_on) c.metrics.emplace_back("match_odometry_auto", *d.auto_on ? 1.0 : 0.0);
    if (d.auto_q90) c.metrics.emplace_back("match_odometry_auto_q90", *d.auto_q90);
    if (d.weighed()) c.metrics.emplace_back("scans_weighed", static_cast<double>(s.weighed));
    if (d.odometry_of_sensor > 0) {
      c.metrics.emplace_back("odometry_of_sensor", static_cast<double>(d.odometry_of_sensor));
    }
    c.metrics.emplace_back("odometry_heading_checks", static_cast<double>(d.graph->odometry_heading_checks()));
    if (const auto q90 = d.graph->odometry_heading_q90()) {
      c.metrics.emplace_back("odometry_heading_q90", *q90);
      // Whether weighing the odometry into each match (match_odometry) suits this log: a true noise model gives
      // 1.645; of the benchmark logs, the one it holds (the Freiburg clinic) 1.4-1.8, the four it folds and
      // ACES 2.8-8.2 over the whole log (docs/slam.md, "Odometry in the match"). With it off the figure is only a
      // metric: good odometry (the simulator's gives 0.7) is nothing to warn of.
      constexpr double kAgrees = 2.0;
      if (d.weighed() && *q90 > kAgrees) {
        c.warnings.push_back(
            "slam: the odometry's heading disagrees with the scan matches beyond its noise model (90% within " +
            short_number(std::round(*q90 * 100) / 100) + " of its standard deviations, over " +
            thousands(static_cast<int64_t>(d.graph->odometry_heading_checks())) +
            " matches; at most 2 where it holds): slam.2d.match_odometry weighs it into each match and may bend the "
            "map; compare a run with it false (docs/slam.md)");
      }
    }
  }
  return c;
}

namespace internal {

Result<IcpSlamFactory> icp_slam_factory() {
  static const Result<IcpSlamFactory> loaded = []() -> Result<IcpSlamFactory> {
    const auto path = sibling_library(kIcpSlamLibrary);
    if (path.empty()) {
      return Error{std::string("slam.2d method icp-slam: ") + kIcpSlamLibrary + " is not beside " +
                   self_executable().string() + " nor in its install tree's lib/driftlab (a partial install?)"};
    }
    void* library = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);  // kept for the process's life
    void* factory = library == nullptr ? nullptr : dlsym(library, kIcpSlamFactory);
    if (factory == nullptr) {
      const char* error = dlerror();  // names the file, when the file is what is wrong
      const std::string why = error != nullptr ? one_line(error) : std::string("no ") + kIcpSlamFactory + " in it";
      return Error{why.rfind(path.string(), 0) == 0 ? why : path.string() + ": " + why};
    }
    return reinterpret_cast<IcpSlamFactory>(factory);
  }();
  return loaded;
}

}  // namespace internal
}  // namespace driftlab::slam
