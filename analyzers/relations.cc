#include "analyzers/relations.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "analyzers/internal/number_lines.h"
#include "core/mapped_file.h"

namespace driftlab::analyzers {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

RelationStats stats(const PoseArray<double>& v) {
  RelationStats s;
  if (v.empty()) return s;
  double sum = 0;
  for (double x : v) {
    sum += x;
    s.max = std::max(s.max, x);
  }
  s.mean = sum / static_cast<double>(v.size());
  if (v.size() > 1) {
    double var = 0;
    for (double x : v) var += (x - s.mean) * (x - s.mean);
    s.std = std::sqrt(var / static_cast<double>(v.size() - 1));
  }
  return s;
}

struct Pose {
  Eigen::Vector3d p;
  Eigen::Quaterniond q;
};

/// The pose of t (sorted) at position i.
Pose pose_at(const Trajectory& t, size_t i) { return {t.positions[i], t.orientations[i].normalized()}; }

/// Position of the stamp of t nearest to s (the earlier on ties).
size_t nearest(const Trajectory& t, double s) {
  const size_t hi = static_cast<size_t>(std::lower_bound(t.stamps.begin(), t.stamps.end(), s) - t.stamps.begin());
  if (hi == 0) return 0;
  if (hi == t.size()) return hi - 1;
  return s - t.stamps[hi - 1] <= t.stamps[hi] - s ? hi - 1 : hi;
}

/// The odometry at stamp s, interpolated between its poses around s when they are at most kMaxOdometryGap apart.
std::optional<Pose> odometry_at(const Trajectory& odom, double s) {
  const auto it = std::lower_bound(odom.stamps.begin(), odom.stamps.end(), s);
  if (it == odom.stamps.end()) return std::nullopt;
  const size_t b = static_cast<size_t>(it - odom.stamps.begin());
  if (*it == s) return pose_at(odom, b);
  if (b == 0) return std::nullopt;
  const size_t a = b - 1;
  const double span = odom.stamps[b] - odom.stamps[a];
  if (span > kMaxOdometryGap) return std::nullopt;
  const double f = (s - odom.stamps[a]) / span;
  const Pose pa = pose_at(odom, a), pb = pose_at(odom, b);
  return Pose{pa.p + f * (pb.p - pa.p), pa.q.slerp(f, pb.q)};
}

}  // namespace

Result<std::vector<Relation>> load_relations(const std::string& path) {
  auto mapped = MappedFile::open(path);
  if (!mapped) return mapped.error();
  const auto bytes = mapped->bytes();
  std::vector<Relation> out;
  std::string error;
  internal::for_each_data_line(
      std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
      [&](size_t line, const char* p, const char* end) {
        double v[8];
        const int n = internal::parse_numbers(p, end, v, 8);
        const std::string where = path + ":" + std::to_string(line);
        if (n != 8) {
          error = where + (n < 0 ? ": not a number" : ": expected 8 numbers (t1 t2 x y z roll pitch yaw), found " +
                                                           std::to_string(n > 8 ? 9 : n) + (n > 8 ? " or more" : ""));
          return false;
        }
        if (!std::all_of(v, v + 8, [](double x) { return std::isfinite(x); })) {
          error = where + ": a number is not finite";
          return false;
        }
        Relation r;
        r.t1 = v[0];
        r.t2 = v[1];
        r.translation = {v[2], v[3], v[4]};
        r.rotation = Eigen::AngleAxisd(v[7], Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(v[6], Eigen::Vector3d::UnitY()) *
                     Eigen::AngleAxisd(v[5], Eigen::Vector3d::UnitX());
        out.push_back(r);
        return true;
      });
  if (!error.empty()) return Error{error};
  if (out.empty()) return Error{path + ": no relations (expected lines of \"t1 t2 x y z roll pitch yaw\")"};
  return out;
}

RelationResult relation_error(const Trajectory& est, const std::vector<Relation>& relations,
                              const RelationOptions& options) {
  RelationResult r;
  r.relations = relations.size();
  if (est.size() == 0) return r;
  // The estimate's pose at a relation's stamp, and how long odometry carried it there (0: not at all) [s].
  struct Found {
    Pose x;
    double bridge_s = 0;
  };
  auto lookup = [&](double s) -> std::optional<Found> {
    const size_t k = nearest(est, s);
    if (std::abs(est.stamps[k] - s) <= options.max_dt) return Found{pose_at(est, k)};
    if (options.odometry == nullptr) return std::nullopt;
    const auto from = odometry_at(*options.odometry, est.stamps[k]);
    const auto to = odometry_at(*options.odometry, s);
    if (!from || !to) return std::nullopt;
    // X(s) = X(t_k) (O(t_k)^-1 O(s)): the estimate moved as the odometry did between the two stamps.
    const Pose x = pose_at(est, k);
    const Eigen::Quaterniond q_rel = from->q.conjugate() * to->q;
    const Eigen::Vector3d p_rel = from->q.conjugate() * (to->p - from->p);
    return Found{{x.p + x.q * p_rel, (x.q * q_rel).normalized()}, std::abs(s - est.stamps[k])};
  };
  PoseArray<double> trans_sq, rot_sq;
  for (size_t i = 0; i < relations.size(); ++i) {
    const Relation& rel = relations[i];
    const auto f1 = lookup(rel.t1);
    const auto f2 = f1 ? lookup(rel.t2) : std::nullopt;
    if (!f1 || !f2) continue;
    const Pose& x1 = f1->x;
    const Pose& x2 = f2->x;
    // D = X1^-1 X2; E = D*^-1 D: translation R*^T (t_D - t*), whose norm is |t_D - t*|.
    const Eigen::Vector3d t_d = x1.q.conjugate() * (x2.p - x1.p);
    const Eigen::Quaterniond q_d = x1.q.conjugate() * x2.q;
    const double trans = (t_d - rel.translation).norm();
    const double rot = rotation_angle(rel.rotation.conjugate() * q_d) * kRadToDeg;
    r.index.push_back(i);
    r.trans_errors_m.push_back(trans);
    r.rot_errors_deg.push_back(rot);
    trans_sq.push_back(trans * trans);
    rot_sq.push_back(rot * rot);
    const double bridge = std::max(f1->bridge_s, f2->bridge_s);
    if (bridge > 0) ++r.bridged;
    r.max_bridge_s = std::max(r.max_bridge_s, bridge);
  }
  r.used = r.index.size();
  r.trans_m = stats(r.trans_errors_m);
  r.trans_sq_m2 = stats(trans_sq);
  r.rot_deg = stats(r.rot_errors_deg);
  r.rot_sq_deg2 = stats(rot_sq);
  return r;
}

}  // namespace driftlab::analyzers
