#include "sim/raycaster.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace driftlab::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Cells list the obstacles within this distance of them, so that rounding at a cell boundary never loses one.
constexpr double kPad = 1e-6;
constexpr size_t kMaxCells = size_t{1} << 22;

// Face codes of a hit, turned into a normal only once the closest hit is known.
// Boxes: axis * 2 + (1 when the normal points along -axis). Cylinders: kSide, kTop, kBottom.
constexpr int kSide = 0, kTop = 1, kBottom = 2;

}  // namespace

struct RayCaster::Best {
  double t;
  int object;  // -1 floor, -2 nothing
  int face;
};

RayCaster::RayCaster(const World& world, double cell_size) : cell_(cell_size > 0 ? cell_size : 0.5) {
  for (const Box& b : world.boxes) {
    boxes_.push_back({b.center.x(), b.center.y(), b.center.z(), 0.5 * b.size.x(), 0.5 * b.size.y(),
                      0.5 * b.size.z(), std::cos(b.yaw), std::sin(b.yaw)});
    colors_.push_back(b.color);
  }
  for (const Cylinder& c : world.cylinders) {
    cyls_.push_back({c.center.x(), c.center.y(), c.center.z(), c.radius, 0.5 * c.height});
    colors_.push_back(c.color);
  }
  z_lo_ = kInf;
  z_hi_ = -kInf;
  for (const BoxData& b : boxes_) z_lo_ = std::min(z_lo_, b.cz - b.hz), z_hi_ = std::max(z_hi_, b.cz + b.hz);
  for (const CylData& c : cyls_) z_lo_ = std::min(z_lo_, c.cz - c.hz), z_hi_ = std::max(z_hi_, c.cz + c.hz);

  const Eigen::AlignedBox2d bounds = world.bounds();
  if (bounds.isEmpty()) return;
  x0_ = bounds.min().x() - kPad;
  y0_ = bounds.min().y() - kPad;
  const double w = bounds.sizes().x() + 2 * kPad, h = bounds.sizes().y() + 2 * kPad;
  while (std::ceil(w / cell_) * std::ceil(h / cell_) > static_cast<double>(kMaxCells)) cell_ *= 2;
  nx_ = std::max(1, static_cast<int>(std::ceil(w / cell_)));
  ny_ = std::max(1, static_cast<int>(std::ceil(h / cell_)));

  // Calls f(cell index) for every cell the object's footprint overlaps (within kPad).
  auto for_cells = [&](int object, auto&& f) {
    double ex, ey, cx, cy;
    const bool is_box = object < static_cast<int>(boxes_.size());
    if (is_box) {
      const BoxData& b = boxes_[object];
      cx = b.cx, cy = b.cy;
      ex = std::abs(b.c) * b.hx + std::abs(b.s) * b.hy;
      ey = std::abs(b.s) * b.hx + std::abs(b.c) * b.hy;
    } else {
      const CylData& c = cyls_[object - boxes_.size()];
      cx = c.cx, cy = c.cy, ex = ey = c.r;
    }
    auto index = [&](double v, double lo, int n) {
      return std::clamp(static_cast<int>(std::floor((v - lo) / cell_)), 0, n - 1);
    };
    const int ix0 = index(cx - ex - kPad, x0_, nx_), ix1 = index(cx + ex + kPad, x0_, nx_);
    const int iy0 = index(cy - ey - kPad, y0_, ny_), iy1 = index(cy + ey + kPad, y0_, ny_);
    const double hc = 0.5 * cell_;
    for (int iy = iy0; iy <= iy1; ++iy) {
      for (int ix = ix0; ix <= ix1; ++ix) {
        const double rx = x0_ + (ix + 0.5) * cell_ - cx, ry = y0_ + (iy + 0.5) * cell_ - cy;
        bool overlap;
        if (is_box) {  // separating axes: the grid's (by the index range) and the box's own two
          const BoxData& b = boxes_[object];
          const double r = (std::abs(b.c) + std::abs(b.s)) * hc;
          overlap = std::abs(b.c * rx + b.s * ry) <= b.hx + r + kPad && std::abs(-b.s * rx + b.c * ry) <= b.hy + r + kPad;
        } else {
          const double qx = std::max(std::abs(rx) - hc, 0.0), qy = std::max(std::abs(ry) - hc, 0.0);
          overlap = qx * qx + qy * qy <= (ex + kPad) * (ex + kPad);
        }
        if (overlap) f(static_cast<size_t>(iy) * nx_ + ix);
      }
    }
  };
  const int n = num_objects();
  cell_start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (int k = 0; k < n; ++k) for_cells(k, [&](size_t i) { ++cell_start_[i + 1]; });
  for (size_t i = 1; i < cell_start_.size(); ++i) cell_start_[i] += cell_start_[i - 1];
  items_.resize(cell_start_.back());
  std::vector<uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (int k = 0; k < n; ++k) for_cells(k, [&](size_t i) { items_[fill[i]++] = k; });
}

