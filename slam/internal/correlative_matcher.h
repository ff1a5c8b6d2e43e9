// Correlative scan matching with branch and bound (E. Olson, "Real-time correlative scan matching", ICRA 2009;
// W. Hess et al., "Real-time loop closure in 2D LIDAR SLAM", ICRA 2016): the pose of a set of points against a
// reference set that scores best, over a whole search window, on a likelihood grid of the reference. ICP finds the
// optimum nearest its start; this finds the best one in the window, which is what closing a loop after metres of
// drift needs. The search is exact: coarse levels of the grid (maxima over 2^d x 2^d cells) bound the score of
// every pose they cover, and a branch is only opened while its bound beats the best pose found.
// Written here because no Debian package has one (MRPT's map aligners are ICP, feature-RANSAC and particle
// based; Cartographer and Karto, which have one, are not packaged). Deterministic; not thread-safe.
#pragma once

#include <cstddef>
#include <vector>

namespace driftlab::slam::internal {

struct Point2f {
  float x = 0, y = 0;
};

class CorrelativeMatcher {
 public:
  /// The likelihood grid of `reference`: exp(-d^2 / (2 r^2)) of the distance d to the nearest point, at
  /// resolution r [m], over the points and `margin` [m] around them; `levels` coarse levels above it.
  CorrelativeMatcher(const std::vector<Point2f>& reference, double resolution, double margin, int levels);
  ~CorrelativeMatcher();
  CorrelativeMatcher(const CorrelativeMatcher&) = delete;
  CorrelativeMatcher& operator=(const CorrelativeMatcher&) = delete;

  struct Match {
    double x = 0, y = 0, yaw = 0;  ///< the best pose in the window
    double score = 0;              ///< its mean likelihood over the points [0, 1]
  };
  /// The best pose of `points` (in their own frame) within guess +- window_xy [m] (in x and y) and +- window_yaw
  /// [rad]; translations on the grid's cells, turns moving the farthest points by about a cell. Poses within
  /// `exclude_xy` [m] of `exclude` (when given) are left out: the best pose elsewhere, to tell a unique place from
  /// an ambiguous one. With `at_least` > 0, a search that only needs to know whether some pose scores at least
  /// that: the first such pose it finds (not always the best), or a score of 0 when there is none, which is
  /// certain once every branch left is bounded below it.
  Match match(const std::vector<Point2f>& points, double guess_x, double guess_y, double guess_yaw, double window_xy,
              double window_yaw, const Match* exclude = nullptr, double exclude_xy = 0, double at_least = 0) const;

  /// Mean likelihood of `points` at a pose (on the finest level).
  double score(const std::vector<Point2f>& points, double x, double y, double yaw) const;

 private:
  /// Cell (x, y) of a level, x in -1..width_ and y in -1..height_ (the border's cells are empty).
  size_t at(int x, int y) const {
    return static_cast<size_t>(y + 1) * static_cast<size_t>(width_ + 2) + static_cast<size_t>(x + 1);
  }
  double resolution_;
  double x0_ = 0, y0_ = 0;
  int width_ = 0, height_ = 0;
  std::vector<std::vector<float>> levels_;  ///< [0]: the grid; [d]: maxima over 2^d x 2^d cells from each cell
};

}  // namespace driftlab::slam::internal
