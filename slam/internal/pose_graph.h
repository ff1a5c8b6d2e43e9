// A 2D pose graph optimised by Levenberg-Marquardt on its sparse normal equations (Eigen's sparse Cholesky):
// nodes are poses (x, y, yaw), edges relative poses with their information matrices; the first node is held
// fixed. Deterministic (one thread). Not thread-safe: one caller. docs/slam.md says why neither Ceres nor MRPT's
// graph-slam optimiser.
#pragma once

#include <array>
#include <cstddef>
#include <deque>
#include <memory>
#include <vector>

namespace driftlab::slam::internal {

class PoseGraph2d {
 public:
  using Pose = std::array<double, 3>;         ///< x [m], y [m], yaw [rad]
  using Information = std::array<double, 9>;  ///< 3x3, row-major, over (x, y, yaw) of "b seen from a"

  PoseGraph2d();
  ~PoseGraph2d();
  PoseGraph2d(const PoseGraph2d&) = delete;
  PoseGraph2d& operator=(const PoseGraph2d&) = delete;

  /// Adds a node at its first estimate; returns its index (0, 1, ...). The first one is fixed.
  size_t add_node(const Pose& pose);
  /// Adds the measurement "b seen from a" with its information matrix (symmetric positive definite). Returns the
  /// edge's id. a and b: two different nodes (std::invalid_argument otherwise).
  size_t add_edge(size_t a, size_t b, const Pose& b_in_a, const Information& information);
  /// Takes an edge out of the problem (a loop closure found wrong).
  void remove_edge(size_t id);
  /// Levenberg-Marquardt from the current estimates, at most max_iterations.
  void optimise(int max_iterations);
  /// The squared Mahalanobis error of an edge at the current estimates (its chi2, without the loss); of a removed
  /// edge too.
  double edge_chi2(size_t id) const;
  /// Of the edges `candidates` (loop closures), takes out the one the optimised graph leaves with the largest chi2
  /// above max_chi2, optimises again (at most max_iterations), and repeats until none is above: the rest of the
  /// graph contradicts them. Returns the edges taken out, in that order, and their chi2 when taken out in `chi2`
  /// if given. Call on an optimised graph.
  std::vector<size_t> remove_contradicted(const std::vector<size_t>& candidates, double max_chi2, int max_iterations,
                                          std::vector<double>* chi2 = nullptr);

  /// How far the current estimates are from an edge's measurement: "b seen from a" less it, in a's frame (x, y,
  /// yaw wrapped); of a removed edge too.
  Pose edge_error(size_t id) const;
  /// Of the edges `candidates`, each in turn is taken out and the graph optimised without it (at most
  /// max_iterations), then put back with the estimates of before; the one the rest of the graph left furthest
  /// beyond max_xy [m] or max_yaw [rad] from its measurement (edge_error) stays out, and the rest are judged
  /// again. remove_contradicted judges an edge with it in, where the graph may bend to keep it; this, by what the
  /// others say of it. Worst first: a wrong edge in bends the graph where a right one is judged. Returns the edges
  /// taken out, in that order. Call on an optimised graph; one optimisation per candidate and round.
  std::vector<size_t> leave_out_contradicted(const std::vector<size_t>& candidates, double max_xy, double max_yaw,
                                             int max_iterations);

  const Pose& node(size_t i) const { return nodes_[i]; }
  void set_node(size_t i, const Pose& pose) { nodes_[i] = pose; }
  size_t size() const { return nodes_.size(); }
  size_t edges() const { return live_edges_; }

 private:
  struct Edge;
  double cost(const std::deque<Pose>& nodes) const;  ///< half the sum of the squared whitened residuals
  std::deque<Pose> nodes_;
  std::vector<std::unique_ptr<Edge>> edges_;
  size_t live_edges_ = 0;
};

/// A diagonal information: standard deviations sigma_xy [m] (each of x and y) and sigma_yaw [rad].
PoseGraph2d::Information diagonal_information(double sigma_xy, double sigma_yaw);

}  // namespace driftlab::slam::internal
