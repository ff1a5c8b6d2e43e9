#include "slam/internal/pose_graph.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace driftlab::slam::internal {
namespace {

double wrap_angle(double a) { return a - 2 * M_PI * std::floor((a + M_PI) / (2 * M_PI)); }

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;

}  // namespace

/// "b seen from a" = z, whitened: r = W e, e = (R(a)^T (b - a) - z_xy, wrap(b_yaw - a_yaw - z_yaw)), W = L^T where
/// information = L L^T.
struct PoseGraph2d::Edge {
  size_t a, b;
  Pose z;
  Mat3 w;
  bool live = true;

  Vec3 residual(const Pose& pa, const Pose& pb) const { return w * error(pa, pb, std::cos(pa[2]), std::sin(pa[2])); }
  /// e, unwhitened.
  Vec3 error(const Pose& pa, const Pose& pb, double c, double s) const {
    const double dx = pb[0] - pa[0], dy = pb[1] - pa[1];
    return {c * dx + s * dy - z[0], -s * dx + c * dy - z[1], wrap_angle(pb[2] - pa[2] - z[2])};
  }
  /// The residual and its Jacobians with respect to a and b.
  Vec3 linearise(const Pose& pa, const Pose& pb, Mat3& ja, Mat3& jb) const {
    const double c = std::cos(pa[2]), s = std::sin(pa[2]), dx = pb[0] - pa[0], dy = pb[1] - pa[1];
    Mat3 ea, eb;
    ea << -c, -s, -s * dx + c * dy, s, -c, -c * dx - s * dy, 0, 0, -1;
    eb << c, s, 0, -s, c, 0, 0, 0, 1;
    ja.noalias() = w * ea;
    jb.noalias() = w * eb;
    return w * error(pa, pb, c, s);
  }
};

PoseGraph2d::PoseGraph2d() = default;
PoseGraph2d::~PoseGraph2d() = default;

PoseGraph2d::Information diagonal_information(double sigma_xy, double sigma_yaw) {
  const double xy = 1 / (sigma_xy * sigma_xy);
  return {xy, 0, 0, 0, xy, 0, 0, 0, 1 / (sigma_yaw * sigma_yaw)};
}

size_t PoseGraph2d::add_node(const Pose& pose) {
  nodes_.push_back(pose);
  return nodes_.size() - 1;
}

size_t PoseGraph2d::add_edge(size_t a, size_t b, const Pose& b_in_a, const Information& information) {
  if (a == b || a >= nodes_.size() || b >= nodes_.size()) throw std::invalid_argument("pose graph: bad edge");
  const Mat3 info = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(information.data());
  auto edge = std::make_unique<Edge>(Edge{a, b, b_in_a, Eigen::LLT<Mat3>(0.5 * (info + info.transpose())).matrixU()});
  edges_.push_back(std::move(edge));
  ++live_edges_;
  return edges_.size() - 1;
}

void PoseGraph2d::remove_edge(size_t id) {
  if (!edges_[id]->live) return;
  edges_[id]->live = false;
  --live_edges_;
}

double PoseGraph2d::cost(const std::deque<Pose>& nodes) const {
  double sum = 0;
  for (const auto& e : edges_) {
    if (e->live) sum += e->residual(nodes[e->a], nodes[e->b]).squaredNorm();
  }
  return 0.5 * sum;
}

