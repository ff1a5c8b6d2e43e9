// The 2D pose graph's back end (slam/internal/pose_graph.h): its optimum is Ceres's on the same graph, and a
// closure the rest of the graph contradicts is taken out again (found with it in, or by leaving it out), the graph
// optimised without it ending where the right closures put it.
#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
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

// A lap of a 25 m square in 0.5 m steps (200 poses, exact steps) and the first 60 steps of a second: five right
// closures tie the second lap's 230-234 to the first's 30-34, and one lone closure ties pose 195 to pose 0 (a
// lookalike stretch of corridor: 3 m along it and 11 degrees off, as MIT Killian Court's far test at 619 s from
// 15 s was). Its cycle runs through 65 steps, and with every closure in, the optimum bends them (5 cm and 0.2
// degrees each) rather than leave it far off: its chi2 stays under loop_max_chi2 and remove_contradicted keeps
// it. Left out, the rest of the graph puts pose 195 where the truth has it, 3 m from the lone closure, where a
// closure alone may move the estimate 0.5 m. A lone right closure (pose 100 to 150) stays.
TEST(PoseGraph2d, ALoneClosureTheOthersContradictIsFoundByLeavingItOut) {
  std::vector<Pose> truth;
  for (int i = 0; i < 260; ++i) {
    const int side = (i / 50) % 4, along = i % 50;
    const double x0[4] = {0, 25, 25, 0}, y0[4] = {0, 0, 25, 25}, yaw = side * M_PI / 2;
    truth.push_back({x0[side] + 0.5 * along * std::cos(yaw), y0[side] + 0.5 * along * std::sin(yaw), yaw});
  }
  PoseGraph2d graph;
  const auto info = diagonal_information(0.02, 0.007);
  for (size_t i = 0; i < truth.size(); ++i) {
    graph.add_node(truth[i]);
    if (i > 0) graph.add_edge(i - 1, i, relative(truth[i - 1], truth[i]), info);
  }
  std::vector<size_t> closures;
  for (size_t i = 0; i < 5; ++i)
    closures.push_back(graph.add_edge(30 + i, 230 + i, relative(truth[30 + i], truth[230 + i]), info));
  const size_t right = graph.add_edge(100, 150, relative(truth[100], truth[150]), info);
  Pose wrong = relative(truth[0], truth[195]);
  wrong[0] += 3.0, wrong[2] += 0.2;
  const size_t bad = graph.add_edge(0, 195, wrong, info);
  closures.push_back(right);
  closures.push_back(bad);
  graph.optimise(100);
  double bent = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    bent = std::max(bent, std::hypot(graph.node(i)[0] - truth[i][0], graph.node(i)[1] - truth[i][1]));
  }
  std::printf("with every closure in: poses up to %.2f m off, the lone wrong closure's chi2 %.1f\n", bent,
              graph.edge_chi2(bad));
  EXPECT_GT(bent, 1.0);
  ASSERT_TRUE(graph.remove_contradicted(closures, 20, 100).empty());  // what the test is about: kept with it in

  // loop_confirm_xy and loop_confirm_yaw (0.5 m, 0.09 rad): the most a closure that went in alone moved the estimate
  EXPECT_EQ(graph.leave_out_contradicted({right, bad}, 0.5, 0.09, 100), std::vector<size_t>{bad});
  const Pose off = graph.edge_error(bad);
  std::printf("left out, it is %.2f m and %.1f deg off\n", std::hypot(off[0], off[1]), off[2] * 180 / M_PI);
  EXPECT_NEAR(std::hypot(off[0], off[1]), 3.0, 0.05);  // the truth's place, and the lookalike's 3 m and 0.2 rad
  EXPECT_NEAR(std::abs(off[2]), 0.2, 0.005);
  EXPECT_EQ(graph.edges(), truth.size() - 1 + 6);
  for (size_t i = 0; i < truth.size(); ++i) {
    EXPECT_NEAR(graph.node(i)[0], truth[i][0], 0.01) << i;
    EXPECT_NEAR(graph.node(i)[1], truth[i][1], 0.01) << i;
    EXPECT_NEAR(std::remainder(graph.node(i)[2] - truth[i][2], 2 * M_PI), 0, 0.001) << i;
  }
  // The right one, left out in turn, is where the rest put it: back in, and the graph as it was.
  EXPECT_TRUE(graph.leave_out_contradicted({right}, 0.5, 0.09, 100).empty());
  EXPECT_EQ(graph.edges(), truth.size() - 1 + 6);
}

/// Ceres's model of the same edge (what the pose graph was optimised with until 2026-12-01): L^T (b seen from a -
/// z), information = L L^T, differentiated by dual numbers.
struct CeresEdge {
  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    const T c = ceres::cos(a[2]), s = ceres::sin(a[2]), dx = b[0] - a[0], dy = b[1] - a[1];
    const T yaw = b[2] - a[2] - T(z[2]);
    const T e[3] = {c * dx + s * dy - z[0], -s * dx + c * dy - z[1],
                    yaw - T(2 * M_PI) * ceres::floor((yaw + T(M_PI)) / T(2 * M_PI))};
    for (size_t i = 0; i < 3; ++i) r[i] = lt[3 * i] * e[0] + lt[3 * i + 1] * e[1] + lt[3 * i + 2] * e[2];
    return true;
  }
  Pose z;
  std::array<double, 9> lt;  ///< L^T, row-major (upper triangular)
};

