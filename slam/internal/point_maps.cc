#include "slam/internal/point_maps.h"

#include <mrpt/core/bits_math.h>
#include <mrpt/math/CMatrixDynamic.h>
#include <mrpt/math/TPose2D.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/tfest/se2.h>
#include <Eigen/Dense>  // MRPT matrices' products and inverses

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace driftlab::slam::internal {

/// The map's points sorted into square cells (a counting sort), each cell's points contiguous.
struct GridPointsMap::Grid {
  uint64_t id = 0;    ///< this grid's number, unique in the process: what a search's bounds were found in
  size_t points = 0;  ///< the map's size when built
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0, cell = 0;
  int64_t nx = 0, ny = 0;
  std::vector<uint32_t> start;  ///< by cell (row-major), where its points begin in xy and index; one past the end
  std::vector<std::array<float, 2>> xy;  ///< the points, a cell's side by side
  std::vector<uint32_t> index;           ///< the points' indices in the map
  /// By cell, how many rings out (Chebyshev distance in cells) the nearest cell with points is: the search starts
  /// there, and a point far from every point (none within the ICP's limit) costs one look-up.
  std::vector<uint16_t> empty_rings;
};

namespace {
thread_local GridPointsMap::Lookups lookups_here;  ///< GridPointsMap::lookups()

// A cell of 0.2 m holds a few points of a wall at the scans' spacing, so the nearest point of a scan point that has
// one within the ICP's distances (0.1-2 m) is found among the 3 x 3 cells around it, most often in its own. The
// cell grows when the map's extent would need more than 4 cells per point (a few stray points far out).
constexpr double kCell = 0.2;
constexpr uint16_t kFarRings = std::numeric_limits<uint16_t>::max();  ///< no cell with points within this many
}  // namespace

const GridPointsMap::Grid& GridPointsMap::grid() const {
  if (grid_ && grid_->points == size()) return *grid_;
  static std::atomic<uint64_t> grids{0};
  auto g = std::make_shared<Grid>();
  g->id = ++grids;
  g->points = size();
  const auto& xs = getPointsBufferRef_x();
  const auto& ys = getPointsBufferRef_y();
  std::vector<uint32_t> finite;
  finite.reserve(xs.size());
  for (size_t i = 0; i < xs.size(); ++i) {
    if (std::isfinite(xs[i]) && std::isfinite(ys[i])) finite.push_back(static_cast<uint32_t>(i));
  }
  if (!finite.empty()) {
    g->min_x = g->max_x = xs[finite[0]], g->min_y = g->max_y = ys[finite[0]];
    for (uint32_t i : finite) {
      g->min_x = std::min<double>(g->min_x, xs[i]), g->max_x = std::max<double>(g->max_x, xs[i]);
      g->min_y = std::min<double>(g->min_y, ys[i]), g->max_y = std::max<double>(g->max_y, ys[i]);
    }
    const double most = 4.0 * static_cast<double>(finite.size()) + 4096;
    g->cell = kCell;
    const double w = g->max_x - g->min_x, h = g->max_y - g->min_y;
    if ((w / g->cell + 1) * (h / g->cell + 1) > most) g->cell = std::max(g->cell, std::sqrt(w * h / most) * 1.01);
    while ((std::floor(w / g->cell) + 1) * (std::floor(h / g->cell) + 1) > most) g->cell *= 1.5;
    g->nx = static_cast<int64_t>(w / g->cell) + 1, g->ny = static_cast<int64_t>(h / g->cell) + 1;
    auto cell_of = [&](uint32_t i) {
      const auto cx = std::min(static_cast<int64_t>((xs[i] - g->min_x) / g->cell), g->nx - 1);
      const auto cy = std::min(static_cast<int64_t>((ys[i] - g->min_y) / g->cell), g->ny - 1);
      return static_cast<size_t>(cy * g->nx + cx);
    };
    g->start.assign(static_cast<size_t>(g->nx * g->ny) + 1, 0);
    for (uint32_t i : finite) ++g->start[cell_of(i) + 1];
    for (size_t c = 1; c < g->start.size(); ++c) g->start[c] += g->start[c - 1];
    std::vector<uint32_t> next(g->start.begin(), g->start.end() - 1);
    g->xy.resize(finite.size()), g->index.resize(finite.size());
    for (uint32_t i : finite) {
      const uint32_t at = next[cell_of(i)]++;
      g->xy[at] = {xs[i], ys[i]}, g->index[at] = i;
    }
    // The chessboard distance transform: a pass forward and one back over the 8 neighbours is exact for it. Each
    // pass takes a row in two steps, the same minima in another order: the three neighbours in the row before (or
    // after) first, in a loop the compiler runs several cells at a time, then the one before in the row.
    const int64_t nx = g->nx, ny = g->ny;
    auto& e = g->empty_rings;
    e.assign(static_cast<size_t>(nx * ny), kFarRings);
    for (size_t c = 0; c + 1 < g->start.size(); ++c) {
      if (g->start[c + 1] > g->start[c]) e[c] = 0;
    }
    // A neighbour's rings plus one, unless that is more (from a far neighbour, kFarRings + 1 is more than any).
    auto relaxed = [](uint16_t here, uint32_t via) { return static_cast<uint16_t>(std::min<uint32_t>(here, via + 1)); };
    auto row = [&](int64_t y, int64_t beside, bool forward) {
      uint16_t* here = e.data() + y * nx;
      if (beside >= 0 && beside < ny) {
        const uint16_t* other = e.data() + beside * nx;
        here[0] = relaxed(here[0], std::min<uint32_t>(other[0], nx > 1 ? other[1] : kFarRings));
        for (int64_t x = 1; x + 1 < nx; ++x) {
          here[x] = relaxed(here[x], std::min({other[x - 1], other[x], other[x + 1]}));
        }
        if (nx > 1) here[nx - 1] = relaxed(here[nx - 1], std::min(other[nx - 2], other[nx - 1]));
      }
      if (forward) {
        for (int64_t x = 1; x < nx; ++x) here[x] = relaxed(here[x], here[x - 1]);
      } else {
        for (int64_t x = nx - 2; x >= 0; --x) here[x] = relaxed(here[x], here[x + 1]);
      }
    };
    for (int64_t y = 0; y < ny; ++y) row(y, y - 1, true);
    for (int64_t y = ny - 1; y >= 0; --y) row(y, y + 1, false);
  }
  grid_ = std::move(g);
  return *grid_;
}

void GridPointsMap::internal_clear() {
  CSimplePointsMap::internal_clear();
  grid_.reset();
}

namespace {

/// Calls visit(x, y) for each of the grid's cells `r` rings (Chebyshev distance in cells) out from the cell (cx, cy),
/// which may lie outside the grid: the ring's bottom and top rows, then its left and right columns between them.
template <typename Visit>
void visit_ring(const GridPointsMap::Grid& g, int64_t cx, int64_t cy, int64_t r, Visit& visit) {
  const int64_t x0 = std::max<int64_t>(cx - r, 0), x1 = std::min(cx + r, g.nx - 1);
  for (const int64_t y : {cy - r, cy + r}) {
    if (y >= 0 && y < g.ny) {
      for (int64_t x = x0; x <= x1; ++x) visit(x, y);
    }
    if (r == 0) return;
  }
  const int64_t y0 = std::max<int64_t>(cy - r + 1, 0), y1 = std::min(cy + r - 1, g.ny - 1);
  for (const int64_t x : {cx - r, cx + r}) {
    if (x >= 0 && x < g.nx) {
      for (int64_t y = y0; y <= y1; ++y) visit(x, y);
    }
  }
}

/// The grid's point nearest to (qx, qy) if its squared distance (in float) is below limit², else -1 (an index into
/// the grid's arrays). Cells are looked at ring by ring out from the query's, from the first ring with points, and
/// no further out than the limit or the best point so far. `hint`, any index into the grid's arrays (or -1), is
/// the first best point: the nearest point of the same point at the ICP's previous iteration, or of the point
/// before, is most often the nearest again, and the search then ends in the query's own cell. Any hint gives the
/// same answer: of points at exactly the same distance, the one first in the map. When a point is found, `others2`
/// is a lower bound on the squared distance from (qx, qy) to every other point of the map (the second nearest among
/// the points looked at, and the nearest any cell not looked at can be).
int64_t nearest_in(const GridPointsMap::Grid& g, float qx, float qy, double limit, float& distance2, int64_t hint,
                   double& others2) {
  distance2 = std::numeric_limits<float>::max();
  if (g.xy.empty() || !(limit > 0) || !std::isfinite(qx) || !std::isfinite(qy)) return -1;
  // Nothing within the limit when the grid's bounding box is beyond it (margins for the distances in float).
  const double reach = limit * (1 + 1e-6) + 1e-5;
  const double out_x = std::max({g.min_x - qx, qx - g.max_x, 0.0}), out_y = std::max({g.min_y - qy, qy - g.max_y, 0.0});
  if (out_x * out_x + out_y * out_y > reach * reach) return -1;
  const double fx = (qx - g.min_x) / g.cell, fy = (qy - g.min_y) / g.cell;
  const auto cx = static_cast<int64_t>(std::floor(fx)), cy = static_cast<int64_t>(std::floor(fy));
  const int64_t rings = std::max({cx, g.nx - 1 - cx, cy, g.ny - 1 - cy});
  // No cell with points is nearer than `first` rings: from outside the grid, not before the grid's edge, nor
  // before the nearest cell with points of the edge's cell, less the way to it.
  const int64_t in_x = std::clamp<int64_t>(cx, 0, g.nx - 1), in_y = std::clamp<int64_t>(cy, 0, g.ny - 1);
  const int64_t outside = std::max(std::abs(cx - in_x), std::abs(cy - in_y));
  const uint16_t empty = g.empty_rings[static_cast<size_t>(in_y * g.nx + in_x)];
  const int64_t first = empty == kFarRings ? outside : std::max<int64_t>(outside, empty - outside);
  float best = std::numeric_limits<float>::max();
  int64_t found = -1;
  // Lower bounds on the squared distance to every point but the best: of the points looked at, and of the cells not
  // looked at.
  float second = std::numeric_limits<float>::infinity();
  double beyond = std::numeric_limits<double>::infinity();
  if (hint >= 0 && static_cast<size_t>(hint) < g.xy.size()) {
    const float dx = qx - g.xy[static_cast<size_t>(hint)][0], dy = qy - g.xy[static_cast<size_t>(hint)][1];
    best = dx * dx + dy * dy, found = hint;
  }
  auto visit = [&](int64_t x, int64_t y) {
    const size_t c = static_cast<size_t>(y * g.nx + x);
    const uint32_t begin = g.start[c], end = g.start[c + 1];
    if (begin == end) return;
    for (uint32_t i = begin; i < end; ++i) {
      const float dx = qx - g.xy[i][0], dy = qy - g.xy[i][1];
      const float d = dx * dx + dy * dy;  // nanoflann's L2 in float, in its order
      // The nearest, and of points at the same distance the first in the map: one answer whatever the hint, the
      // order cells are looked at in, or the thread.
      if (static_cast<int64_t>(i) == found) continue;
      const bool better = d < best || (d == best && found >= 0 && g.index[i] < g.index[static_cast<size_t>(found)]);
      const float other = better ? best : d;  // the one of the two that is not the best now
      second = other < second ? other : second;
      best = better ? d : best;
      found = better ? static_cast<int64_t>(i) : found;
    }
  };
  // The nearest a point k rings out can be: k - 1 whole cells, and the way to the own cell's edge.
  const double edge = std::min({fx - static_cast<double>(cx), static_cast<double>(cx + 1) - fx,
                                fy - static_cast<double>(cy), static_cast<double>(cy + 1) - fy});
  const double ring = g.cell * (1 - 1e-6);
  for (int64_t k = first; k <= rings; ++k) {
    if (k > 0) {
      const double bound = (static_cast<double>(k - 1) + edge) * ring - 1e-5;
      if (bound > limit || (found >= 0 && bound * bound > best)) {
        beyond = std::min(beyond, bound > 0 ? bound * bound : 0.0);
        break;
      }
    }
    if (k == 1 && found >= 0) {
      // The 8 cells around the query's own: each only if its side (or corner) is nearer than the best point.
      const double c2 = g.cell * g.cell * (1 - 1e-6), b = static_cast<double>(best) + 1e-10;
      const double left = fx - static_cast<double>(cx), right = 1 - left;
      const double down = fy - static_cast<double>(cy), up = 1 - down;
      const double lx2 = left * left * c2, rx2 = right * right * c2, dy2 = down * down * c2, uy2 = up * up * c2;
      auto cell = [&](int64_t x, int64_t y, double gap2) {
        if (x < 0 || x >= g.nx || y < 0 || y >= g.ny) return;
        if (gap2 <= b) {
          visit(x, y);
        } else {
          beyond = std::min(beyond, gap2);
        }
      };
      cell(cx - 1, cy, lx2), cell(cx + 1, cy, rx2), cell(cx, cy - 1, dy2), cell(cx, cy + 1, uy2);
      cell(cx - 1, cy - 1, lx2 + dy2), cell(cx + 1, cy - 1, rx2 + dy2), cell(cx - 1, cy + 1, lx2 + uy2);
      cell(cx + 1, cy + 1, rx2 + uy2);
      continue;
    }
    visit_ring(g, cx, cy, k, visit);
  }
  if (found < 0 || !(static_cast<double>(best) < limit * limit)) return -1;
  distance2 = best;
  others2 = std::min(static_cast<double>(second), beyond);
  return found;
}

}  // namespace

GridPointsMap::Lookups GridPointsMap::lookups() { return lookups_here; }

int64_t GridPointsMap::nearest(float x, float y, double limit, float& distance2) const {
  const Grid& g = grid();
  double others2 = 0;
  const int64_t i = nearest_in(g, x, y, limit, distance2, -1, others2);
  return i < 0 ? -1 : static_cast<int64_t>(g.index[static_cast<size_t>(i)]);
}

bool GridPointsMap::nearest_k(float x, float y, size_t k, std::vector<size_t>& out) const {
  out.clear();
  const Grid& g = grid();
  if (k == 0 || g.xy.size() < k || !std::isfinite(x) || !std::isfinite(y)) return false;
  // The k + 1 nearest so far, nearest first: (squared distance, index into the grid's arrays).
  static thread_local std::vector<std::pair<float, uint32_t>> best;
  best.clear();
  const size_t keep = k + 1;
  const double fx = (x - g.min_x) / g.cell, fy = (y - g.min_y) / g.cell;
  const auto cx = static_cast<int64_t>(std::floor(fx)), cy = static_cast<int64_t>(std::floor(fy));
  const int64_t rings = std::max({cx, g.nx - 1 - cx, cy, g.ny - 1 - cy});
  // As in nearest_in: a point k rings out is at least k - 1 whole cells and the way to the own cell's edge away.
  const double edge = std::min({fx - static_cast<double>(cx), static_cast<double>(cx + 1) - fx,
                                fy - static_cast<double>(cy), static_cast<double>(cy + 1) - fy});
  const double ring = g.cell * (1 - 1e-6);
  auto visit = [&](int64_t cell_x, int64_t cell_y) {
    const size_t c = static_cast<size_t>(cell_y * g.nx + cell_x);
    for (uint32_t i = g.start[c]; i < g.start[c + 1]; ++i) {
      const float dx = x - g.xy[i][0], dy = y - g.xy[i][1];
      const float d = dx * dx + dy * dy;  // nanoflann's L2 in float
      if (best.size() == keep && !(d < best.back().first)) continue;
      const auto at = std::upper_bound(best.begin(), best.end(), std::make_pair(d, i),
                                       [](const auto& a, const auto& b) { return a.first < b.first; });
      best.insert(at, {d, i});
      if (best.size() > keep) best.pop_back();
    }
  };
  for (int64_t r = 0; r <= rings; ++r) {
    if (r > 0 && best.size() == keep) {
      // Every point from this ring out is further than the (k + 1)-th so far: none can take a place or tie.
      const double bound = (static_cast<double>(r - 1) + edge) * ring - 1e-5;
      if (bound > 0 && bound * bound > static_cast<double>(best.back().first)) break;
    }
    visit_ring(g, cx, cy, r, visit);
  }
  if (best.size() < k) return false;
  for (size_t i = 1; i < std::min(best.size(), keep); ++i) {
    if (best[i].first == best[i - 1].first) return false;  // a tie: the kd-tree's order is its own
  }
  for (size_t i = 0; i < k; ++i) out.push_back(g.index[best[i].second]);
  return true;
}

void GridPointsMap::determineMatching2D(const mrpt::maps::CMetricMap* other_map, const mrpt::poses::CPose2D& other_pose,
                                        mrpt::tfest::TMatchingPairList& pairs,
                                        const mrpt::maps::TMatchingParams& params,
                                        mrpt::maps::TMatchingExtraResults& extra) const {
  const auto* other = dynamic_cast<const mrpt::maps::CPointsMap*>(other_map);
  if (other == nullptr || params.decimation_other_map_points == 0 ||
      params.offset_other_map_points >= params.decimation_other_map_points ||
      (params.onlyUniqueRobust && !params.onlyKeepTheClosest)) {
    CSimplePointsMap::determineMatching2D(other_map, other_pose, pairs, params, extra);  // MRPT's checks and errors
    return;
  }
  extra = mrpt::maps::TMatchingExtraResults();
  pairs.clear();
  const size_t n_other = other->size(), n_this = size();
  if (n_other == 0 || n_this == 0) return;
  pairs.reserve(n_other);

  // The other map's points at other_pose, in float as MRPT computes them (its build without SSE2: Eigen arrays of
  // float, the pose's cosine, sine and position cast to float), and their bounding box.
  const auto& ox = other->getPointsBufferRef_x();
  const auto& oy = other->getPointsBufferRef_y();
  const auto& oz = other->getPointsBufferRef_z();
  const auto c = static_cast<float>(std::cos(other_pose.phi())), s = static_cast<float>(std::sin(other_pose.phi()));
  const auto x0 = static_cast<float>(other_pose.x()), y0 = static_cast<float>(other_pose.y());
  static thread_local std::vector<float> lx, ly;  // scratch: a matching per ICP iteration, no allocation each
  lx.resize(n_other), ly.resize(n_other);
  {
    const float* __restrict in_x = ox.data();
    const float* __restrict in_y = oy.data();
    float* __restrict out_x = lx.data();
    float* __restrict out_y = ly.data();
    size_t i = 0;
    using Float4 = float __attribute__((vector_size(16)));  // four at a time: the same operations on each
    for (; i + 4 <= n_other; i += 4) {
      Float4 px, py;
      std::memcpy(&px, in_x + i, sizeof px), std::memcpy(&py, in_y + i, sizeof py);
      const Float4 qx = (x0 + c * px) - s * py, qy = (y0 + s * px) + c * py;
      std::memcpy(out_x + i, &qx, sizeof qx), std::memcpy(out_y + i, &qy, sizeof qy);
    }
    for (; i < n_other; ++i) {
      out_x[i] = (x0 + c * in_x[i]) - s * in_y[i];
      out_y[i] = (y0 + s * in_x[i]) + c * in_y[i];
    }
  }
  // Their bounding box, in four lanes that the compiler runs side by side (MRPT's box: the same comparisons, so
  // the same answer whatever the order, a NaN first point included).
  float lo_x[4], hi_x[4], lo_y[4], hi_y[4];
  for (int l = 0; l < 4; ++l) lo_x[l] = hi_x[l] = lx[0], lo_y[l] = hi_y[l] = ly[0];
  size_t i = 1;
  for (; i + 4 <= n_other; i += 4) {
    for (int l = 0; l < 4; ++l) {
      const float x = lx[i + static_cast<size_t>(l)], y = ly[i + static_cast<size_t>(l)];
      lo_x[l] = x < lo_x[l] ? x : lo_x[l], hi_x[l] = x > hi_x[l] ? x : hi_x[l];
      lo_y[l] = y < lo_y[l] ? y : lo_y[l], hi_y[l] = y > hi_y[l] ? y : hi_y[l];
    }
  }
  for (; i < n_other; ++i) {
    lo_x[0] = lx[i] < lo_x[0] ? lx[i] : lo_x[0], hi_x[0] = lx[i] > hi_x[0] ? lx[i] : hi_x[0];
    lo_y[0] = ly[i] < lo_y[0] ? ly[i] : lo_y[0], hi_y[0] = ly[i] > hi_y[0] ? ly[i] : hi_y[0];
  }
  float min_x = lo_x[0], max_x = hi_x[0], min_y = lo_y[0], max_y = hi_y[0];
  for (int l = 1; l < 4; ++l) {
    min_x = lo_x[l] < min_x ? lo_x[l] : min_x, max_x = hi_x[l] > max_x ? hi_x[l] : max_x;
    min_y = lo_y[l] < min_y ? lo_y[l] : min_y, max_y = hi_y[l] > max_y ? hi_y[l] : max_y;
  }
  const auto box = boundingBox();
  if (min_x > box.max.x || max_x < box.min.x || min_y > box.max.y || max_y < box.min.y) return;  // no overlap

  const Grid& g = grid();
  const auto& tx = getPointsBufferRef_x();
  const auto& ty = getPointsBufferRef_y();
  const auto& tz = getPointsBufferRef_z();
  // Each point's nearest map point, in the points' order: (the map point, the point, the squared distance).
  struct Found {
    uint32_t map, point;
    float d2;
  };
  static thread_local std::vector<Found> found;  // scratch, as lx and ly
  found.clear();
  // By point, what the last full search for it found in this grid (at the ICP's previous iterations, or for the
  // same point of the scan before): where it was, its nearest map point and how near every other map point may be.
  // A fact about the grid, whatever the point is now: while the point is nearer to that map point than to where
  // any other may be, less the way it moved since, that map point is still its nearest, and no search is needed
  // (from an ICP's second iteration on, the pose moves by millimetres). Else the map point is the search's hint.
  static thread_local struct {
    uint64_t grid = 0;
    size_t points = 0;
    std::vector<int64_t> at;     ///< the nearest map point (an index into the grid's arrays), or -1
    std::vector<float> x, y;     ///< where the point was
    std::vector<double> others;  ///< every other map point at least this far from there [m]
  } last;
  if (last.grid != g.id || last.points != n_other) {
    last.grid = g.id, last.points = n_other;
    last.at.assign(n_other, -1), last.x.resize(n_other), last.y.resize(n_other), last.others.resize(n_other);
  }
  int64_t before = -1;  // the previous point's
  float sum = 0;
  const auto& pivot = params.angularDistPivotPoint;
  const auto angular = static_cast<double>(params.maxAngularDistForCorrespondence);
  const auto linear = static_cast<double>(params.maxDistForCorrespondence);
  for (size_t i = params.offset_other_map_points; i < n_other; i += params.decimation_other_map_points) {
    // The limit grows with the distance from the pivot (the pose), by the angular threshold: searched within a
    // bound of it without the square root (|dx| + |dy| is at least the distance), then checked exactly, the
    // square root taken only when the linear part alone does not decide.
    const double dx = pivot.x - lx[i], dy = pivot.y - ly[i];
    float d2 = 0;
    const double reach = angular * (std::abs(dx) + std::abs(dy)) + linear;
    int64_t at = -1;
    const int64_t known = last.at[i];
    bool searched = true;
    if (known >= 0 && reach > 0) {
      // The way moved, bounded by |dx| + |dy|; margins of 1e-5 for the distances in float (the order of two
      // squared distances in float is the order of the distances when they differ by more).
      const double moved =
          (std::abs(static_cast<double>(lx[i] - last.x[i])) + std::abs(static_cast<double>(ly[i] - last.y[i]))) *
              (1 + 1e-6) +
          1e-9;
      const double room = last.others[i] - moved;
      const auto& p = g.xy[static_cast<size_t>(known)];
      const float ex = lx[i] - p[0], ey = ly[i] - p[1];
      const float d = ex * ex + ey * ey;  // as nearest_in computes it
      if (room > 0 && static_cast<double>(d) * (1 + 1e-5) < room * room) {
        searched = false;
        ++lookups_here.proved;
        if (static_cast<double>(d) < reach * reach) at = known, d2 = d;
      }
    }
    if (searched) {
      ++lookups_here.searched;
      double others2 = 0;
      at = nearest_in(g, lx[i], ly[i], reach, d2, known >= 0 ? known : before, others2);
      last.at[i] = at;
      if (at >= 0) last.x[i] = lx[i], last.y[i] = ly[i], last.others[i] = std::sqrt(others2 * (1 - 1e-6));
    }
    if (at < 0) continue;
    before = at;
    if (!(d2 < linear * linear)) {
      const double limit = angular * std::sqrt(dx * dx + dy * dy) + linear;
      if (!(d2 < limit * limit)) continue;
    }
    found.push_back({g.index[static_cast<size_t>(at)], static_cast<uint32_t>(i), d2});
    sum += d2;
  }
  // With onlyUniqueRobust, a map point keeps only its nearest point (the first of equal distances), as MRPT's
  // filterUniqueRobustPairs does, without its allocation of a slot per map point at every call.
  static thread_local std::vector<int32_t> best;  // by map point: its best entry in found, or -1
  if (params.onlyUniqueRobust) {
    if (best.size() < n_this) best.resize(n_this, -1);
    for (size_t f = 0; f < found.size(); ++f) {
      int32_t& b = best[found[f].map];
      if (b < 0 || found[f].d2 < found[static_cast<size_t>(b)].d2) b = static_cast<int32_t>(f);
    }
  }
  for (size_t f = 0; f < found.size(); ++f) {
    const Found& m = found[f];
    if (params.onlyUniqueRobust && best[m.map] != static_cast<int32_t>(f)) continue;
    auto& p = pairs.emplace_back();
    p.globalIdx = m.map;
    p.global = {tx[m.map], ty[m.map], tz[m.map]};
    p.localIdx = m.point;
    p.local = {ox[m.point], oy[m.point], oz[m.point]};
    p.errorSquareAfterTransformation = m.d2;
  }
  if (params.onlyUniqueRobust) {
    for (const Found& m : found) best[m.map] = -1;
  }
  const size_t with = found.size();
  extra.sumSqrDist = with > 0 ? static_cast<float>(sum / static_cast<double>(with)) : 0.f;
  extra.correspondencesRatio =
      static_cast<float>(params.decimation_other_map_points * with) / static_cast<float>(static_cast<double>(n_other));
}

void IcpOptions::load(const mrpt::config::CConfigFileBase& ini, const std::string& section) {
  // In CICP::TConfigParams::loadFromConfigFile's order and with its readers: a number read as float is rounded to
  // float even when absent (its default passes through read_float), as MRPT's are.
  maxIterations = static_cast<unsigned int>(ini.read_int(section, "maxIterations", static_cast<int>(maxIterations)));
  minAbsStep_trans = ini.read_float(section, "minAbsStep_trans", static_cast<float>(minAbsStep_trans));
  minAbsStep_rot = ini.read_float(section, "minAbsStep_rot", static_cast<float>(minAbsStep_rot));
  // An enum as MRPT reads one: its name, or a number.
  const auto read_enum = [&](const char* key, const std::vector<std::string>& names, int value) {
    const std::string word = ini.read_string_first_word(section, key, "");
    if (word.empty()) return value;
    if (std::isdigit(static_cast<unsigned char>(word[0])) != 0) return std::atoi(word.c_str());
    for (size_t i = 0; i < names.size(); ++i) {
      if (names[i] == word) return static_cast<int>(i);
    }
    throw std::runtime_error("[" + section + "] " + key + ": '" + word + "' is none of its values");
  };
  if (const int algorithm = read_enum("ICP_algorithm", {"icpClassic", "icpLevenbergMarquardt"}, 0); algorithm != 0) {
    throw std::runtime_error("[" + section + "] ICP_algorithm: the graph method runs icpClassic only (given " +
                             std::to_string(algorithm) + "); icp-slam runs the others");
  }
  const int method = read_enum("ICP_covariance_method", {"icpCovLinealMSE", "icpCovFiniteDifferences"},
                               static_cast<int>(covariance_method));
  if (method != 0 && method != 1) {
    throw std::runtime_error("[" + section + "] ICP_covariance_method: " + std::to_string(method) +
                             " is none of its values (0 icpCovLinealMSE, 1 icpCovFiniteDifferences)");
  }
  covariance_method = static_cast<Covariance>(method);
  thresholdDist = ini.read_float(section, "thresholdDist", static_cast<float>(thresholdDist));
  thresholdAng =
      mrpt::DEG2RAD(ini.read_float(section, "thresholdAng_DEG", static_cast<float>(mrpt::RAD2DEG(thresholdAng))));
  ALFA = ini.read_float(section, "ALFA", static_cast<float>(ALFA));
  smallestThresholdDist = ini.read_float(section, "smallestThresholdDist", static_cast<float>(smallestThresholdDist));
  onlyUniqueRobust = ini.read_bool(section, "onlyUniqueRobust", onlyUniqueRobust);
  if (ini.read_bool(section, "doRANSAC", false)) {
    throw std::runtime_error("[" + section + "] doRANSAC: the graph method's ICP has no RANSAC step; icp-slam has");
  }
  covariance_varPoints = ini.read_float(section, "covariance_varPoints", static_cast<float>(covariance_varPoints));
  kernel_rho = ini.read_float(section, "kernel_rho", static_cast<float>(kernel_rho));
  use_kernel = ini.read_bool(section, "use_kernel", use_kernel);
  skip_cov_calculation = ini.read_bool(section, "skip_cov_calculation", skip_cov_calculation);
  corresponding_points_decimation = static_cast<uint32_t>(
      ini.read_int(section, "corresponding_points_decimation", static_cast<int>(corresponding_points_decimation)));
  if (!(ALFA >= 0 && ALFA < 1)) throw std::runtime_error("[" + section + "] ALFA must be in [0, 1)");
}

namespace {

/// CICP::kernel, in its float arguments.
float icp_kernel(float x2, float rho2, bool use) { return use ? (x2 / (x2 + rho2)) : x2; }

/// CICP's finite-difference covariance (ICP_covariance_method icpCovFiniteDifferences, "OXSMV2"): the pairs'
/// residuals' derivatives by a parabola through three points 1 cm apart, COV = (D D^T + 1e-6 I)^-1.
mrpt::math::CMatrixDouble33 finite_difference_covariance(const mrpt::tfest::TMatchingPairList& pairs,
                                                         const mrpt::poses::CPose2D& pose, const IcpOptions& o) {
  const size_t n = pairs.size();
  mrpt::math::CMatrixDouble D(3, n);
  const mrpt::math::TPose2D transf = pose.asTPose();
  const double ccos = std::cos(transf.phi), csin = std::sin(transf.phi);
  constexpr double kAxy = 0.01;
  const double rho2 = o.kernel_rho * o.kernel_rho;
  // The parabola through (w1, q1), (w2, q2), (w3, q3): its slope at w2.
  const auto slope = [](double w1, double w2, double w3, double q1, double q2, double q3) {
    const double a = ((q3 - q2) / ((w3 - w2) * (w3 - w1))) - ((q1 - q2) / ((w1 - w2) * (w3 - w1)));
    const double b = ((q1 - q2) + (a * ((w2 * w2) - (w1 * w1)))) / (w1 - w2);
    return (2 * a * w2) + b;
  };
  for (size_t i = 0; i < n; ++i) {
    const auto& p = pairs[i];
    const float x = static_cast<float>(transf.x + ccos * p.local.x - csin * p.local.y);
    const float y = static_cast<float>(transf.y + csin * p.local.x + ccos * p.local.y);
    // The residual with one coordinate moved (in double, as MRPT's w) and the other as found (in float, as its).
    const auto moved_x = [&](double w) {
      return icp_kernel(static_cast<float>(mrpt::square(p.global.x - w) + mrpt::square(p.global.y - y)),
                        static_cast<float>(rho2), o.use_kernel);
    };
    const auto moved_y = [&](double w) {
      return icp_kernel(static_cast<float>(mrpt::square(p.global.x - x) + mrpt::square(p.global.y - w)),
                        static_cast<float>(rho2), o.use_kernel);
    };
    const double wx = x, wy = y;
    D(0, i) = slope(wx - kAxy, wx, wx + kAxy, moved_x(wx - kAxy), moved_x(wx), moved_x(wx + kAxy));
    D(1, i) = slope(wy - kAxy, wy, wy + kAxy, moved_y(wy - kAxy), moved_y(wy), moved_y(wy + kAxy));
    D(2, i) = D(0, i) * (-csin * p.local.x - ccos * p.local.y) + D(1, i) * (ccos * p.local.x - csin * p.local.y);
  }
  mrpt::math::CMatrixDouble33 DDt;
  DDt.matProductOf_AAt(D);
  for (int i = 0; i < 3; ++i) DDt(i, i) += 1e-6;  // not singular, the covariance hardly changed
  return DDt.inverse_LLt();
}

}  // namespace

IcpResult icp_align(const GridPointsMap& reference, const mrpt::maps::CSimplePointsMap& query,
                    const mrpt::poses::CPose2D& start, const IcpOptions& o,
                    const std::function<bool(const mrpt::poses::CPose2D&)>& settled) {
  IcpResult r;
  r.pose = start;
  r.covariance.setZero();
  if (query.isEmpty()) return r;
  mrpt::maps::TMatchingParams params;
  params.maxDistForCorrespondence = static_cast<float>(o.thresholdDist);
  params.maxAngularDistForCorrespondence = static_cast<float>(o.thresholdAng);
  params.onlyKeepTheClosest = true;
  params.onlyUniqueRobust = o.onlyUniqueRobust;
  params.decimation_other_map_points = o.corresponding_points_decimation;
  params.offset_other_map_points = 0;
  // MRPT's arithmetic: the float thresholds shrunk in double, compared with the double limit.
  const auto shrink = [&](float& threshold) { threshold = static_cast<float>(threshold * o.ALFA); };
  mrpt::tfest::TMatchingPairList pairs;
  mrpt::maps::TMatchingExtraResults extra;
  mrpt::poses::CPose2D last;  // as MRPT's: the origin, not the start
  bool approaching = false;
  do {
    params.angularDistPivotPoint = mrpt::math::TPoint3D(r.pose.translation());
    reference.determineMatching2D(&query, r.pose, pairs, params, extra);
    approaching = !pairs.empty();
    if (approaching) {
      mrpt::math::TPose2D estimate;
      mrpt::tfest::se2_l2(pairs, estimate);
      r.pose = mrpt::poses::CPose2D(estimate);
      if (!(std::fabs(last.x() - r.pose.x()) > o.minAbsStep_trans ||
            std::fabs(last.y() - r.pose.y()) > o.minAbsStep_trans ||
            std::fabs(mrpt::math::wrapToPi(last.phi() - r.pose.phi())) > o.minAbsStep_rot)) {
        shrink(params.maxDistForCorrespondence);
        shrink(params.maxAngularDistForCorrespondence);
        if (params.maxDistForCorrespondence < o.smallestThresholdDist) approaching = false;
        if (++params.offset_other_map_points >= o.corresponding_points_decimation) params.offset_other_map_points = 0;
      }
      last = r.pose;
    }
    ++r.iterations;
    if (r.iterations >= o.maxIterations && params.maxDistForCorrespondence > o.smallestThresholdDist) {
      shrink(params.maxDistForCorrespondence);
    }
    if (settled && settled(r.pose)) return r;  // asked for the pose only
  } while ((approaching && r.iterations < o.maxIterations) ||
           (r.iterations >= o.maxIterations && params.maxDistForCorrespondence > o.smallestThresholdDist));
  if (!o.skip_cov_calculation && !pairs.empty()) {
    if (o.covariance_method == IcpOptions::Covariance::linear_mse) {
      mrpt::poses::CPosePDFGaussian gauss(r.pose);
      mrpt::tfest::se2_l2(pairs, gauss);  // the mean too, from the same pairs, as MRPT keeps it
      r.pose = gauss.mean;
      gauss.cov *= o.covariance_varPoints;
      r.covariance = gauss.cov;
    } else {
      r.covariance = finite_difference_covariance(pairs, r.pose, o);
    }
  }
  r.goodness = extra.correspondencesRatio;
  return r;
}

mrpt::poses::CPose2D icp_classic(const GridPointsMap& reference, const mrpt::maps::CSimplePointsMap& query,
                                 const mrpt::poses::CPose2D& start, const IcpOptions& o,
                                 const std::function<bool(const mrpt::poses::CPose2D&)>& settled) {
  IcpOptions pose_only = o;
  pose_only.skip_cov_calculation = true;
  return icp_align(reference, query, start, pose_only, settled).pose;
}

}  // namespace driftlab::slam::internal
