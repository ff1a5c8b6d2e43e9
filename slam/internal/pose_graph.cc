#include "slam/internal/pose_graph.h"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <cmath>

namespace driftlab::slam::internal {
namespace {

template <typename T>
T wrap_angle(const T& a) {
  const T two_pi(2 * M_PI);
  return a - two_pi * ceres::floor((a + T(M_PI)) / two_pi);
}

/// The residual of "b seen from a" = z, whitened: L^T (b seen from a - z), where information = L L^T.
struct RelativePoseError {
  RelativePoseError(const PoseGraph2d::Pose& z, const PoseGraph2d::Information& information) : z_(z) {
    const Eigen::Matrix3d info = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(information.data());
    const Eigen::Matrix3d lt = Eigen::LLT<Eigen::Matrix3d>(0.5 * (info + info.transpose())).matrixU();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) w_[i * 3 + j] = lt(i, j);
    }
  }
  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    const T c = ceres::cos(a[2]), s = ceres::sin(a[2]);
    const T dx = b[0] - a[0], dy = b[1] - a[1];
    const T e[3] = {c * dx + s * dy - z_[0], -s * dx + c * dy - z_[1], wrap_angle(b[2] - a[2] - T(z_[2]))};
    for (size_t i = 0; i < 3; ++i) r[i] = w_[3 * i] * e[0] + w_[3 * i + 1] * e[1] + w_[3 * i + 2] * e[2];
    return true;
  }
  PoseGraph2d::Pose z_;
  std::array<double, 9> w_{};  ///< L^T, row-major
};

ceres::Problem::Options problem_options() {
  ceres::Problem::Options o;
  o.enable_fast_removal = true;  // loop edges found wrong are taken out again
  return o;
}

}  // namespace

struct PoseGraph2d::Edge {
  size_t a, b;
  RelativePoseError error;
  ceres::ResidualBlockId id = nullptr;
};

struct PoseGraph2d::Problem {
  ceres::Problem problem{problem_options()};
};

PoseGraph2d::PoseGraph2d() : problem_(std::make_unique<Problem>()) {}
PoseGraph2d::~PoseGraph2d() = default;

PoseGraph2d::Information diagonal_information(double sigma_xy, double sigma_yaw) {
  const double xy = 1 / (sigma_xy * sigma_xy);
  return {xy, 0, 0, 0, xy, 0, 0, 0, 1 / (sigma_yaw * sigma_yaw)};
}

size_t PoseGraph2d::add_node(const Pose& pose) {
  nodes_.push_back(pose);
  problem_->problem.AddParameterBlock(nodes_.back().data(), 3);
  if (nodes_.size() == 1) problem_->problem.SetParameterBlockConstant(nodes_.back().data());
  return nodes_.size() - 1;
}

size_t PoseGraph2d::add_edge(size_t a, size_t b, const Pose& b_in_a, const Information& information) {
  auto edge = std::make_unique<Edge>(Edge{a, b, RelativePoseError(b_in_a, information)});
  auto* cost = new ceres::AutoDiffCostFunction<RelativePoseError, 3, 3, 3>(new RelativePoseError(edge->error));
  edge->id = problem_->problem.AddResidualBlock(cost, nullptr, nodes_[a].data(), nodes_[b].data());
  edges_.push_back(std::move(edge));
  ++live_edges_;
  return edges_.size() - 1;
}

void PoseGraph2d::remove_edge(size_t id) {
  if (edges_[id]->id == nullptr) return;
  problem_->problem.RemoveResidualBlock(edges_[id]->id);
  edges_[id]->id = nullptr;
  --live_edges_;
}

void PoseGraph2d::optimise(int max_iterations) {
  if (live_edges_ == 0) return;
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  o.max_num_iterations = max_iterations;
  o.num_threads = 1;  // deterministic
  o.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem_->problem, &summary);
}

std::vector<size_t> PoseGraph2d::remove_contradicted(const std::vector<size_t>& candidates, double max_chi2,
                                                     int max_iterations, std::vector<double>* chi2) {
  std::vector<size_t> removed;
  while (true) {
    size_t worst = edges_.size();
    double worst_chi2 = max_chi2;
    for (size_t id : candidates) {
      if (edges_[id]->id == nullptr) continue;
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

double PoseGraph2d::edge_chi2(size_t id) const {
  const Edge& e = *edges_[id];
  double r[3];
  e.error(nodes_[e.a].data(), nodes_[e.b].data(), r);
  return r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
}

}  // namespace driftlab::slam::internal
