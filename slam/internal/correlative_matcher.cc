#include "slam/internal/correlative_matcher.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>

namespace driftlab::slam::internal {

namespace {
/// Grids of earlier matchers, kept for the next: a far loop test's grid over a long-range laser's reference can
/// hold millions of cells a level, and freeing and allocating them for every test costs more in page faults and
/// zeroing than the matching itself.
thread_local std::vector<std::vector<float>> spare_grids;
constexpr size_t kSpareGrids = 8;

std::vector<float> grid_of(size_t cells) {
  if (spare_grids.empty()) return std::vector<float>(cells);
  std::vector<float> grid = std::move(spare_grids.back());
  spare_grids.pop_back();
  grid.resize(cells);
  return grid;
}
}  // namespace

CorrelativeMatcher::~CorrelativeMatcher() {
  for (auto& level : levels_) {
    if (spare_grids.size() < kSpareGrids) spare_grids.push_back(std::move(level));
  }
}

CorrelativeMatcher::CorrelativeMatcher(const std::vector<Point2f>& reference, double resolution, double margin,
                                       int levels)
    : resolution_(resolution) {
  if (reference.empty()) return;
  float min_x = reference[0].x, max_x = min_x, min_y = reference[0].y, max_y = min_y;
  for (const auto& p : reference) {
    min_x = std::min(min_x, p.x), max_x = std::max(max_x, p.x);
    min_y = std::min(min_y, p.y), max_y = std::max(max_y, p.y);
  }
  x0_ = min_x - margin;
  y0_ = min_y - margin;
  width_ = static_cast<int>(std::ceil((max_x - min_x + 2 * margin) / resolution)) + 1;
  height_ = static_cast<int>(std::ceil((max_y - min_y + 2 * margin) / resolution)) + 1;
  // Each level with a border of empty cells around it, where lookups off the grid land (score() and bound()).
  const auto cells = static_cast<size_t>(width_ + 2) * static_cast<size_t>(height_ + 2);
  levels_.push_back(grid_of(cells));
  auto& grid = levels_[0];
  std::fill(grid.begin(), grid.end(), 0.0f);
  constexpr int r = 3;  // cells: the likelihood is 1% three standard deviations away
  const double k = -1 / (2 * resolution * resolution);
  // exp(k (dx^2 + dy^2)) as exp(k dx^2) exp(k dy^2): 2 (2r + 1) exponentials a point instead of (2r + 1)^2.
  std::array<double, 2 * r + 1> ex{}, ey{};
  for (const auto& p : reference) {
    const int cx = static_cast<int>(std::floor((p.x - x0_) / resolution));
    const int cy = static_cast<int>(std::floor((p.y - y0_) / resolution));
    const int x_from = std::max(0, cx - r), x_to = std::min(width_ - 1, cx + r);
    const int y_from = std::max(0, cy - r), y_to = std::min(height_ - 1, cy + r);
    for (int ix = x_from; ix <= x_to; ++ix) {
      const double dx = x0_ + (ix + 0.5) * resolution - p.x;
      ex[static_cast<size_t>(ix - x_from)] = std::exp(k * dx * dx);
    }
    for (int iy = y_from; iy <= y_to; ++iy) {
      const double dy = y0_ + (iy + 0.5) * resolution - p.y;
      ey[static_cast<size_t>(iy - y_from)] = std::exp(k * dy * dy);
    }
    for (int iy = y_from; iy <= y_to; ++iy) {
      float* row = &grid[at(x_from, iy)];
      const double wy = ey[static_cast<size_t>(iy - y_from)];
      for (int ix = x_from; ix <= x_to; ++ix) {
        float& cell = row[ix - x_from];
        cell = std::max(cell, static_cast<float>(wy * ex[static_cast<size_t>(ix - x_from)]));
      }
    }
  }
  // Level d at a cell: the maximum of the grid over the 2^d x 2^d cells from it (an upper bound for each of them).
  for (int d = 1; d <= levels; ++d) {
    const auto& below = levels_.back();
    const int h = 1 << (d - 1);
    std::vector<float> level = grid_of(cells);
    std::fill(level.begin(), level.end(), 0.0f);  // the border (and the rest, written next)
    // The maximum over x and x + h, then over y and y + h of that (in place: row y + h is read before it is
    // written). Off the grid counts as 0, which no likelihood is below.
    for (int y = 0; y < height_; ++y) {
      const float* from = &below[at(0, y)];
      float* to = &level[at(0, y)];
      for (int x = 0; x < width_; ++x) to[x] = x + h < width_ ? std::max(from[x], from[x + h]) : from[x];
    }
    for (int y = 0; y + h < height_; ++y) {
      float* to = &level[at(0, y)];
      const float* up = &level[at(0, y + h)];
      for (int x = 0; x < width_; ++x) to[x] = std::max(to[x], up[x]);
    }
    levels_.push_back(std::move(level));
  }
}

namespace {

struct Cells {
  std::vector<int> x, y;  ///< each point's cell with the guess's translation
  /// Each point's index into a level (at(x, y)) when no translation of the window takes it off the grid, or -1:
  /// then the look-up needs no clamping.
  std::vector<int64_t> inside;
};

/// The turn that moves the farthest points (the 90th percentile of distance, so one stray return does not decide)
/// by about `resolution`.
double yaw_step(const std::vector<Point2f>& points, double resolution) {
  std::vector<double> reach(points.size());
  for (size_t i = 0; i < points.size(); ++i) reach[i] = std::hypot(double{points[i].x}, double{points[i].y});
  const size_t at = reach.size() * 9 / 10;
  std::nth_element(reach.begin(), reach.begin() + static_cast<std::ptrdiff_t>(at), reach.end());
  return std::clamp(resolution / std::max(reach[at], 1e-3), 0.002, 0.035);
}

}  // namespace

double CorrelativeMatcher::score(const std::vector<Point2f>& points, double x, double y, double yaw) const {
  if (points.empty() || levels_.empty()) return 0;
  const double c = std::cos(yaw), s = std::sin(yaw);
  double sum = 0;
  for (const auto& p : points) {
    const auto ix = static_cast<int>(std::floor((c * p.x - s * p.y + x - x0_) / resolution_));
    const auto iy = static_cast<int>(std::floor((s * p.x + c * p.y + y - y0_) / resolution_));
    if (ix >= 0 && iy >= 0 && ix < width_ && iy < height_) {
      sum += levels_[0][at(ix, iy)];
    }
  }
  return sum / static_cast<double>(points.size());
}

CorrelativeMatcher::Match CorrelativeMatcher::match(const std::vector<Point2f>& points, double guess_x, double guess_y,
                                                    double guess_yaw, double window_xy, double window_yaw,
                                                    const Match* exclude, double exclude_xy, double at_least) const {
  Match best{guess_x, guess_y, guess_yaw, 0};
  if (points.empty() || levels_.empty()) return best;
  const double res = resolution_;
  const double step = yaw_step(points, res);
  const int n = static_cast<int>(std::ceil(window_xy / res));  // translations -n..n cells in x and y
  const int n_yaw = static_cast<int>(std::ceil(window_yaw / step));
  std::vector<Cells> turns;
  for (int k = -n_yaw; k <= n_yaw; ++k) {
    const double yaw = guess_yaw + k * step, c = std::cos(yaw), s = std::sin(yaw);
    Cells cells;
    for (const auto& p : points) {
      const auto x = static_cast<int>(std::floor((c * p.x - s * p.y + guess_x - x0_) / res));
      const auto y = static_cast<int>(std::floor((s * p.x + c * p.y + guess_y - y0_) / res));
      cells.x.push_back(x), cells.y.push_back(y);
      const bool in = x - n >= 0 && x + n <= width_ && y - n >= 0 && y + n <= height_;
      cells.inside.push_back(in ? static_cast<int64_t>(at(x, y)) : -1);
    }
    turns.push_back(std::move(cells));
  }
  auto bound = [&](int turn, int tx, int ty, int level) {
    const Cells& cells = turns[static_cast<size_t>(turn)];
    const auto& grid = levels_[static_cast<size_t>(level)];
    // A coarse cell covers the 2^level cells from it: one left of or below the grid still covers the grid's first
    // cells, whose maximum the grid's first coarse cell bounds.
    const int below = 1 - (1 << level);
    // A point no translation takes off the grid: its index moved by the translation. Another: clamped, so that off
    // the grid the lookup lands in the empty border (x = -1 or width_). The sum in the points' order either way.
    double sum = 0;
    const int64_t shift = static_cast<int64_t>(ty) * (width_ + 2) + tx;
    for (size_t i = 0; i < cells.x.size(); ++i) {
      if (cells.inside[i] >= 0) {
        sum += grid[static_cast<size_t>(cells.inside[i] + shift)];
        continue;
      }
      int x = cells.x[i] + tx, y = cells.y[i] + ty;
      x = x < 0 ? (x >= below ? 0 : -1) : std::min(x, width_);
      y = y < 0 ? (y >= below ? 0 : -1) : std::min(y, height_);
      sum += grid[at(x, y)];
    }
    return sum / static_cast<double>(cells.x.size());
  };
  struct Candidate {
    double bound;
    int turn, tx, ty;
  };
  auto by_bound = [](const Candidate& a, const Candidate& b) {
    if (a.bound != b.bound) return a.bound > b.bound;
    if (a.turn != b.turn) return a.turn < b.turn;
    return a.ty != b.ty ? a.ty < b.ty : a.tx < b.tx;
  };
  const int top = static_cast<int>(levels_.size()) - 1;
  std::vector<Candidate> roots;
  for (int k = 0; k < static_cast<int>(turns.size()); ++k) {
    for (int ty = -n; ty <= n; ty += 1 << top) {
      for (int tx = -n; tx <= n; tx += 1 << top) roots.push_back({bound(k, tx, ty, top), k, tx, ty});
    }
  }
  std::sort(roots.begin(), roots.end(), by_bound);
  // Only branches that may reach `at_least` are opened (the pruning a pose of that score would give from the
  // start), and the first pose found ends the search.
  double best_score = at_least > 0 ? std::nextafter(at_least, 0.0) : -1;
  bool done = false;
  std::function<void(const Candidate*, size_t, int)> branch = [&](const Candidate* list, size_t count, int level) {
    for (const Candidate* it = list; it != list + count && !done; ++it) {
      const Candidate& c = *it;
      if (c.bound <= best_score) return;  // sorted: nothing further down the list can do better
      if (level == 0) {
        const double x = guess_x + c.tx * res, y = guess_y + c.ty * res;
        if (exclude != nullptr && std::hypot(x - exclude->x, y - exclude->y) <= exclude_xy) continue;
        best_score = c.bound;
        best = {x, y, guess_yaw + (c.turn - n_yaw) * step, c.bound};
        done = at_least > 0;  // all the caller asked
        continue;
      }
      if (exclude != nullptr) {  // a branch wholly inside the excluded disc holds no pose to find
        const double span = ((1 << level) - 1) * res;
        const double x = guess_x + c.tx * res - exclude->x, y = guess_y + c.ty * res - exclude->y;
        const double far_x = std::max(std::abs(x), std::abs(x + span)),
                     far_y = std::max(std::abs(y), std::abs(y + span));
        if (std::hypot(far_x, far_y) <= exclude_xy) continue;
      }
      const int h = 1 << (level - 1);
      std::array<Candidate, 4> children;
      size_t found = 0;
      for (int dy : {0, h}) {
        for (int dx : {0, h}) {
          if (c.tx + dx > n || c.ty + dy > n) continue;
          children[found++] = {bound(c.turn, c.tx + dx, c.ty + dy, level - 1), c.turn, c.tx + dx, c.ty + dy};
        }
      }
      for (size_t a = 1; a < found; ++a) {  // at most 4: an insertion sort (the keys are unique)
        for (size_t b = a; b > 0 && by_bound(children[b], children[b - 1]); --b)
          std::swap(children[b], children[b - 1]);
      }
      branch(children.data(), found, level - 1);
    }
  };
  branch(roots.data(), roots.size(), top);
  best.score = best_score >= at_least ? std::max(best_score, 0.0) : 0.0;
  return best;
}

}  // namespace driftlab::slam::internal