// A robot driving 300 steps of 0.3 m round a 3 m square (seven laps and a half), its odometry 2 cm and 0.6 degrees
// wrong a step; 40 closures one or two laps back, as wrong as a scan match (1 cm, 0.3 degrees), two of them with a full
// information matrix; the estimate starts as the odometry integrated, metres off by the third lap. Optimised by
// ours and by Ceres (SPARSE_NORMAL_CHOLESKY, the options the module used), both from that start: the same
// minimum. Both stop when a step changes the cost by less than 1e-6 of it, so each ends within about that of the
// minimum's cost: ours must not end higher than Ceres's by more. The minimum is flat along the chain: poses a
// millimetre apart differ in cost by 1e-7 of it (ours and Ceres's end 0.5 mm and 0.007 degrees apart), so the
// poses must agree to 2 mm and 0.03 degrees. A wrong Jacobian or damping ends far from both: the heading's
// derivative of the first residual with a sign flipped fails both tests, the trust radius shrunk where it should
// grow ends at 1.16 times the cost, 0.45 m away.
TEST(PoseGraph2d, FindsTheMinimumCeresFinds) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, 1);
  std::vector<Pose> truth;
  double x = 0, y = 0, yaw = 0;
  for (int i = 0; i < 300; ++i) {
    truth.push_back({x, y, yaw});
    x += 0.3 * std::cos(yaw), y += 0.3 * std::sin(yaw);
    if (i % 10 == 9) yaw = std::remainder(yaw + M_PI / 2, 2 * M_PI);  // a corner every 3 m
  }
  PoseGraph2d ours;
  ceres::Problem::Options po;
  ceres::Problem problem(po);
  std::vector<std::array<double, 3>> theirs;
  theirs.reserve(truth.size());
  Pose estimate = truth[0];
  std::vector<Pose> start;
  auto edge = [&](size_t a, size_t b, const Pose& z, const PoseGraph2d::Information& info) {
    ours.add_edge(a, b, z, info);
    const Eigen::Matrix3d m = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(info.data());
    const Eigen::Matrix3d u = Eigen::LLT<Eigen::Matrix3d>(m).matrixU();
    CeresEdge e{z, {}};
    for (int i = 0; i < 9; ++i) e.lt[static_cast<size_t>(i)] = u(i / 3, i % 3);
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CeresEdge, 3, 3, 3>(new CeresEdge(e)), nullptr,
                             theirs[a].data(), theirs[b].data());
  };
  for (size_t i = 0; i < truth.size(); ++i) {
    if (i > 0) {
      Pose step = relative(truth[i - 1], truth[i]);
      step[0] += 0.02 * noise(rng), step[1] += 0.02 * noise(rng), step[2] += 0.01 * noise(rng);
      estimate = {estimate[0] + step[0] * std::cos(estimate[2]) - step[1] * std::sin(estimate[2]),
                  estimate[1] + step[0] * std::sin(estimate[2]) + step[1] * std::cos(estimate[2]),
                  estimate[2] + step[2]};
    }
    ours.add_node(estimate);
    theirs.push_back(estimate);
    problem.AddParameterBlock(theirs.back().data(), 3);
    start.push_back(estimate);
    if (i > 0) edge(i - 1, i, relative(start[i - 1], start[i]), diagonal_information(0.02, 0.01));
  }
  problem.SetParameterBlockConstant(theirs[0].data());
  for (int k = 0; k < 40; ++k) {
    const size_t b = 100 + static_cast<size_t>(k) * 5, a = b - (k % 2 == 0 ? 40 : 80);  // one or two laps back
    Pose z = relative(truth[a], truth[b]);
    z[0] += 0.01 * noise(rng), z[1] += 0.01 * noise(rng), z[2] += 0.005 * noise(rng);
    PoseGraph2d::Information info = diagonal_information(0.01, 0.005);
    if (k < 2) info = {8000, 3000, 500, 3000, 6000, -400, 500, -400, 30000};  // correlated, positive definite
    edge(a, b, z, info);
  }
  ours.optimise(100);
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  o.max_num_iterations = 100;
  o.num_threads = 1;
  o.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
  ASSERT_EQ(summary.termination_type, ceres::CONVERGENCE) << summary.BriefReport();
  double moved = 0, apart = 0, apart_yaw = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    moved = std::max(moved, std::hypot(start[i][0] - theirs[i][0], start[i][1] - theirs[i][1]));
    apart = std::max(apart, std::hypot(ours.node(i)[0] - theirs[i][0], ours.node(i)[1] - theirs[i][1]));
    apart_yaw = std::max(apart_yaw, std::abs(std::remainder(ours.node(i)[2] - theirs[i][2], 2 * M_PI)));
  }
  double cost = 0;
  for (size_t e = 0; e < ours.edges(); ++e) cost += 0.5 * ours.edge_chi2(e);
  std::printf(
      "the optimum moved the start by up to %.3f m; cost %.9g (from %.7g), Ceres's %.9g; apart by %.2e m, "
      "%.2e rad\n",
      moved, cost, summary.initial_cost, summary.final_cost, apart, apart_yaw);
  EXPECT_GT(moved, 0.5);  // the closures had work to do
  EXPECT_LE(cost, summary.final_cost * (1 + 1e-6));
  EXPECT_LT(apart, 2e-3);
  EXPECT_LT(apart_yaw, 5e-4);
}

}  // namespace
}  // namespace driftlab::slam::internal