template <typename Visit>
void RayCaster::walk(double ox, double oy, double dx, double dy, double t0, double t1, Visit&& visit) const {
  if (nx_ == 0 || !(t0 <= t1)) return;
  // Clip [t0, t1] to the grid's rectangle.
  auto clip = [&](double o, double d, double lo, double hi) {
    if (d == 0) return o >= lo && o <= hi;
    double a = (lo - o) / d, b = (hi - o) / d;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    return t0 <= t1;
  };
  if (!clip(ox, dx, x0_, x0_ + nx_ * cell_) || !clip(oy, dy, y0_, y0_ + ny_ * cell_)) return;
  int ix = std::clamp(static_cast<int>(std::floor((ox + t0 * dx - x0_) / cell_)), 0, nx_ - 1);
  int iy = std::clamp(static_cast<int>(std::floor((oy + t0 * dy - y0_) / cell_)), 0, ny_ - 1);
  const int sx = dx > 0 ? 1 : -1, sy = dy > 0 ? 1 : -1;
  double tnx = dx != 0 ? (x0_ + (ix + (dx > 0)) * cell_ - ox) / dx : kInf;
  double tny = dy != 0 ? (y0_ + (iy + (dy > 0)) * cell_ - oy) / dy : kInf;
  const double tdx = dx != 0 ? cell_ / std::abs(dx) : kInf, tdy = dy != 0 ? cell_ / std::abs(dy) : kInf;
  for (;;) {
    const double t_exit = std::min(tnx, tny);
    const size_t i = static_cast<size_t>(iy) * nx_ + ix;
    if (visit(items_.data() + cell_start_[i], items_.data() + cell_start_[i + 1], std::min(t_exit, t1))) return;
    if (t_exit >= t1) return;
    if (tnx < tny) {
      ix += sx;
      if (ix < 0 || ix >= nx_) return;
      tnx += tdx;
    } else {
      iy += sy;
      if (iy < 0 || iy >= ny_) return;
      tny += tdy;
    }
  }
}

namespace {

/// Slab test along one axis; false when the ray misses.
inline bool slab(double o, double d, double h, int axis, double& tn, double& tf, int& face) {
  if (d == 0) return std::abs(o) <= h;
  const double inv = 1.0 / d;
  double a = (-h - o) * inv, b = (h - o) * inv;
  if (a > b) std::swap(a, b);
  if (a > tn) tn = a, face = axis * 2 + (d > 0);
  tf = std::min(tf, b);
  return true;
}

}  // namespace

