#include "slam/internal/scan_graph.h"

#include <mrpt/poses/CPosePDFGaussian.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <set>

#include "core/number_text.h"
#include "slam/internal/correlative_matcher.h"

namespace driftlab::slam::internal {

using mrpt::poses::CPose2D;
using mrpt::poses::CPose3D;

namespace {

/// How far beyond an old scan's hit a current point still counts as seen by it (loop_seen_only): the spread of a
/// wall's points over a few scans, and the near test's reach of the estimate's drift (docs/slam.md).
constexpr double kSeenMargin = 0.3;

double angle_of(const CPose2D& p) { return std::abs(mrpt::math::wrapToPi(p.phi())); }
double degrees(double rad) { return rad * 180 / M_PI; }

/// "0.12 m and 1.3 deg": how far a pose moved (no comma: a reason is one CSV field unquoted).
std::string moved(const CPose2D& p) {
  std::string s;
  appendf(s, "%.2f m and %.1f deg", p.norm(), degrees(angle_of(p)));
  return s;
}
PoseGraph2d::Pose array_of(const CPose2D& p) { return {p.x(), p.y(), p.phi()}; }

/// What a match pins down, from its point pairs: each pair constrains the pose along the normal of the old surface
/// at its point (point to line), so H = mean over the pairs of J^T J, J = [n_x, n_y, n . d(point)/d(yaw)], is the
/// information per point about the current pose (x, y, yaw in the map frame) at `pose`. In a corridor every normal
/// points across it, and H's translation block has an eigenvalue near zero along it. At most 200 pairs, evenly
/// spread, are looked at; `lines` receives how many had a clear surface (a line through their 8 nearest old
/// points: spread along it by 2 cm at least, so dense scans (the simulator's 360 beams, several keyframes on top
/// of each other) still show their walls, and ten times less across it).
Eigen::Matrix3d constraint_of(const GridPointsMap& reference, const mrpt::tfest::TMatchingPairList& pairs,
                              const CPose2D& pose, size_t& lines) {
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  lines = 0;
  std::vector<size_t> idx;
  std::vector<float> d2;
  std::vector<Eigen::Vector2d> near;
  const size_t every = std::max<size_t>(1, pairs.size() / 200);
  for (size_t p = 0; p < pairs.size(); p += every) {
    const auto& pair = pairs[p];
    // From the grid the matching built; the kd-tree (built at the first such call) only where the grid cannot
    // tell which points it would give: the same points in the same order either way.
    if (!reference.nearest_k(pair.global.x, pair.global.y, 8, idx)) {
      reference.kdTreeNClosestPoint2DIdx(pair.global.x, pair.global.y, 8, idx, d2);
    }
    if (idx.size() < 4) continue;
    near.clear();
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (size_t i : idx) {
      float x, y;
      reference.getPoint(i, x, y);
      near.emplace_back(x, y);
      mean += near.back();
    }
    mean /= static_cast<double>(near.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& q : near) cov += (q - mean) * (q - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
    if (eig.eigenvalues()(1) < 0.02 * 0.02 * static_cast<double>(near.size()) ||
        eig.eigenvalues()(0) > 0.1 * eig.eigenvalues()(1)) {
      continue;
    }
    const Eigen::Vector2d n = eig.eigenvectors().col(0);
    const Eigen::Vector2d arm(pair.global.x - pose.x(), pair.global.y - pose.y());  // the point seen from the robot
    const Eigen::Vector3d j(n.x(), n.y(), n.y() * arm.x() - n.x() * arm.y());
    h += j * j.transpose();
    ++lines;
  }
  if (lines > 0) h /= static_cast<double>(lines);
  return h;
}

/// Each point of `query` at `pose` paired with its nearest point of `reference` within `distance` (all points
/// looked at); `extra` receives the share of them paired.
mrpt::tfest::TMatchingPairList pairs_within(const mrpt::maps::CSimplePointsMap& reference,
                                            const mrpt::maps::CSimplePointsMap& query, const CPose2D& pose,
                                            double distance, mrpt::maps::TMatchingExtraResults* extra = nullptr) {
  mrpt::maps::TMatchingParams params;
  params.maxDistForCorrespondence = static_cast<float>(distance);
  params.maxAngularDistForCorrespondence = 0;
  params.onlyKeepTheClosest = true;
  params.decimation_other_map_points = 1;
  mrpt::tfest::TMatchingPairList pairs;
  mrpt::maps::TMatchingExtraResults unused;
  reference.determineMatching2D(&query, pose, pairs, params, extra != nullptr ? *extra : unused);
  return pairs;
}

std::vector<Point2f> points_in(const mrpt::maps::CSimplePointsMap& map, size_t at_most) {
  std::vector<Point2f> out;
  const size_t every = std::max<size_t>(1, map.size() / std::max<size_t>(at_most, 1));
  for (size_t i = 0; i < map.size(); i += every) {
    Point2f p;
    map.getPoint(i, p.x, p.y);
    out.push_back(p);
  }
  return out;
}

}  // namespace

mrpt::maps::CSimplePointsMap seen_points(
    const std::vector<std::pair<const mrpt::obs::CObservation2DRangeScan*, CPose2D>>& scans,
    const mrpt::maps::CSimplePointsMap& query, const CPose2D& pose, double margin) {
  const auto& qx = query.getPointsBufferRef_x();
  const auto& qy = query.getPointsBufferRef_y();
  std::vector<double> mx(qx.size()), my(qx.size());
  for (size_t i = 0; i < qx.size(); ++i) pose.composePoint(qx[i], qy[i], mx[i], my[i]);
  std::vector<char> seen(qx.size(), 0);
  for (const auto& [scan, base] : scans) {
    const size_t n = scan->getScanSize();
    if (n < 2 || !(scan->aperture > 0)) continue;
    const CPose2D sensor = base + CPose2D(scan->sensorPose);
    const double half = scan->aperture / 2, step = scan->aperture / static_cast<double>(n - 1);
    for (size_t i = 0; i < qx.size(); ++i) {
      if (seen[i]) continue;
      double lx = 0, ly = 0;
      sensor.inverseComposePoint(mx[i], my[i], lx, ly);
      const double range = std::hypot(lx, ly);
      // The bearing from the first beam: beams go counterclockwise from -aperture/2, or clockwise from +aperture/2.
      const double bearing = scan->rightToLeft ? std::atan2(ly, lx) + half : half - std::atan2(ly, lx);
      if (bearing < -step / 2 || bearing > scan->aperture + step / 2) continue;
      const auto beam = static_cast<size_t>(std::clamp(std::lround(bearing / step), 0L, static_cast<long>(n - 1)));
      for (size_t k = beam > 0 ? beam - 1 : 0; k <= std::min(beam + 1, n - 1) && !seen[i]; ++k) {
        seen[i] = scan->getScanRangeValidity(k) ? scan->getScanRange(k) + margin >= range : range < scan->maxRange;
      }
    }
  }
  mrpt::maps::CSimplePointsMap out;
  out.reserve(qx.size());
  for (size_t i = 0; i < qx.size(); ++i) {
    if (seen[i]) out.insertPointFast(qx[i], qy[i], 0);
  }
  return out;
}

Eigen::Matrix3d odometry_information(const CPose2D& step, const std::array<double, 4>& noise) {
  const double xy = std::max(noise[0] * step.norm() + noise[1], 1e-6);  // a noise of zero: exact, not infinite
  const double yaw = std::max(noise[2] * angle_of(step) + noise[3], 1e-6);
  return Eigen::Vector3d(1 / (xy * xy), 1 / (xy * xy), 1 / (yaw * yaw)).asDiagonal();
}

CPose2D combine(const CPose2D& a, const Eigen::Matrix3d& a_information, const CPose2D& b,
                const Eigen::Matrix3d& b_information) {
  const Eigen::Vector3d towards_b(b.x() - a.x(), b.y() - a.y(), mrpt::math::wrapToPi(b.phi() - a.phi()));
  const Eigen::Vector3d step = (a_information + b_information).ldlt().solve(b_information * towards_b);
  return {a.x() + step.x(), a.y() + step.y(), mrpt::math::wrapToPi(a.phi() + step.z())};
}

const char* outcome_name(LoopRecord::Outcome outcome) {
  switch (outcome) {
    case LoopRecord::Outcome::accepted: return "accepted";
    case LoopRecord::Outcome::waiting: return "waiting";
    case LoopRecord::Outcome::low_overlap: return "low_overlap";
    case LoopRecord::Outcome::ambiguous: return "ambiguous";
    case LoopRecord::Outcome::not_unique: return "not_unique";
    case LoopRecord::Outcome::refused_chi2: return "refused_chi2";
    case LoopRecord::Outcome::unconfirmed: return "unconfirmed";
    case LoopRecord::Outcome::undone: return "undone";
  }
  return "?";
}

void ScanGraph::record(LoopRecord r, LoopRecord::Outcome outcome, std::string reason) {
  r.outcome = outcome;
  r.reason = std::move(reason);
  records_.push_back(std::move(r));
}

ScanGraph::ScanGraph(const ScanGraphOptions& options) : o_(options) {}

CPose2D ScanGraph::keyframe_pose(size_t i) const {
  const auto& p = graph_.node(i);
  return CPose2D(p[0], p[1], std::remainder(p[2], 2 * M_PI));
}

mrpt::maps::CSimplePointsMap ScanGraph::points_of(const mrpt::obs::CObservation2DRangeScan& scan) const {
  mrpt::maps::CSimplePointsMap points;
  points.insertionOptions.minDistBetweenLaserPoints = static_cast<float>(o_.min_dist_between_points);
  points.insertionOptions.isPlanarMap = true;
  points.insertObservation(scan);  // at the origin: the points land in the base frame (the sensor's pose applied)
  return points;
}

CPose2D ScanGraph::add(int64_t stamp, const mrpt::obs::CObservation2DRangeScan::Ptr& scan,
                       const std::optional<CPose2D>& odometry, mrpt::math::CMatrixDouble33* covariance) {
  ++stats_.scans;
  auto points = points_of(*scan);
  if (covariance != nullptr) covariance->setZero();
  if (keyframes_.empty()) {
    last_odometry_ = odometry;
    scans_.push_back({stamp, 0, CPose2D()});
    add_keyframe(stamp, scan, points, CPose2D());
    return CPose2D();
  }
  // Predict with the odometry's motion since the previous scan, then match against the local map.
  const CPose2D previous = keyframe_pose(current_keyframe_) + relative_;
  CPose2D pose = previous;
  std::optional<CPose2D> step;  // the odometry's
  if (odometry && last_odometry_) step = *odometry - *last_odometry_, pose = previous + *step;
  if (odometry) last_odometry_ = odometry;
  // Standing still by the odometry since the last matched scan: the prediction is as good as a match.
  const CPose2D since = pose - (keyframe_pose(matched_keyframe_) + matched_);
  if (odometry && since.norm() < o_.still_distance && angle_of(since) < o_.still_angle) {
    ++stats_.still;
    relative_ = pose - keyframe_pose(current_keyframe_);
    scans_.push_back({stamp, current_keyframe_, relative_});
    return pose;
  }
  const IcpResult match = icp_align(local_map_, points, pose, o_.icp);
  if (points.size() >= 10 && match.goodness >= o_.min_icp_goodness) {
    ++stats_.matched;
    if (step) {
      const double noise = o_.odometry_noise[2] * std::abs(step->phi()) + o_.odometry_noise[3];
      float z = static_cast<float>(std::abs(mrpt::math::wrapToPi(match.pose.phi() - pose.phi())) / noise);
      if (std::isnan(z)) z = std::numeric_limits<float>::infinity();  // cannot be compared: as far off as any
      heading_z_.add(z);
    }
    if (o_.match_odometry && step) {
      pose = weigh_in_odometry(match.pose, points, pose, *step);
    } else {
      pose = match.pose;
    }
    if (covariance != nullptr) *covariance = match.covariance;
  } else {
    ++stats_.unmatched;  // the prediction stands
  }
  relative_ = pose - keyframe_pose(current_keyframe_);
  matched_keyframe_ = current_keyframe_, matched_ = relative_;
  scans_.push_back({stamp, current_keyframe_, relative_});
  if (relative_.norm() >= o_.keyframe_distance || angle_of(relative_) >= o_.keyframe_angle) {
    scans_.back() = {stamp, static_cast<uint32_t>(keyframes_.size()), CPose2D()};
    add_keyframe(stamp, scan, points, pose);
    return keyframe_pose(current_keyframe_);  // loop closures may have moved it
  }
  return pose;
}

std::optional<double> ScanGraph::odometry_heading_q90() const {
  if (heading_z_.size() < kMinHeadingChecks) return std::nullopt;
  return heading_z_.value();
}

CPose2D ScanGraph::weigh_in_odometry(const CPose2D& matched, const mrpt::maps::CSimplePointsMap& points,
                                     const CPose2D& predicted, const CPose2D& step) {
  // What the match pins down: its pairs' point-to-line information at the matched pose (constraint_of, a mean
  // over the pairs with a clear wall), times the pairs, over the noise of a point's distance to its wall.
  const auto pairs = pairs_within(local_map_, points, matched, o_.loop_match_distance);  // as a loop test counts
  size_t lines = 0;
  const Eigen::Matrix3d per_pair = constraint_of(local_map_, pairs, matched, lines);
  const Eigen::Matrix3d information = per_pair * static_cast<double>(lines) / (o_.match_sigma * o_.match_sigma);
  ++stats_.weighed;
  return combine(matched, information, predicted, odometry_information(step, o_.odometry_noise));
}

void ScanGraph::add_keyframe(int64_t stamp, const mrpt::obs::CObservation2DRangeScan::Ptr& scan,
                             const mrpt::maps::CSimplePointsMap& points, const CPose2D& pose) {
  const auto id = static_cast<uint32_t>(keyframes_.size());
  const double step_length = id == 0 ? 0.0 : (pose - keyframe_pose(current_keyframe_)).norm();
  keyframes_.push_back({stamp, scan, points, id == 0 ? 0.0 : keyframes_.back().path + step_length});
  adjacency_.emplace_back();
  graph_.add_node(array_of(pose));
  if (id > 0) {
    const CPose2D step = pose - keyframe_pose(current_keyframe_);
    graph_.add_edge(current_keyframe_, id, array_of(step), diagonal_information(o_.edge_sigma_xy, o_.edge_sigma_yaw));
    adjacency_[current_keyframe_].push_back({id, step_length});
    adjacency_[id].push_back({current_keyframe_, step_length});
  }
  if (matched_keyframe_ == current_keyframe_) matched_keyframe_ = id, matched_ = pose - keyframe_pose(id);
  current_keyframe_ = id;
  relative_ = CPose2D();
  ++stats_.keyframes;
  if (o_.loop_closure) close_loops();
  rebuild_local_map();
}

void ScanGraph::rebuild_local_map() {
  local_map_.clear();
  const size_t n = keyframes_.size();
  const auto last = static_cast<size_t>(o_.local_map_keyframes);
  for (size_t i = n > last ? n - last : 0; i < n; ++i) {
    local_map_.insertAnotherMap(&keyframes_[i].points, CPose3D(keyframe_pose(i)));
  }
}

ScanGraph::GraphDistances::GraphDistances(const ScanGraph& graph, size_t from)
    : g_(graph), d_(graph.keyframes_.size(), std::numeric_limits<double>::infinity()), done_(d_.size(), 0) {
  d_[from] = 0;
  queue_.push({0, static_cast<uint32_t>(from)});
}

double ScanGraph::GraphDistances::to(uint32_t target) {
  const ScanGraphOptions& o = g_.o_;
  while (done_[target] == 0 && !queue_.empty()) {
    const auto [dist, node] = queue_.top();
    // Every node not settled yet is at least this far: as far as the largest reach needs, or further.
    if (o.loop_radius + o.loop_drift * dist >= o.loop_max_radius) break;
    queue_.pop();
    if (done_[node] != 0) continue;
    done_[node] = 1;
    for (const auto& [next, length] : g_.adjacency_[node]) {
      if (dist + length < d_[next]) {
        d_[next] = dist + length;
        queue_.push({d_[next], next});
      }
    }
  }
  return d_[target];
}

void ScanGraph::close_loops() {
  const size_t k = current_keyframe_;
  // Large corrections wait a few keyframes for a second, consistent match; then they are dropped.
  std::erase_if(pending_, [&](const LoopEdge& l) {
    if (k - l.record.keyframe <= static_cast<size_t>(o_.loop_confirm_keyframes)) return false;
    ++stats_.loop_unconfirmed;
    record(l.record, LoopRecord::Outcome::unconfirmed,
           "no match from the " + std::to_string(o_.loop_confirm_keyframes) + " keyframes after it agreed");
    return true;
  });
  // The old keyframe the graph places nearest, among those within reach of the drift since the graph last tied
  // the two together (the graph distance between them, loop edges counting as the short links they are).
  const CPose2D here = keyframe_pose(k);
  const double path = keyframes_[k].path;
  std::vector<std::pair<double, uint32_t>> candidates;  // within the largest reach: (distance, keyframe)
  for (size_t j = 0; j + static_cast<size_t>(o_.local_map_keyframes) < k; ++j) {
    if (path - keyframes_[j].path < o_.loop_min_travel) continue;
    const auto& there = graph_.node(j);  // its position only: no sine and cosine of its heading
    const double d = std::hypot(there[0] - here.x(), there[1] - here.y());
    if (d <= o_.loop_max_radius) candidates.emplace_back(d, static_cast<uint32_t>(j));
  }
  // Nearest first; the first within its reach is the one. The graph distances come from one Dijkstra's run from
  // this keyframe, taken only as far as each candidate in turn needs: most keyframes are near in the graph too (the
  // path just walked, places loops have tied), and settle at once.
  std::sort(candidates.begin(), candidates.end());
  GraphDistances graph_distance(*this, k);
  for (const auto& [away, j] : candidates) {
    const double radius = std::min(o_.loop_max_radius, o_.loop_radius + o_.loop_drift * graph_distance.to(j));
    if (away <= radius) {
      try_loop(j, radius);
      return;
    }
  }
}

bool ScanGraph::try_loop(size_t j, double radius, bool widened, bool rescue) {
  ++stats_.loop_tests;
  const size_t k = current_keyframe_;
  const double path = keyframes_[k].path;
  const CPose2D here = keyframe_pose(k);
  const bool far = radius > o_.loop_far_radius || rescue;
  LoopRecord rec;
  rec.keyframe = k, rec.old_keyframe = j, rec.far = far, rec.rescued = rescue, rec.radius = radius;
  // The current place: this keyframe and the ones just before it, in this keyframe's frame.
  mrpt::maps::CSimplePointsMap query;
  const auto q = static_cast<size_t>(o_.loop_query_keyframes);
  for (size_t i = k + 1 > q ? k + 1 - q : 0; i <= k; ++i) {
    query.insertAnotherMap(&keyframes_[i].points, CPose3D(keyframe_pose(i) - here));
  }
  // The old place, at the graph's poses: near, the candidate and its neighbours; far, every old keyframe within
  // reach.
  GridPointsMap reference;
  std::vector<size_t> old;
  if (far) {
    for (size_t i = 0; i < k; ++i) {
      const auto& there = graph_.node(i);
      if (path - keyframes_[i].path >= o_.loop_min_travel &&
          std::hypot(there[0] - here.x(), there[1] - here.y()) <= radius) {
        old.push_back(i);
      }
    }
  } else {
    const auto s = static_cast<size_t>(o_.loop_submap_keyframes);
    for (size_t i = j > s ? j - s : 0; i <= j + s && i < k; ++i) {
      if (path - keyframes_[i].path >= o_.loop_min_travel) old.push_back(i);
    }
  }
  // Room for them all at once: MRPT's insertion grows a map by exactly what it adds, copying it each time.
  size_t total = 0;
  for (size_t i : old) total += keyframes_[i].points.size();
  reference.reserve(total);
  for (size_t i : old) reference.insertAnotherMap(&keyframes_[i].points, CPose3D(keyframe_pose(i)));

  // With loop_seen_only, a near test's ICP takes only the current points one of the old place's scans could have
  // seen from where the estimate, then the coarse ICP, puts them (docs/slam.md, "What an old place saw").
  const bool seen_only = o_.loop_seen_only && !far;
  std::vector<std::pair<const mrpt::obs::CObservation2DRangeScan*, CPose2D>> old_scans;
  if (seen_only) {
    for (size_t i : old) old_scans.emplace_back(keyframes_[i].scan.get(), keyframe_pose(i));
  }
  const auto icp_points = [&](const CPose2D& at) {
    mrpt::maps::CSimplePointsMap seen;
    if (seen_only) seen = seen_points(old_scans, query, at, kSeenMargin);
    return seen;
  };
  const auto or_query = [&](const mrpt::maps::CSimplePointsMap& seen) -> const mrpt::maps::CSimplePointsMap& {
    return seen_only && static_cast<double>(seen.size()) >= o_.loop_min_points ? seen : query;
  };
  CPose2D start = here;
  if (far) {
    // Further than ICP reaches from the estimate (the first return after a long excursion): the best pose in the
    // whole window, and no other place in it nearly as good.
    const CorrelativeMatcher matcher(points_in(reference, std::numeric_limits<size_t>::max()), o_.loop_grid_resolution,
                                     1.0, o_.loop_grid_levels);
    const auto points = points_in(query, static_cast<size_t>(o_.loop_search_points));
    const double yaw_window = widened ? o_.loop_far_yaw * o_.loop_widen : o_.loop_far_yaw;
    const auto best = matcher.match(points, here.x(), here.y(), here.phi(), radius, yaw_window);
    // The best pose near the window's edge: the drift may have outrun the reach, the place lie just beyond the
    // window, and what the window holds be the best of the wrong places (a door further down the corridor, the
    // same room turned). The same test again in a wider window, once: there the place is the best, or it and the
    // first best both score high and the test is ambiguous.
    const double wider = std::min(radius * o_.loop_widen, o_.loop_max_radius);
    if (!widened && wider > radius &&
        (std::max(std::abs(best.x - here.x()), std::abs(best.y - here.y())) > o_.loop_edge * radius ||
         std::abs(best.yaw - here.phi()) > o_.loop_edge * yaw_window)) {
      --stats_.loop_tests;  // counted by the wider search
      return try_loop(j, wider, true);
    }
    // All the test needs to know is whether some place elsewhere scores loop_ambiguity of the best: the search
    // stops at the first that does, and only opens branches that may.
    const auto other = matcher.match(points, here.x(), here.y(), here.phi(), radius, yaw_window, &best, 0.5,
                                     o_.loop_ambiguity * best.score);
    if (other.score >= o_.loop_ambiguity * best.score) {
      ++stats_.loop_rejected_unique;
      std::string why;
      appendf(why, "another place 0.5 m or more from the best scores %.0f%% of it (at most %.0f%%)",
              100 * other.score / best.score, 100 * o_.loop_ambiguity);
      record(rec, LoopRecord::Outcome::ambiguous, why);
      return false;
    }
    start = CPose2D(best.x, best.y, best.yaw);
  } else {
    // Near: ICP from the estimate, correspondences first as far apart as the drift may have carried it.
    IcpOptions coarse = o_.icp;
    coarse.thresholdDist = std::clamp(radius, o_.icp.thresholdDist, 2.0);
    coarse.thresholdAng = std::max(o_.icp.thresholdAng, o_.loop_threshold_ang);
    start = icp_classic(reference, or_query(icp_points(here)), here, coarse);
  }
  const mrpt::maps::CSimplePointsMap seen = icp_points(start);
  const mrpt::maps::CSimplePointsMap& icp_query = or_query(seen);
  const CPose2D found = icp_classic(reference, icp_query, start, o_.icp);
  // Near, ICP pulled beyond the reach: it started where the estimate is, and its first correspondences, as far apart
  // as the reach, let it slide off to a lookalike or a stretch of wall (on the benchmark logs the right place mostly
  // lay within centimetres of the estimate, or turned by more than those correspondences allow: MIT CSAIL from 3 s,
  // its first turn on the spot lost 23 degrees). With loop_rescue_near, the same window is searched as a far test
  // searches its own, turned as far as a widened one (docs/slam.md, "How robust").
  if (!far && o_.loop_rescue_near && (found - here).norm() > radius) {
    --stats_.loop_tests;  // counted by the search
    return try_loop(j, radius, true, true);
  }

  // Overlap: the share of the current points with an old point close by, all points counted.
  mrpt::maps::TMatchingExtraResults overlap;
  const auto pairs = pairs_within(reference, query, found, o_.loop_match_distance, &overlap);
  const CPose2D correction = found - here;
  rec.correction = correction, rec.overlap = overlap.correspondencesRatio;
  rec.pairs = static_cast<int64_t>(pairs.size());
  if (overlap.correspondencesRatio < o_.loop_min_goodness || static_cast<double>(pairs.size()) < o_.loop_min_points ||
      correction.norm() > radius) {
    ++stats_.loop_rejected_goodness;
    std::string why;
    if (correction.norm() > radius) {
      appendf(why, "the match moved it %.2f m: beyond the search's reach (%.2f m)", correction.norm(), radius);
    } else {
      appendf(why, "%.0f%% of the current points (%zu) have an old point within %.2f m (at least %.0f%% and %.0f)",
              100 * overlap.correspondencesRatio, pairs.size(), o_.loop_match_distance, 100 * o_.loop_min_goodness,
              o_.loop_min_points);
    }
    record(rec, LoopRecord::Outcome::low_overlap, why);
    return false;
  }
  // What the match pins down. A corridor pins the pose across it and its heading, not along it: such a match is
  // kept, with the information it has (next to none along the corridor).
  size_t lines = 0;
  Eigen::Matrix3d h = constraint_of(reference, pairs, found, lines);
  if (static_cast<double>(lines) < o_.loop_min_points / 2) {
    ++stats_.loop_rejected_unique;
    record(rec, LoopRecord::Outcome::not_unique,
           std::to_string(lines) + " of the matched points lie on a clear surface (at least " +
               std::to_string(static_cast<int>(o_.loop_min_points / 2)) + ")");
    return false;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> axes(h.topLeftCorner<2, 2>());
  const bool corridor = axes.eigenvalues()(0) < o_.loop_min_constraint;
  // A unique optimum: started loop_uniqueness off along each pinned-down axis, and turned, ICP must come back.
  const double u = o_.loop_uniqueness;
  IcpOptions restart = o_.icp;
  restart.thresholdDist = std::max(o_.icp.thresholdDist, 2 * u);
  restart.thresholdAng = std::max(o_.icp.thresholdAng, o_.loop_threshold_ang);
  constexpr double kSameXy = 0.05, kSameYaw = 0.02;  // ICP's own spread from nearby starts
  std::vector<Eigen::Vector3d> offsets = {{0, 0, 2 * u / 3}};
  for (int a = corridor ? 1 : 0; a < 2; ++a)
    offsets.emplace_back(u * axes.eigenvectors()(0, a), u * axes.eigenvectors()(1, a), 0);
  for (const Eigen::Vector3d& off : offsets) {
    // Back within a fifth of the bars below, it has come back: what the finer thresholds do from there is ICP's
    // own spread around the optimum, and stopping saves half the restarts' iterations (most run into the cap).
    const CPose2D back =
        icp_classic(reference, icp_query, CPose2D(found.x() + off.x(), found.y() + off.y(), found.phi() + off.z()),
                    restart, [&](const CPose2D& p) {
                      return std::hypot(p.x() - found.x(), p.y() - found.y()) <= kSameXy / 5 &&
                             std::abs(mrpt::math::wrapToPi(p.phi() - found.phi())) <= kSameYaw / 5;
                    });
    const Eigen::Vector2d step(back.x() - found.x(), back.y() - found.y());
    const double turned = std::abs(mrpt::math::wrapToPi(back.phi() - found.phi()));
    bool same = turned <= kSameYaw;
    for (int a = corridor ? 1 : 0; a < 2; ++a) same &= std::abs(step.dot(axes.eigenvectors().col(a))) <= kSameXy;
    if (!same) {
      ++stats_.loop_rejected_unique;
      std::string why;
      appendf(why,
              "ICP started %.2f m and %.1f deg off came back %.3f m and %.2f deg away (at most %.2f m along what "
              "the match pins down and %.2f deg)",
              std::hypot(off.x(), off.y()), degrees(std::abs(off.z())), step.norm(), degrees(turned), kSameXy,
              degrees(kSameYaw));
      record(rec, LoopRecord::Outcome::not_unique, why);
      return false;
    }
  }
  if (corridor) {  // next to no information along the corridor (a standard deviation of about a metre)
    Eigen::Vector2d values = axes.eigenvalues();
    values(0) = std::max(values(0), 1e-3);
    h.topLeftCorner<2, 2>() = axes.eigenvectors() * values.asDiagonal() * axes.eigenvectors().transpose();
  }

  // The edge: this keyframe seen from the old keyframe nearest where the match put it.
  if (far) {
    double nearest = std::numeric_limits<double>::infinity();
    for (size_t i : old) {
      const auto& there = graph_.node(i);
      const double d = std::hypot(there[0] - found.x(), there[1] - found.y());
      if (d < nearest) nearest = d, j = i;
    }
  }
  const CPose2D there = keyframe_pose(j);
  const CPose2D measured = found - there;
  rec.old_keyframe = j, rec.measured = measured;
  // Its information: what the match pinned down (h, per point, in the map frame) turned into the old keyframe's
  // frame, and scaled so that a place pinned down equally in x and y gives edge_sigma_xy in each.
  Eigen::Matrix3d rotate = Eigen::Matrix3d::Identity();
  rotate.topLeftCorner<2, 2>() = Eigen::Rotation2Dd(there.phi()).toRotationMatrix().transpose();
  const Eigen::Matrix3d info = rotate * h * rotate.transpose() * (2 / (o_.edge_sigma_xy * o_.edge_sigma_xy));
  LoopEdge loop{rec, {}};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) loop.information[static_cast<size_t>(r) * 3 + static_cast<size_t>(c)] = info(r, c);
  }
  // A small correction is one the graph nearly agrees with already. A large one (the first return after a long
  // excursion, or a wrong match) waits for a second match, from one of the next keyframes, that puts this stretch
  // of the path in the same place; then both go in.
  if (correction.norm() <= o_.loop_confirm_xy && angle_of(correction) <= o_.loop_confirm_yaw) {
    loop.record.reason = "moves the estimate " + moved(correction);
    return add_loops({loop});
  }
  for (auto it = pending_.begin(); it != pending_.end(); ++it) {
    const LoopRecord& r = it->record;
    const CPose2D predicted = (keyframe_pose(r.old_keyframe) + r.measured) + (here - keyframe_pose(r.keyframe));
    const CPose2D diff = found - predicted;
    if (diff.norm() <= o_.loop_consistency_xy && angle_of(diff) <= o_.loop_consistency_yaw) {
      LoopEdge first = *it;
      pending_.erase(it);
      first.record.reason = "moves the estimate " + moved(first.record.correction) + "; keyframe " + std::to_string(k) +
                            "'s match agrees within " + moved(diff);
      loop.record.reason = "moves the estimate " + moved(correction) + "; agrees with keyframe " +
                           std::to_string(first.record.keyframe) + "'s match within " + moved(diff);
      return add_loops({first, loop});
    }
  }
  record(loop.record, LoopRecord::Outcome::waiting,
         "moves the estimate " + moved(correction) + ": waits for a second match that agrees");
  pending_.push_back(loop);
  return false;
}

bool ScanGraph::add_loops(std::vector<LoopEdge> loops) {
  std::vector<PoseGraph2d::Pose> before(graph_.size());
  for (size_t i = 0; i < before.size(); ++i) before[i] = graph_.node(i);
  std::vector<size_t> edges;
  bool disagree = false;
  for (const auto& l : loops) {
    const LoopRecord& r = l.record;
    edges.push_back(graph_.add_edge(r.old_keyframe, r.keyframe, array_of(r.measured), l.information));
    const CPose2D off = (keyframe_pose(r.keyframe) - keyframe_pose(r.old_keyframe)) - r.measured;
    disagree |= off.norm() > o_.optimize_threshold_xy || angle_of(off) > o_.optimize_threshold_yaw;
  }
  if (disagree) {
    ++stats_.optimisations;
    graph_.optimise(10);
    // A match that contradicts the rest of the graph stays far from what the optimum makes of it.
    for (size_t e : edges) {
      if (graph_.edge_chi2(e) <= o_.loop_max_chi2) continue;
      for (size_t i = 0; i < loops.size(); ++i) {
        auto& r = loops[i].record;
        r.chi2 = graph_.edge_chi2(edges[i]);
        std::string why;
        if (edges[i] == e || r.chi2 > o_.loop_max_chi2) {
          appendf(why, "; after optimising its chi2 is %.1f (at most %.0f)", r.chi2, o_.loop_max_chi2);
        } else {
          appendf(why, "; after optimising its partner's chi2 is above %.0f (its own %.1f)", o_.loop_max_chi2, r.chi2);
        }
        record(r, LoopRecord::Outcome::refused_chi2, r.reason + why);
      }
      for (size_t r : edges) graph_.remove_edge(r);
      for (size_t i = 0; i < before.size(); ++i) graph_.set_node(i, before[i]);
      stats_.loop_rejected_chi2 += static_cast<int64_t>(loops.size());
      return false;
    }
  }
  for (size_t i = 0; i < loops.size(); ++i) {
    const LoopRecord& r = loops[i].record;
    adjacency_[r.old_keyframe].push_back({static_cast<uint32_t>(r.keyframe), r.measured.norm()});
    adjacency_[r.keyframe].push_back({static_cast<uint32_t>(r.old_keyframe), r.measured.norm()});
    closures_.push_back({edges[i], r});
    record(r, LoopRecord::Outcome::accepted, r.reason);
    ++stats_.loop_closures;
  }
  return true;
}

void ScanGraph::finish() {
  for (const auto& l : pending_) {
    ++stats_.loop_unconfirmed;
    record(l.record, LoopRecord::Outcome::unconfirmed, "the log ended before a second match agreed");
  }
  pending_.clear();
  if (stats_.loop_closures == 0) return;
  ++stats_.optimisations;
  graph_.optimise(100);
  // With every closure in, one the rest of the graph contradicts is undone (worst first), as each one was refused
  // when it came in if the graph of then contradicted it. Only at the end: undoing during the run, when the graph
  // has fewer closures to judge by, took out right ones (MIT CSAIL went from 0.034 to 0.49 m).
  std::vector<size_t> edges;
  for (const auto& c : closures_) edges.push_back(c.edge);
  std::set<size_t> undone;
  const auto undo = [&](const Closure& c, double chi2, const std::string& why) {
    LoopRecord r = c.record;
    r.chi2 = chi2;
    record(r, LoopRecord::Outcome::undone, why);
    std::erase_if(adjacency_[c.record.old_keyframe], [&](const auto& n) { return n.first == c.record.keyframe; });
    std::erase_if(adjacency_[c.record.keyframe], [&](const auto& n) { return n.first == c.record.old_keyframe; });
    undone.insert(c.edge);
    ++stats_.loop_undone;
    --stats_.loop_closures;
  };
  const auto closure_of = [&](size_t edge) -> const Closure& {
    return *std::find_if(closures_.begin(), closures_.end(), [&](const Closure& x) { return x.edge == edge; });
  };
  std::vector<double> chi2;
  const auto contradicted = graph_.remove_contradicted(edges, o_.loop_max_chi2, 100, &chi2);
  for (size_t u = 0; u < contradicted.size(); ++u) {
    std::string why;
    appendf(why, "the graph with every closure in leaves it chi2 %.1f (at most %.0f)", chi2[u], o_.loop_max_chi2);
    undo(closure_of(contradicted[u]), chi2[u], why);
    ++stats_.optimisations;
  }
  // A closure that went in alone, no other closure within loop_confirm_keyframes of both its keyframes, went in
  // because the graph of then agreed with it: it moved the estimate loop_confirm_xy and loop_confirm_yaw at most.
  // With every closure in, the graph may rather bend than leave it far off, and its chi2 then says little. MIT
  // Killian Court from 15 s: a far test at 619 s matched a lookalike stretch of corridor where the drifted estimate
  // put the robot and tied it to the first keyframe; the return confirmed at 644 s put that place metres away, and
  // the optimiser bent the first keyframes by 22 deg to keep both (relations 6 m off). So each such closure is
  // taken out and the graph optimised without it: where the rest of the graph then puts its keyframes more than
  // kAloneMargin times as far from its measurement as a closure alone may move them, the others contradict it,
  // and it is undone (the worst first). Left out, a right one is off by the drift it corrected and the drift since
  // (Freiburg's clinic from 3 s: 0.85 m), the wrong ones found on Killian 1.5-7.9 m; undoing those over 0.5 m, or
  // those chi2 judges contradicted (above loop_max_chi2), took right ones out too (docs/slam.md, step 5 (f)).
  constexpr double kAloneMargin = 2;
  const auto near = [&](const Closure& a, const Closure& b) {
    const auto w = static_cast<int64_t>(o_.loop_confirm_keyframes);
    const auto apart = [](uint32_t x, uint32_t y) { return std::abs(static_cast<int64_t>(x) - y); };
    return apart(a.record.keyframe, b.record.keyframe) <= w && apart(a.record.old_keyframe, b.record.old_keyframe) <= w;
  };
  std::vector<size_t> alone;
  for (const auto& c : closures_) {
    if (undone.contains(c.edge)) continue;
    if (std::none_of(closures_.begin(), closures_.end(),
                     [&](const Closure& d) { return d.edge != c.edge && !undone.contains(d.edge) && near(c, d); })) {
      alone.push_back(c.edge);
    }
  }
  const double most_xy = kAloneMargin * o_.loop_confirm_xy, most_yaw = kAloneMargin * o_.loop_confirm_yaw;
  const auto left_out = graph_.leave_out_contradicted(alone, most_xy, most_yaw, 100);
  // One optimisation per closure left alone and round, a round per one undone and one more, and one after each.
  for (size_t round = 0; round <= left_out.size(); ++round) {
    stats_.optimisations += static_cast<int64_t>(alone.size() - round) + (round < left_out.size() ? 1 : 0);
  }
  for (size_t e : left_out) {
    const PoseGraph2d::Pose off = graph_.edge_error(e);
    std::string why;
    appendf(why,
            "alone (no other closure near it): the graph without it is %.2f m and %.1f deg from it (at most %.2f m "
            "and %.1f deg)",
            std::hypot(off[0], off[1]), degrees(std::abs(off[2])), most_xy, degrees(most_yaw));
    undo(closure_of(e), graph_.edge_chi2(e), why);
  }
}

std::vector<std::pair<int64_t, CPose2D>> ScanGraph::trajectory() const {
  std::vector<std::pair<int64_t, CPose2D>> out;
  out.reserve(scans_.size());
  for (const auto& s : scans_) out.emplace_back(s.stamp, keyframe_pose(s.keyframe) + s.relative);
  // In stamp order: a scan that arrived late was matched after newer ones.
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

}  // namespace driftlab::slam::internal
