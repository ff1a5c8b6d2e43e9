// Exact ray casting against a World (yawed boxes, vertical cylinders and the floor plane z = 0), accelerated by a
// uniform 2D grid over the world's footprint: a ray walks the cells it crosses (2D DDA) and stops at the first hit
// closer than the next cell boundary. All positions are in the world frame, all lengths in metres.
// Surfaces are seen from outside only: a ray that starts inside an obstacle does not hit that obstacle, and the
// floor is hit only by rays coming down from z > 0.
// Thread-safety: immutable after construction; const methods may be called concurrently. They never allocate.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <type_traits>
#include <vector>

#include "sim/world.h"

namespace driftlab::sim {

/// The first surface met by a ray.
struct Hit {
  double range;             ///< distance from the ray origin [m]
  Eigen::Vector3d normal;   ///< unit outward normal of the surface hit, world frame
  int object;               ///< index of the obstacle: boxes first, then cylinders; -1 for the floor
  std::array<uint8_t, 3> color;  ///< RGB of the obstacle; kFloorColor for the floor
};

/// Where a horizontal 2D ray crosses an obstacle's footprint (for 2.5D renderers, see camera_render.cc).
struct Span {
  double s_in, s_out;       ///< distances along the 2D ray where it enters and leaves the footprint [m]; s_in < 0
                            ///< when the ray starts inside it
  double z_min, z_max;      ///< vertical extent of the obstacle [m]
  Eigen::Vector2d normal;   ///< outward normal of the footprint where the ray enters it (zero when s_in < 0)
  int object;               ///< as Hit::object
  std::array<uint8_t, 3> color;
};

class RayCaster {
 public:
  static constexpr std::array<uint8_t, 3> kFloorColor{128, 128, 128};

  /// Builds the grid: cells of `cell_size` [m] (enlarged if the world would need more than 4M cells).
  /// Copies what it needs: `world` may be destroyed afterwards.
  explicit RayCaster(const World& world, double cell_size = 0.5);

  /// First hit along the ray origin + t*dir (dir unit length) for t in (0, max_range]; nullopt when nothing within
  /// max_range.
  std::optional<Hit> cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range) const;

  /// Convenience for 2D lidars: the range only [m], or +infinity.
  double range(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range) const;

  /// Every obstacle whose footprint the horizontal ray origin + s*dir (dir a unit 2D vector) crosses at some
  /// s in [0, max_s], appended to `out` sorted by s_in (out is cleared first; it allocates only when it grows).
  void spans(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir, double max_s, std::vector<Span>& out) const;

  /// The spans() of a ray handed over while the grid is walked, so that a renderer can stop as soon as nearer spans
  /// hide everything it still needs. After each grid cell, the spans not handed over yet whose s_in is at most
  /// s_done (where the ray leaves that cell; +infinity once the walk is over) are appended to `out`, sorted as in
  /// spans(); then sink(context, out, first, s_done) is called, `first` the index of the first new span (there may
  /// be none). Every span with s_in <= s_done is then in `out`, so `out` is always a prefix of what spans()
  /// returns (all of it if sink never returns false). The walk stops when sink returns false. `pending` is
  /// scratch; neither vector allocates unless it grows.
  using SpanSink = bool (*)(void* context, const std::vector<Span>& out, size_t first, double s_done);
  void spans_until(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir, double max_s, std::vector<Span>& out,
                   std::vector<Span>& pending, SpanSink sink, void* context) const;
  /// spans_until with any callable bool(const std::vector<Span>& out, size_t first, double s_done).
  template <typename F>
  void spans_until(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir, double max_s, std::vector<Span>& out,
                   std::vector<Span>& pending, F&& sink) const {
    using Fn = std::remove_reference_t<F>;
    spans_until(
        origin, dir, max_s, out, pending,
        [](void* f, const std::vector<Span>& o, size_t first, double s_done) -> bool {
          return (*static_cast<Fn*>(f))(o, first, s_done);
        },
        const_cast<void*>(static_cast<const void*>(std::addressof(sink))));
  }

  /// Lowest bottom and highest top of all obstacles [m]; +infinity and -infinity when there are none.
  double z_bottom() const { return z_lo_; }
  double z_top() const { return z_hi_; }

  int num_objects() const { return static_cast<int>(colors_.size()); }
  double cell_size() const { return cell_; }

 private:
  struct BoxData {
    double cx, cy, cz, hx, hy, hz, c, s;  // centre, half extents, cos/sin yaw
  };
  struct CylData {
    double cx, cy, cz, r, hz;  // centre, radius, half height
  };
  struct Best;

  /// 2D DDA over the cells crossed by (ox, oy) + t (dx, dy) for t in [t0, t1], in order; calls
  /// visit(first item, end item, t where the ray leaves the cell) and stops when it returns true.
  /// The Span of object k along the horizontal ray (ox, oy) + s (dx, dy); false when the ray misses it or
  /// crosses it outside [0, max_s] (as in spans()).
  bool span_of(int k, double ox, double oy, double dx, double dy, double max_s, Span& out) const;

  template <typename Visit>
  void walk(double ox, double oy, double dx, double dy, double t0, double t1, Visit&& visit) const;

  std::vector<BoxData> boxes_;
  std::vector<CylData> cyls_;
  std::vector<std::array<uint8_t, 3>> colors_;
  double z_lo_ = 0, z_hi_ = 0;   // vertical extent of all obstacles
  double x0_ = 0, y0_ = 0;       // grid corner
  double cell_ = 0.5;
  int nx_ = 0, ny_ = 0;
  std::vector<uint32_t> cell_start_;  // CSR: objects of cell (ix, iy) are items_[start[i]..start[i+1]), i = iy*nx+ix
  std::vector<int32_t> items_;
};

}  // namespace driftlab::sim