std::optional<Hit> RayCaster::cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                   double max_range) const {
  const double ox = origin.x(), oy = origin.y(), oz = origin.z();
  const double dx = dir.x(), dy = dir.y(), dz = dir.z();
  Best best{max_range, -2, 0};
  if (dz < 0 && oz > 0 && -oz / dz <= max_range) best = {-oz / dz, -1, 0};
  const int nb = static_cast<int>(boxes_.size());

  // Only where the ray is within the obstacles' heights.
  double t0 = 0, t1 = best.t;
  if (dz != 0) {
    double a = (z_lo_ - oz) / dz, b = (z_hi_ - oz) / dz;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a), t1 = std::min(t1, b);
  } else if (oz < z_lo_ || oz > z_hi_) {
    t1 = -1;
  }
  walk(ox, oy, dx, dy, t0, t1, [&](const int32_t* it, const int32_t* end, double t_exit) {
    for (; it != end; ++it) {
      const int k = *it;
      double tn = -kInf, tf = kInf;
      int face = 0;
      if (k < nb) {
        const BoxData& b = boxes_[k];
        const double px = ox - b.cx, py = oy - b.cy;
        if (!slab(b.c * px + b.s * py, b.c * dx + b.s * dy, b.hx, 0, tn, tf, face) ||
            !slab(-b.s * px + b.c * py, -b.s * dx + b.c * dy, b.hy, 1, tn, tf, face) ||
            !slab(oz - b.cz, dz, b.hz, 2, tn, tf, face)) {
          continue;
        }
      } else {
        const CylData& c = cyls_[k - nb];
        const double px = ox - c.cx, py = oy - c.cy, a = dx * dx + dy * dy;
        const double cc = px * px + py * py - c.r * c.r;
        double sn = -kInf, sf = kInf;
        if (a > 1e-18) {
          const double b = px * dx + py * dy, disc = b * b - a * cc;
          if (disc < 0) continue;
          const double sq = std::sqrt(disc);
          sn = (-b - sq) / a, sf = (-b + sq) / a;
        } else if (cc > 0) {
          continue;
        }
        int zface = 0;
        if (!slab(oz - c.cz, dz, c.hz, 0, tn, tf, zface)) continue;
        face = dz > 0 ? kBottom : kTop;
        if (sn >= tn) tn = sn, face = kSide;
        tf = std::min(tf, sf);
      }
      if (tn <= tf && tn > 0 && tn <= best.t) best = {tn, k, face};
    }
    return best.t <= t_exit;
  });

  if (best.object == -2) return std::nullopt;
  Hit hit{best.t, Eigen::Vector3d::UnitZ(), best.object, kFloorColor};
  if (best.object >= 0) {
    hit.color = colors_[best.object];
    if (best.object < nb) {
      const BoxData& b = boxes_[best.object];
      const int axis = best.face / 2;
      const double sign = (best.face & 1) ? -1.0 : 1.0;
      const Eigen::Vector3d local = sign * Eigen::Vector3d::Unit(axis);
      hit.normal = Eigen::Vector3d(b.c * local.x() - b.s * local.y(), b.s * local.x() + b.c * local.y(), local.z());
    } else {
      const CylData& c = cyls_[best.object - nb];
      if (best.face == kSide) {
        hit.normal = Eigen::Vector3d(ox + best.t * dx - c.cx, oy + best.t * dy - c.cy, 0).normalized();
      } else {
        hit.normal = Eigen::Vector3d(0, 0, best.face == kTop ? 1 : -1);
      }
    }
  }
  return hit;
}

double RayCaster::range(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range) const {
  const std::optional<Hit> hit = cast(origin, dir, max_range);
  return hit ? hit->range : kInf;
}

void RayCaster::spans(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir, double max_s,
                      std::vector<Span>& out) const {
  out.clear();
  const double ox = origin.x(), oy = origin.y(), dx = dir.x(), dy = dir.y();
  walk(ox, oy, dx, dy, 0, max_s, [&](const int32_t* it, const int32_t* end, double) {
    Span sp;
    for (; it != end; ++it) {
      if (span_of(*it, ox, oy, dx, dy, max_s, sp)) out.push_back(sp);
    }
    return false;
  });
  std::sort(out.begin(), out.end(),
            [](const Span& a, const Span& b) { return a.s_in < b.s_in || (a.s_in == b.s_in && a.object < b.object); });
  out.erase(std::unique(out.begin(), out.end(),
                        [](const Span& a, const Span& b) { return a.object == b.object && a.s_in == b.s_in; }),
            out.end());
}

