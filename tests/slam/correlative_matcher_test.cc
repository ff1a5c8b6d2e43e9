// The correlative matcher of the 2D SLAM's far loop search (slam/internal/correlative_matcher.h): it finds the
// pose a place was seen from metres away from the guess, its branch and bound returns what scoring every pose of
// the window would, and the second search (the best pose away from the first) tells a room from a corridor, which
// is what the loop closure's ambiguity test (loop_ambiguity, 90%) relies on.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "slam/internal/correlative_matcher.h"

namespace driftlab::slam::internal {
namespace {

struct Pose {
  double x, y, yaw;
};

/// Points every 2 cm along the segment a-b.
void wall(std::vector<Point2f>& out, double ax, double ay, double bx, double by) {
  const double length = std::hypot(bx - ax, by - ay);
  const int n = static_cast<int>(length / 0.02);
  for (int i = 0; i <= n; ++i) {
    const double t = static_cast<double>(i) / n;
    out.push_back({static_cast<float>(ax + t * (bx - ax)), static_cast<float>(ay + t * (by - ay))});
  }
}

/// A 6 x 4 m room with a notch in one wall and a 0.4 m pillar: no two poses see it alike.
std::vector<Point2f> room() {
  std::vector<Point2f> p;
  wall(p, 0, 0, 6, 0);
  wall(p, 6, 0, 6, 4);
  wall(p, 6, 4, 3.5, 4), wall(p, 3.5, 4, 3.5, 3.2), wall(p, 3.5, 3.2, 2.5, 3.2), wall(p, 2.5, 3.2, 2.5, 4);
  wall(p, 2.5, 4, 0, 4);
  wall(p, 0, 4, 0, 0);
  wall(p, 1.5, 1.2, 1.9, 1.2), wall(p, 1.9, 1.2, 1.9, 1.6), wall(p, 1.9, 1.6, 1.5, 1.6), wall(p, 1.5, 1.6, 1.5, 1.2);
  return p;
}

/// A featureless corridor 2 m wide and 30 m long, along x.
std::vector<Point2f> corridor() {
  std::vector<Point2f> p;
  wall(p, 0, 0, 30, 0);
  wall(p, 0, 2, 30, 2);
  return p;
}

/// What a robot at `at` sees of `map` within `reach` [m], in its own frame.
std::vector<Point2f> seen_from(const std::vector<Point2f>& map, const Pose& at, double reach) {
  std::vector<Point2f> out;
  const double c = std::cos(at.yaw), s = std::sin(at.yaw);
  for (const auto& p : map) {
    const double dx = p.x - at.x, dy = p.y - at.y;
    if (std::hypot(dx, dy) > reach) continue;
    out.push_back({static_cast<float>(c * dx + s * dy), static_cast<float>(-s * dx + c * dy)});
  }
  return out;
}

constexpr double kResolution = 0.1, kMargin = 1.0;  // the scan graph's (loop_grid_resolution, its margin)
constexpr int kLevels = 4;                          // loop_grid_levels

// The robot is 0.7 m, 0.4 m and 7 degrees from where the guess puts it, as after a long excursion: the match
// lands within a cell (0.1 m) and a turn step of the truth, scoring near the full likelihood.
TEST(CorrelativeMatcher, FindsThePoseFarFromTheGuess) {
  const auto map = room();
  const CorrelativeMatcher matcher(map, kResolution, kMargin, kLevels);
  const Pose truth{3.0, 2.0, 0.3};
  const auto points = seen_from(map, truth, 2.8);
  ASSERT_GT(points.size(), 200u);
  const auto m = matcher.match(points, truth.x - 0.7, truth.y + 0.4, truth.yaw - 0.12, 1.0, 0.2);
  EXPECT_NEAR(m.x, truth.x, kResolution);
  EXPECT_NEAR(m.y, truth.y, kResolution);
  EXPECT_NEAR(m.yaw, truth.yaw, 0.035);  // the turn step: points 2.8 m away moved by about a cell
  EXPECT_GT(m.score, 0.8);
  EXPECT_NEAR(m.score, matcher.score(points, m.x, m.y, m.yaw), 1e-9);
}

/// The best score over every pose of a window, scored one by one: the translations on the grid's cells, turns in
/// steps of 0.035 rad (the matcher's step for points within 2.86 m at 0.1 m cells).
double best_of_every_pose(const CorrelativeMatcher& matcher, const std::vector<Point2f>& points, const Pose& guess,
                          double window, double window_yaw) {
  const double step = 0.035;
  const int n = static_cast<int>(std::ceil(window / kResolution));
  const int n_yaw = static_cast<int>(std::ceil(window_yaw / step));
  double best = 0;
  for (int k = -n_yaw; k <= n_yaw; ++k) {
    for (int ty = -n; ty <= n; ++ty) {
      for (int tx = -n; tx <= n; ++tx) {
        best = std::max(
            best, matcher.score(points, guess.x + tx * kResolution, guess.y + ty * kResolution, guess.yaw + k * step));
      }
    }
  }
  return best;
}

// Branch and bound only skips poses whose bound is beaten: scoring every pose of the window finds nothing better.
// In the corridor the window reaches past the grid's lower edge, where a coarse cell left of or below the grid
// still covers cells of it (its bound once counted those points as zero, and the search missed the place by 5
// degrees). The tolerance is for a point on a cell's edge, which rounding may put in either cell (a few of the
// hundreds of points changing cell by one move the mean likelihood by well under 0.01).
TEST(CorrelativeMatcher, BranchAndBoundFindsWhatScoringEveryPoseFinds) {
  struct Case {
    const char* name;
    std::vector<Point2f> map;
    Pose truth, guess;
    double reach, window, window_yaw;
  };
  for (const Case& c : {Case{"room", room(), {2.8, 2.1, 0.25}, {2.5, 2.3, 0.1}, 2.5, 0.6, 0.2},
                        Case{"corridor", corridor(), {15.0, 1.0, 0.0}, {14.0, 1.2, 0.05}, 2.8, 3.0, 0.35}}) {
    SCOPED_TRACE(c.name);
    const CorrelativeMatcher matcher(c.map, kResolution, kMargin, kLevels);
    const auto points = seen_from(c.map, c.truth, c.reach);
    const auto m = matcher.match(points, c.guess.x, c.guess.y, c.guess.yaw, c.window, c.window_yaw);
    const double best = best_of_every_pose(matcher, points, c.guess, c.window, c.window_yaw);
    EXPECT_GT(best, 0.8);  // the truth is in the window: most points on a wall
    EXPECT_NEAR(m.score, best, 0.01);
  }
}

// The ambiguity test: the best pose 0.5 m or more from the first. In the room it scores far below the first
// (under the 90% at which the scan graph calls a place ambiguous); in the corridor every place along it scores
// alike, so it is at 90% or more, and the excluded disc is respected.
TEST(CorrelativeMatcher, TheSecondBestTellsARoomFromACorridor) {
  {
    const auto map = room();
    const CorrelativeMatcher matcher(map, kResolution, kMargin, kLevels);
    const auto points = seen_from(map, {3.0, 2.0, 0.3}, 2.8);
    const auto best = matcher.match(points, 3.2, 1.8, 0.25, 1.5, 0.35);
    const auto other = matcher.match(points, 3.2, 1.8, 0.25, 1.5, 0.35, &best, 0.5);
    EXPECT_GT(std::hypot(other.x - best.x, other.y - best.y), 0.5);
    EXPECT_LT(other.score, 0.9 * best.score);
  }
  {
    const auto map = corridor();
    const CorrelativeMatcher matcher(map, kResolution, kMargin, kLevels);
    const auto points = seen_from(map, {15.0, 1.0, 0.0}, 2.8);
    const auto best = matcher.match(points, 14.0, 1.2, 0.05, 3.0, 0.35);
    EXPECT_NEAR(best.y, 1.0, kResolution);  // across the corridor it is pinned down ...
    EXPECT_NEAR(best.yaw, 0.0, 0.035);      // ... and in heading
    const auto other = matcher.match(points, 14.0, 1.2, 0.05, 3.0, 0.35, &best, 0.5);
    EXPECT_GT(std::hypot(other.x - best.x, other.y - best.y), 0.5);
    EXPECT_GE(other.score, 0.9 * best.score);
  }
}

// The ambiguity test asks only whether some place away from the best scores 90% of it: with `at_least` the search
// returns a pose that scores that much (its score the grid's at that pose, outside the excluded disc) when the full
// search finds one, and a score of 0 when the full search's best there is below it; in the room and the corridor,
// at thresholds either side of the full search's answer.
TEST(CorrelativeMatcher, AtLeastAnswersWhetherSomePoseScoresThat) {
  for (const bool in_corridor : {false, true}) {
    SCOPED_TRACE(in_corridor ? "corridor" : "room");
    const auto map = in_corridor ? corridor() : room();
    const Pose truth = in_corridor ? Pose{15.0, 1.0, 0.0} : Pose{3.0, 2.0, 0.3};
    const Pose guess = in_corridor ? Pose{14.0, 1.2, 0.05} : Pose{3.2, 1.8, 0.25};
    const double window = in_corridor ? 3.0 : 1.5;
    const CorrelativeMatcher matcher(map, kResolution, kMargin, kLevels);
    const auto points = seen_from(map, truth, 2.8);
    const auto best = matcher.match(points, guess.x, guess.y, guess.yaw, window, 0.35);
    const auto other = matcher.match(points, guess.x, guess.y, guess.yaw, window, 0.35, &best, 0.5);
    ASSERT_GT(other.score, 0.1);
    for (const double share : {0.5, 0.9, 1.0, 1.001, 1.2}) {
      const double at_least = share * other.score;
      const auto found = matcher.match(points, guess.x, guess.y, guess.yaw, window, 0.35, &best, 0.5, at_least);
      if (at_least <= other.score) {
        EXPECT_GE(found.score, at_least) << share;
        EXPECT_NEAR(found.score, matcher.score(points, found.x, found.y, found.yaw), 1e-9) << share;
        EXPECT_GT(std::hypot(found.x - best.x, found.y - best.y), 0.5) << share;
      } else {
        EXPECT_EQ(found.score, 0.0) << share;
      }
    }
    // The scan graph's question, answered the same either way.
    const double bar = 0.9 * best.score;
    const auto answer = matcher.match(points, guess.x, guess.y, guess.yaw, window, 0.35, &best, 0.5, bar);
    EXPECT_EQ(answer.score >= bar, other.score >= bar);
    EXPECT_EQ(other.score >= bar, in_corridor);
  }
}

// Nothing to match, or nothing to match against: the guess comes back with a score of zero.
TEST(CorrelativeMatcher, NoPointsScoreZero) {
  const CorrelativeMatcher matcher(room(), kResolution, kMargin, kLevels);
  const auto none = matcher.match({}, 1.0, 2.0, 0.5, 1.0, 0.2);
  EXPECT_EQ(none.score, 0.0);
  EXPECT_EQ(none.x, 1.0);
  const CorrelativeMatcher empty({}, kResolution, kMargin, kLevels);
  EXPECT_EQ(empty.match(seen_from(room(), {3, 2, 0}, 2.8), 1.0, 2.0, 0.5, 1.0, 0.2).score, 0.0);
  EXPECT_EQ(empty.score(seen_from(room(), {3, 2, 0}, 2.8), 1.0, 2.0, 0.5), 0.0);
}

}  // namespace
}  // namespace driftlab::slam::internal