void PoseGraph2d::optimise(int max_iterations) {
  if (live_edges_ == 0 || nodes_.size() < 2) return;
  // Levenberg-Marquardt on the normal equations, as Ceres's trust region does it (its defaults): columns scaled by
  // 1 / (1 + their norm), the damping diag(H) / radius, the radius grown or shrunk by the step's quality. The first
  // node is held fixed: unknowns are nodes 1..n-1, three each.
  const auto unknowns = static_cast<Eigen::Index>(3 * (nodes_.size() - 1));
  // The pattern of H's lower triangle, once per call: 3x3 blocks on the diagonal and where an edge joins two nodes.
  std::vector<Eigen::Triplet<double>> pattern;
  auto block = [&](size_t row_node, size_t col_node, bool lower_only) {
    const auto r0 = static_cast<int>(3 * (row_node - 1)), c0 = static_cast<int>(3 * (col_node - 1));
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < (lower_only ? r + 1 : 3); ++c) pattern.emplace_back(r0 + r, c0 + c, 0.0);
    }
  };
  for (size_t i = 1; i < nodes_.size(); ++i) block(i, i, true);
  for (const auto& e : edges_) {
    if (e->live && e->a != 0 && e->b != 0) block(std::max(e->a, e->b), std::min(e->a, e->b), false);
  }
  Eigen::SparseMatrix<double> h(unknowns, unknowns);
  h.setFromTriplets(pattern.begin(), pattern.end(), [](double a, double) { return a; });
  h.makeCompressed();
  const double* base = h.valuePtr();
  auto at = [&](Eigen::Index r, Eigen::Index c) { return &h.coeffRef(r, c) - base; };
  // Where each edge's blocks go in h's values (-1: a fixed node's, not there).
  struct Slots {
    std::array<ptrdiff_t, 9> aa, bb, ab;  // ab: block (max, min) of the pair, row-major
  };
  std::vector<Slots> slots(edges_.size());
  for (size_t k = 0; k < edges_.size(); ++k) {
    const Edge& e = *edges_[k];
    if (!e.live) continue;
    Slots& s = slots[k];
    s.aa.fill(-1), s.bb.fill(-1), s.ab.fill(-1);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c <= r; ++c) {
        if (e.a != 0) s.aa[3 * r + c] = at(3 * (e.a - 1) + r, 3 * (e.a - 1) + c);
        if (e.b != 0) s.bb[3 * r + c] = at(3 * (e.b - 1) + r, 3 * (e.b - 1) + c);
      }
    }
    if (e.a != 0 && e.b != 0) {
      const size_t hi = std::max(e.a, e.b) - 1, lo = std::min(e.a, e.b) - 1;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) s.ab[3 * r + c] = at(3 * hi + r, 3 * lo + c);
      }
    }
  }
  std::vector<ptrdiff_t> diagonal_at(static_cast<size_t>(unknowns));
  for (Eigen::Index j = 0; j < unknowns; ++j) diagonal_at[static_cast<size_t>(j)] = at(j, j);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> solver;
  solver.analyzePattern(h);

  double* v = h.valuePtr();
  Eigen::VectorXd g(unknowns), scale(unknowns), hd(unknowns), damping(unknowns), y(unknowns), step(unknowns);
  double radius = 1e4, decrease = 2, x_cost = cost(nodes_), x_norm = 0;
  auto norm_of_nodes = [&] {
    double sum = 0;
    for (size_t i = 1; i < nodes_.size(); ++i) {
      sum += nodes_[i][0] * nodes_[i][0] + nodes_[i][1] * nodes_[i][1] + nodes_[i][2] * nodes_[i][2];
    }
    return std::sqrt(sum);
  };
  bool linearise = true;
  auto shrink = [&] {  // a step not taken: a smaller trust region, shrinking faster each time in a row
    radius /= decrease, decrease *= 2;
    return radius >= 1e-32;
  };
  std::deque<Pose> candidate = nodes_;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    if (linearise) {
      x_norm = norm_of_nodes();
      std::fill(v, v + h.nonZeros(), 0.0);
      g.setZero();
      for (size_t k = 0; k < edges_.size(); ++k) {
        const Edge& e = *edges_[k];
        if (!e.live) continue;
        Mat3 ja, jb;
        const Vec3 r = e.linearise(nodes_[e.a], nodes_[e.b], ja, jb);
        const Slots& s = slots[k];
        auto own = [&](size_t node, const Mat3& j, const std::array<ptrdiff_t, 9>& at) {  // a node's block of H, g
          if (node == 0) return;
          const Mat3 hjj = j.transpose() * j;
          for (int i = 0; i < 9; ++i) {
            if (at[i] >= 0) v[at[i]] += hjj(i / 3, i % 3);
          }
          g.segment<3>(3 * static_cast<Eigen::Index>(node - 1)) += j.transpose() * r;
        };
        own(e.a, ja, s.aa), own(e.b, jb, s.bb);
        if (s.ab[0] >= 0) {
          const Mat3 hab = e.a > e.b ? Mat3(ja.transpose() * jb) : Mat3(jb.transpose() * ja);
          for (int i = 0; i < 9; ++i) v[s.ab[i]] += hab(i / 3, i % 3);
        }
      }
      // Gradient small enough: converged (Ceres's gradient_tolerance).
      if (g.lpNorm<Eigen::Infinity>() <= 1e-10) return;
      // Jacobi scaling: column j of J times 1 / (1 + |J_j|); H and g scaled alike.
      for (Eigen::Index j = 0; j < unknowns; ++j)
        scale[j] = 1 / (1 + std::sqrt(v[diagonal_at[static_cast<size_t>(j)]]));
      for (Eigen::Index col = 0; col < unknowns; ++col) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(h, col); it; ++it)
          it.valueRef() *= scale[it.row()] * scale[col];
      }
      g = g.cwiseProduct(scale);
      for (Eigen::Index j = 0; j < unknowns; ++j) hd[j] = v[diagonal_at[static_cast<size_t>(j)]];
      linearise = false;
    }
    // (S H S + D / radius) y = -S g, D = diag(S H S) clamped; the step is S y.
    for (Eigen::Index j = 0; j < unknowns; ++j) {
      damping[j] = std::clamp(hd[j], 1e-6, 1e32) / radius;
      v[diagonal_at[static_cast<size_t>(j)]] = hd[j] + damping[j];
    }
    solver.factorize(h);
    bool valid = solver.info() == Eigen::Success;
    if (valid) {
      y = solver.solve(-g);
      valid = y.allFinite();
    }
    if (!valid) {
      if (!shrink()) break;
      continue;
    }
    step = y.cwiseProduct(scale);
    // The model's decrease: -(g.y + y.SHS.y / 2), in the scaled space (SHS y = the damped product less the damping).
    const Eigen::VectorXd hy = h.selfadjointView<Eigen::Lower>() * y - damping.cwiseProduct(y);
    const double model = -(g.dot(y) + 0.5 * y.dot(hy));
    for (size_t i = 1; i < nodes_.size(); ++i) {
      for (int d = 0; d < 3; ++d) candidate[i][d] = nodes_[i][d] + step[3 * static_cast<Eigen::Index>(i - 1) + d];
    }
    const double c_cost = cost(candidate);
    // Ceres's parameter_tolerance (1e-8) and function_tolerance (1e-6).
    if (step.norm() <= 1e-8 * (x_norm + 1e-8)) break;
    const double change = x_cost - c_cost;
    const bool converged = std::abs(change) <= 1e-6 * x_cost;
    const double quality = model > 0 ? change / model : -1;
    if (quality > 1e-3) {
      for (size_t i = 1; i < nodes_.size(); ++i) nodes_[i] = candidate[i];
      x_cost = c_cost;
      radius = std::min(1e16, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2 * quality - 1, 3)));
      decrease = 2;
      linearise = true;
    } else if (!shrink()) {
      break;
    }
    if (converged) break;
  }
}