bool RayCaster::span_of(int k, double ox, double oy, double dx, double dy, double max_s, Span& out) const {
  const int nb = static_cast<int>(boxes_.size());
  double tn = -kInf, tf = kInf;
  Eigen::Vector2d normal = Eigen::Vector2d::Zero();
  double z0, z1;
  if (k < nb) {
    const BoxData& b = boxes_[k];
    const double px = ox - b.cx, py = oy - b.cy;
    int face = -1;
    if (!slab(b.c * px + b.s * py, b.c * dx + b.s * dy, b.hx, 0, tn, tf, face) ||
        !slab(-b.s * px + b.c * py, -b.s * dx + b.c * dy, b.hy, 1, tn, tf, face)) {
      return false;
    }
    if (tn > 0 && face >= 0) {
      const double sign = (face & 1) ? -1.0 : 1.0;
      normal = face / 2 == 0 ? Eigen::Vector2d(sign * b.c, sign * b.s) : Eigen::Vector2d(-sign * b.s, sign * b.c);
    }
    z0 = b.cz - b.hz, z1 = b.cz + b.hz;
  } else {
    const CylData& c = cyls_[k - nb];
    const double px = ox - c.cx, py = oy - c.cy;
    const double b = px * dx + py * dy, disc = b * b - (px * px + py * py - c.r * c.r);
    if (disc < 0) return false;
    const double sq = std::sqrt(disc);
    tn = -b - sq, tf = -b + sq;
    if (tn > 0) normal = Eigen::Vector2d(px + tn * dx, py + tn * dy) / c.r;
    z0 = c.cz - c.hz, z1 = c.cz + c.hz;
  }
  if (tn > tf || tf < 0 || tn > max_s) return false;
  out = {tn, tf, z0, z1, normal, k, colors_[k]};
  return true;
}

void RayCaster::spans_until(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir, double max_s,
                            std::vector<Span>& out, std::vector<Span>& pending, SpanSink sink, void* context) const {
  out.clear();
  pending.clear();
  const double ox = origin.x(), oy = origin.y(), dx = dir.x(), dy = dir.y();
  auto by_s = [](const Span& a, const Span& b) { return a.s_in < b.s_in || (a.s_in == b.s_in && a.object < b.object); };
  // Moves the pending spans with s_in <= s_done to `out`, sorted; returns the index of the first one moved.
  auto hand_over = [&](double s_done) {
    const size_t first = out.size();
    const auto ready = std::partition(pending.begin(), pending.end(), [&](const Span& p) { return p.s_in <= s_done; });
    out.insert(out.end(), pending.begin(), ready);
    pending.erase(pending.begin(), ready);
    std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end(), by_s);
    return first;
  };
  // A footprint entered at s_in is listed in the cell that holds its entry point (cells list every object within
  // kPad of them), so a span with s_in before the current cell was found, and handed over, in an earlier cell.
  double s_enter = -kInf;
  bool stopped = false;
  walk(ox, oy, dx, dy, 0, max_s, [&](const int32_t* it, const int32_t* end, double t_exit) {
    for (; it != end; ++it) {
      Span sp;
      if (!span_of(*it, ox, oy, dx, dy, max_s, sp) || sp.s_in <= s_enter) continue;
      bool seen = false;
      for (const Span& p : pending) seen = seen || p.object == sp.object;
      if (!seen) pending.push_back(sp);
    }
    s_enter = t_exit;
    const size_t first = hand_over(t_exit);
    stopped = !sink(context, out, first, t_exit);
    return stopped;
  });
  if (stopped) return;
  const size_t first = hand_over(kInf);
  sink(context, out, first, kInf);
}

}  // namespace driftlab::sim
