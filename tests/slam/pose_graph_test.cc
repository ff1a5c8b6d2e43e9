// The 2D pose graph's back end (slam/internal/pose_graph.h): a closure the rest of the graph contradicts is
// taken out again, and the graph optimised without it ends where the right closures put it.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "slam/internal/pose_graph.h"

namespace driftlab::slam::internal {
namespace {

using Pose = PoseGraph2d::Pose;

/// b seen from a.
Pose relative(const Pose& a, const Pose& b) {
  const double c = std::cos(a[2]), s = std::sin(a[2]), dx = b[0] - a[0], dy = b[1] - a[1];
  return {c * dx + s * dy, -s * dx + c * dy, std::remainder(b[2] - a[2], 2 * M_PI)};
}

// 40 poses around a 10 m square, joined by exact steps (2 cm and 0.4 degrees, the scan graph's), started from an
// estimate whose heading drifted 0.5 degrees a step (the square does not close by 3.5 m). Three closures are right;
// a fourth, joining two places across the square, is 2 m and 20 degrees off, as a match in a row of identical
// rooms may be.
TEST(PoseGraph2d, AClosureTheOthersContradictIsTakenOutAndTheRestStand) {
  std::vector<Pose> truth;
  for (int side = 0; side < 4; ++side) {
    for (int i = 0; i < 10; ++i) {
      const double yaw = side * M_PI / 2, along = i;
      const double x0[4] = {0, 10, 10, 0}, y0[4] = {0, 0, 10, 10};
      truth.push_back({x0[side] + along * std::cos(yaw), y0[side] + along * std::sin(yaw), yaw});
    }
  }
  PoseGraph2d graph;
  Pose estimate = truth[0];
  graph.add_node(estimate);
  const auto info = diagonal_information(0.02, 0.007);
  for (size_t i = 1; i < truth.size(); ++i) {
    const Pose step = relative(truth[i - 1], truth[i]);
    const double drifted = estimate[2] + 0.0087;  // 0.5 degrees a step
    estimate = {estimate[0] + step[0] * std::cos(drifted) - step[1] * std::sin(drifted),
                estimate[1] + step[0] * std::sin(drifted) + step[1] * std::cos(drifted), drifted + step[2]};
    graph.add_node(estimate);
    graph.add_edge(i - 1, i, step, info);
  }
  std::vector<size_t> closures;
  for (auto [a, b] : {std::pair<size_t, size_t>{39, 0}, {30, 10}, {25, 5}}) {
    closures.push_back(graph.add_edge(a, b, relative(truth[a], truth[b]), info));
  }
  Pose wrong = relative(truth[35], truth[15]);
  wrong[0] += 2.0, wrong[2] += 0.35;
  const size_t bad = graph.add_edge(35, 15, wrong, info);
  closures.push_back(bad);
  graph.optimise(100);
  double before = 0;  // the bad closure bends the graph: metres off
  for (size_t i = 0; i < truth.size(); ++i) {
    before = std::max(before, std::hypot(graph.node(i)[0] - truth[i][0], graph.node(i)[1] - truth[i][1]));
  }
  EXPECT_GT(before, 0.3);

  // loop_max_chi2 (20): a right closure's chi2 at the optimum is a few units (3 degrees of freedom).
  const auto removed = graph.remove_contradicted(closures, 20, 100);
  EXPECT_EQ(removed, std::vector<size_t>{bad});
  EXPECT_EQ(graph.edges(), truth.size() - 1 + 3);
  for (size_t i = 0; i < truth.size(); ++i) {
    EXPECT_NEAR(graph.node(i)[0], truth[i][0], 0.01) << i;
    EXPECT_NEAR(graph.node(i)[1], truth[i][1], 0.01) << i;
    EXPECT_NEAR(std::remainder(graph.node(i)[2] - truth[i][2], 2 * M_PI), 0, 0.001) << i;
  }
  // Nothing more to take out: the right closures agree with the graph.
  EXPECT_TRUE(graph.remove_contradicted(closures, 20, 100).empty());
}

}  // namespace
}  // namespace driftlab::slam::internal