std::vector<size_t> PoseGraph2d::remove_contradicted(const std::vector<size_t>& candidates, double max_chi2,
                                                     int max_iterations, std::vector<double>* chi2) {
  std::vector<size_t> removed;
  while (true) {
    size_t worst = edges_.size();
    double worst_chi2 = max_chi2;
    for (size_t id : candidates) {
      if (!edges_[id]->live) continue;
      const double chi2 = edge_chi2(id);
      if (chi2 > worst_chi2) worst = id, worst_chi2 = chi2;
    }
    if (worst == edges_.size()) return removed;
    remove_edge(worst);
    removed.push_back(worst);
    if (chi2 != nullptr) chi2->push_back(worst_chi2);
    optimise(max_iterations);
  }
}

std::vector<size_t> PoseGraph2d::leave_out_contradicted(const std::vector<size_t>& candidates, double max_xy,
                                                        double max_yaw, int max_iterations) {
  std::vector<size_t> removed;
  while (true) {
    const std::deque<Pose> with = nodes_;
    size_t worst = edges_.size();
    double worst_off = 1;  // in units of max_xy or max_yaw, whichever is more
    for (size_t id : candidates) {
      if (!edges_[id]->live) continue;
      remove_edge(id);
      optimise(max_iterations);
      const Pose e = edge_error(id);
      const double off = std::max(std::hypot(e[0], e[1]) / max_xy, std::abs(e[2]) / max_yaw);
      if (off > worst_off) worst = id, worst_off = off;
      edges_[id]->live = true;  // back in, and the estimates of before
      ++live_edges_;
      nodes_ = with;
    }
    if (worst == edges_.size()) return removed;
    remove_edge(worst);
    removed.push_back(worst);
    optimise(max_iterations);
  }
}

PoseGraph2d::Pose PoseGraph2d::edge_error(size_t id) const {
  const Edge& e = *edges_[id];
  const Pose& a = nodes_[e.a];
  const Vec3 v = e.error(a, nodes_[e.b], std::cos(a[2]), std::sin(a[2]));
  return {v[0], v[1], v[2]};
}

double PoseGraph2d::edge_chi2(size_t id) const {
  const Edge& e = *edges_[id];
  return e.residual(nodes_[e.a], nodes_[e.b]).squaredNorm();
}

}  // namespace driftlab::slam::internal
