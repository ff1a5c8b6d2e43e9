// The renderer exploits that every obstacle is a vertical prism (a footprint extruded between two heights): along
// a vertical half-plane from the camera, a horizontal 2D ray crosses the same footprints at the same distances
// whatever the elevation. So the view is cut into thin azimuth slices (a quarter pixel wide or less); each slice's
// footprint crossings (RayCaster::spans) are computed once per frame, and each pixel only compares its own height
// along the slice with the crossings' height ranges: a side, top or bottom face, or the floor. A level camera uses
// one slice per column; a tilted camera uses whichever slices its pixels fall in, so any orientation works.
// A (nearly) level camera takes a faster path (render_level below): sky and floor are drawn row by row first (one
// floor distance per row and column, stepped along the row); then each column, a vertical half-plane, walks its
// spans along its exact azimuth near to far (RayCaster::spans_until) until nearer spans hide everything, each
// span's side face showing as one run of rows, and the obstacles are drawn over sky and floor.
#include "sim/camera_render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <opencv2/core.hpp>

namespace driftlab::sim {
namespace {

/// A cheap monotonic stand-in for the angle of (x, y): 0..4 for 0..2 pi.
inline double diamond_angle(double x, double y) {
  if (y >= 0) return x >= 0 ? y / (x + y) : 1 - x / (-x + y);
  return x < 0 ? 2 - y / (-x - y) : 3 + x / (x - y);
}

/// The unit 2D direction whose diamond angle is p.
Eigen::Vector2d diamond_direction(double p) {
  const int q = static_cast<int>(p);
  const double f = p - q;
  Eigen::Vector2d v(1 - f, f);
  for (int i = 0; i < (q & 3); ++i) v = Eigen::Vector2d(-v.y(), v.x());
  return v.normalized();
}

struct SliceRef {
  uint64_t frame = 0;
  uint32_t begin = 0, end = 0;  // into Scratch::pool
  double z_top = 0;             // highest top among the slice's spans [m]
};

/// One image column of a level camera: a vertical half-plane from the camera.
struct LevelColumn {
  double dz0;     // z of the ray of row 0; row r adds r * ez
  double hx, hy;  // horizontal part of the column's ray (at the middle row), not unit length: H = |(hx, hy)|
  double H, H2, inv_H;
  int r_floor;  // first row whose ray goes down
};

/// Rows [ra, rb) of one image column see the side of span `span` (unless an earlier run holds them), s away.
struct SideRun {
  int ra, rb;
  int32_t span;
  double s;
};

/// Per-thread memory reused from frame to frame.
struct Scratch {
  uint64_t frame = 0;
  std::vector<SliceRef> slices;
  std::vector<Span> pool, tmp;
  // Level fast path: the columns, and one column's rows.
  std::vector<LevelColumn> columns;
  std::vector<Span> pending;
  std::vector<SideRun> sides;
  std::vector<std::pair<int, int>> covered;
  std::vector<double> best;  // per row
  std::vector<int32_t> hit;  // per row: index into tmp (| kCapFlag), or kNoHit
};
thread_local Scratch scratch;

/// Which floor square (1 m checkerboard) a point is in: light or dark. (Integer floor without a libm call.)
inline bool light_square(double x, double y) {
  const int64_t ix = static_cast<int64_t>(x) - (x < static_cast<double>(static_cast<int64_t>(x)));
  const int64_t iy = static_cast<int64_t>(y) - (y < static_cast<double>(static_cast<int64_t>(y)));
  return ((ix + iy) & 1) == 0;
}

constexpr std::array<uint8_t, 3> kFloorLight{190, 190, 180}, kFloorDark{105, 105, 100};

inline void put(uint8_t* px, const std::array<uint8_t, 3>& rgb, double gain) {
  px[0] = static_cast<uint8_t>(std::min(255.0, rgb[2] * gain + 0.5));
  px[1] = static_cast<uint8_t>(std::min(255.0, rgb[1] * gain + 0.5));
  px[2] = static_cast<uint8_t>(std::min(255.0, rgb[0] * gain + 0.5));
}

/// put() with the gain in 16-bit fixed point, 0 <= g <= 65536.
inline void put_fixed(uint8_t* px, const std::array<uint8_t, 3>& rgb, uint32_t g) {
  px[0] = static_cast<uint8_t>((rgb[2] * g + 32768) >> 16);
  px[1] = static_cast<uint8_t>((rgb[1] * g + 32768) >> 16);
  px[2] = static_cast<uint8_t>((rgb[0] * g + 32768) >> 16);
}

/// An RGB colour for put_packed: B, G and R in bits 0, 21 and 42.
inline uint64_t pack(const std::array<uint8_t, 3>& rgb) {
  return rgb[2] | uint64_t{rgb[1]} << 21 | uint64_t{rgb[0]} << 42;
}

/// put_fixed() with the gain in 13-bit fixed point, 0 <= g <= 8192: one multiply for the three channels (each
/// product stays below 2^21, within its field).
inline void put_packed(uint8_t* px, uint64_t packed, uint32_t g) {
  constexpr uint64_t kHalf = 4096 | uint64_t{4096} << 21 | uint64_t{4096} << 42;
  const uint64_t p = packed * g + kHalf;
  px[0] = static_cast<uint8_t>(p >> 13);
  px[1] = static_cast<uint8_t>(p >> 34);
  px[2] = static_cast<uint8_t>(p >> 55);
}


/// Distance dimming: 1 at the camera, 0.4 at max_range.
inline double dim(double t, double max_range) { return t >= max_range ? 0.4 : 1.0 - 0.6 * t * (1.0 / max_range); }

/// Lambertian-like shading from the cosine between the ray and the surface normal.
inline double shade(double cosine) { return 0.35 + 0.65 * std::abs(cosine); }

}  // namespace

namespace detail {

void render_camera_generic(const RayCaster& caster, const CameraModel& model, const Eigen::Isometry3d& camera_in_world,
                           cv::Mat& bgr) {
  const int width = std::max(1, model.width), height = std::max(1, model.height);
  bgr.create(height, width, CV_8UC3);
  const double max_range = model.max_range;
  const double f = 0.5 * width / std::tan(0.5 * model.hfov);
  const Eigen::Matrix3d R = camera_in_world.linear();
  const Eigen::Vector3d o = camera_in_world.translation();
  const double ox = o.x(), oy = o.y(), oz = o.z();
  // Ray of pixel (c, r): a + c * b + r * e (not unit length).
  const Eigen::Vector3d b = -R.col(1) / f, e = -R.col(2) / f;
  const Eigen::Vector3d a = R.col(0) + (0.5 - 0.5 * width) * b + (0.5 - 0.5 * height) * e;

  // Slices of equal diamond angle; the widest is at most 8/K rad, a quarter of a pixel's angle at the centre.
  const int K = std::clamp(static_cast<int>(std::ceil(32.0 * width / std::max(model.hfov, 1e-3))), 64, 1 << 18);
  const double quarter_k = K / 4.0;
  Scratch& s = scratch;
  ++s.frame;
  if (s.slices.size() < static_cast<size_t>(K)) s.slices.resize(K);
  s.pool.clear();
  const Eigen::Vector2d origin2(ox, oy);

  for (int r = 0; r < height; ++r) {
    uint8_t* row = bgr.ptr<uint8_t>(r);
    Eigen::Vector3d d = a + r * e;
    for (int c = 0; c < width; ++c, d += b) {
      uint8_t* px = row + 3 * c;
      const double dx = d.x(), dy = d.y(), dz = d.z();
      const double h2 = dx * dx + dy * dy, n = std::sqrt(h2 + dz * dz);
      if (h2 < 1e-12 * n * n) {  // looking straight up or down: no azimuth, ask the caster
        const Eigen::Vector3d unit = d / n;
        const std::optional<Hit> hit = caster.cast(o, unit, max_range);
        if (!hit) {
          put(px, kSkyColor, 1.0);
        } else if (hit->object < 0) {
          const Eigen::Vector3d p = o + hit->range * unit;
          put(px, light_square(p.x(), p.y()) ? kFloorLight : kFloorDark, dim(hit->range, max_range));
        } else {
          put(px, hit->color, shade(hit->normal.dot(unit)) * dim(hit->range, max_range));
        }
        continue;
      }
      const double h = std::sqrt(h2), inv_h = 1.0 / h;
      const double m = dz * inv_h, scale = n * inv_h;  // height gained and 3D distance per metre of s
      const int k = std::min(K - 1, static_cast<int>(diamond_angle(dx, dy) * quarter_k));
      SliceRef& slice = s.slices[k];
      if (slice.frame != s.frame) {
        caster.spans(origin2, diamond_direction((k + 0.5) * (4.0 / K)), max_range, s.tmp);
        slice.frame = s.frame;
        slice.begin = static_cast<uint32_t>(s.pool.size());
        s.pool.insert(s.pool.end(), s.tmp.begin(), s.tmp.end());
        slice.end = static_cast<uint32_t>(s.pool.size());
        slice.z_top = -std::numeric_limits<double>::infinity();
        for (const Span& sp : s.tmp) slice.z_top = std::max(slice.z_top, sp.z_max);
      }

      const double s_max = max_range * h / n;
      double best = s_max;
      const Span* hit = nullptr;
      double cosine = 0;
      bool floor = false;
      const double s_floor = (dz < 0 && oz > 0) ? oz * h / -dz : std::numeric_limits<double>::infinity();
      if (s_floor < best) best = s_floor, floor = true;
      // A rising ray that is above every obstacle of the slice can stop there.
      double s_stop = best;
      if (m > 0) s_stop = std::min(best, std::max(0.0, (slice.z_top - oz) / m));
      for (uint32_t i = slice.begin; i < slice.end; ++i) {
        const Span& sp = s.pool[i];
        if (sp.s_in >= best || sp.s_in > s_stop) break;
        const double s_in = std::max(sp.s_in, 0.0), z_in = oz + m * s_in;
        if (z_in >= sp.z_min && z_in <= sp.z_max) {
          if (sp.s_in <= 0) continue;  // the camera is inside this obstacle: it does not see it
          best = s_in, hit = &sp, floor = false;
          cosine = (sp.normal.x() * dx + sp.normal.y() * dy) / n;
          break;  // every later span starts farther
        }
        if (z_in > sp.z_max && m < 0) {
          const double st = (sp.z_max - oz) / m;
          if (st <= sp.s_out && st < best) best = st, hit = &sp, floor = false, cosine = dz / n;
        } else if (z_in < sp.z_min && m > 0) {
          const double sb = (sp.z_min - oz) / m;
          if (sb <= sp.s_out && sb < best) best = sb, hit = &sp, floor = false, cosine = dz / n;
        }
      }
      if (hit != nullptr) {
        put(px, hit->color, shade(cosine) * dim(best * scale, max_range));
      } else if (floor) {
        const double x = ox + best * inv_h * dx, y = oy + best * inv_h * dy;
        put(px, light_square(x, y) ? kFloorLight : kFloorDark, dim(best * scale, max_range));
      } else if (dz < 0 && oz > 0) {  // floor beyond max_range: the average floor colour, fully dimmed
        put(px, {148, 148, 140}, dim(max_range, max_range));
      } else {
        put(px, kSkyColor, 1.0);
      }
    }
  }
}

}  // namespace detail

namespace {

constexpr int32_t kNoHit = -1;
constexpr int32_t kCapFlag = 1 << 30;  // set on `hit` when the top or bottom face was hit (not the side)
constexpr double kInf = std::numeric_limits<double>::infinity();

/// The first r in [lo, hi] with pred(r), for a pred that is false and then true on [lo, hi) (hi when it never
/// holds); searched from `guess`, an estimate (any value works, a close one takes few steps).
template <typename Pred>
int first_row(int lo, int hi, double guess, Pred&& pred) {
  int r = guess >= hi ? hi : guess > lo ? static_cast<int>(guess) : lo;
  while (r > lo && pred(r - 1)) --r;
  while (r < hi && !pred(r)) ++r;
  return r;
}

/// What the floor drawing needs of a level frame.
struct LevelFloor {
  int width;
  double oz, ez, max_range, k_dim;  // k_dim: dimming per metre
  // The floor point of a ray with k = oz / -D (D its z) is the camera + k (hx, hy); its square is light when
  // ((int64)(x0 + k hx) ^ (int64)(y0 + k hy) ^ parity0) & 1 == 0: x0, y0 are the camera's offset in its own square
  // plus an even number of metres that keeps them positive within max_range.
  double x0, y0;
  int64_t parity0;
  const LevelColumn* cols;
  uint8_t beyond[3];
  uint64_t palette[2];  // light, dark: pack()ed
};

inline const std::array<uint8_t, 3>& floor_rgb(const LevelFloor& F, const LevelColumn& col, double k) {
  const int64_t ix = static_cast<int64_t>(F.x0 + k * col.hx), iy = static_cast<int64_t>(F.y0 + k * col.hy);
  return ((ix ^ iy ^ F.parity0) & 1) == 0 ? kFloorLight : kFloorDark;
}

/// The floor at pixel (r, c) below the horizon, exactly: t = k * sqrt(H^2 + D^2) is the 3D distance.
inline void floor_pixel(const LevelFloor& F, int r, int c, uint8_t* px) {
  const LevelColumn& col = F.cols[c];
  const double D = col.dz0 + r * F.ez, k = F.oz / -D, t = k * std::sqrt(col.H2 + D * D);
  if (t < F.max_range) {
    put_fixed(px, floor_rgb(F, col, k), static_cast<uint32_t>(static_cast<int32_t>((1 - F.k_dim * t) * 65536.0)));
  } else {
    px[0] = F.beyond[0], px[1] = F.beyond[1], px[2] = F.beyond[2];
  }
}

/// Image row r, all below the horizon, as floor. The squares are exact per pixel; the distance gain is exact every
/// 32 columns (16 for a camera not quite level) and linear in between where that is exact to far below a grey
/// level: always for a level camera (k is the same along the row and t a convex, nearly flat function of the
/// column: the chord is off by less than k * 3e-3 m, a third of a grey level at 20 m), after a check at the middle
/// otherwise. Where the range limit cuts in, every pixel is exact.
template <bool kLevel>
void floor_row(const LevelFloor& F, int r, uint8_t* row) {
  const LevelColumn* const cols = F.cols;
  const double D_row = cols[0].dz0 + r * F.ez, k_row = F.oz / -D_row;
  auto D_of = [&](int c) { return kLevel ? D_row : cols[c].dz0 + r * F.ez; };
  auto k_of = [&](int c) { return kLevel ? k_row : F.oz / -D_of(c); };
  auto t_of = [&](int c) {
    const double D = D_of(c);
    return k_of(c) * std::sqrt(cols[c].H2 + D * D);
  };
  const int W = F.width;
  double t0 = t_of(0);
  for (int c0 = 0; c0 < W;) {
    const int c1 = std::min(c0 + (kLevel ? 32 : 16), W - 1), n = c1 - c0;
    const int stop = c1 == W - 1 ? W : c1;  // this stretch: [c0, stop)
    const double t1 = n > 0 ? t_of(c1) : t0;
    bool linear = n > 1 && t0 < F.max_range && t1 < F.max_range;
    if (linear && !kLevel) {
      const int cm = c0 + n / 2;
      const double tm = t_of(cm);
      linear = tm < F.max_range && std::abs(tm - (t0 + (t1 - t0) * (cm - c0) / n)) * F.k_dim < 1.0 / 2048;
    }
    if (linear) {
      // Gain in 19-bit fixed point (put_packed takes 13 bits).
      const double g0 = (1 - F.k_dim * t0) * 524288.0, g1 = (1 - F.k_dim * t1) * 524288.0;
      int32_t g = static_cast<int32_t>(g0);
      const int32_t dg = static_cast<int32_t>((g1 - g0) / n);
      if (kLevel) {
        // The floor point moves linearly along the row: its coordinates in 32.32 fixed point, exact at c0.
        constexpr double kOne = 4294967296.0;
        int64_t X = static_cast<int64_t>((F.x0 + k_row * cols[c0].hx) * kOne);
        int64_t Y = static_cast<int64_t>((F.y0 + k_row * cols[c0].hy) * kOne);
        const int64_t dX = static_cast<int64_t>(k_row * (cols[c1].hx - cols[c0].hx) / n * kOne);
        const int64_t dY = static_cast<int64_t>(k_row * (cols[c1].hy - cols[c0].hy) / n * kOne);
        const int64_t p0 = F.parity0 << 32;
        uint8_t* px = row + 3 * c0;
        for (int c = c0; c < stop; ++c, g += dg, X += dX, Y += dY, px += 3) {
          put_packed(px, F.palette[((X ^ Y ^ p0) >> 32) & 1], static_cast<uint32_t>(g) >> 6);
        }
      } else {
        for (int c = c0; c < stop; ++c, g += dg) {
          put_packed(row + 3 * c, pack(floor_rgb(F, cols[c], k_of(c))), static_cast<uint32_t>(g) >> 6);
        }
      }
    } else {
      for (int c = c0; c < stop; ++c) floor_pixel(F, r, c, row + 3 * c);
    }
    c0 = stop, t0 = t1;
  }
}

/// The level fast path: with the camera's up axis (nearly) vertical, every image column is a vertical half-plane.
/// The sky and the floor are drawn first, row by row (each image row below the horizon has one floor distance per
/// column); then each column's footprint crossings are walked, exactly along the column's own azimuth and near to
/// far (RayCaster::spans_until), each span filling the contiguous range of rows that can see it (a per-row depth
/// buffer), and the walk stops once no farther span can change any row; the obstacles' pixels are drawn over the
/// floor and sky. Per pixel this makes the same comparisons as the generic path. Returns false (nothing drawn) when
/// the camera is not level enough: the column's azimuth may then drift by at most an eighth of a pixel from top to
/// bottom (the generic path's error).
bool render_level(const RayCaster& caster, const CameraModel& model, const Eigen::Isometry3d& camera_in_world,
                  cv::Mat& bgr) {
  const int width = std::max(1, model.width), height = std::max(1, model.height);
  const double f = 0.5 * width / std::tan(0.5 * model.hfov);
  const Eigen::Matrix3d R = camera_in_world.linear();
  const double tilt = std::hypot(R(0, 2), R(1, 2));
  const double u_max = 0.5 * width / f;
  const double max_range = model.max_range;
  const Eigen::Vector3d o = camera_in_world.translation();
  const double ox = o.x(), oy = o.y(), oz = o.z();
  if (!(R(2, 2) > 0.5) || !std::isfinite(f) || !(f > 0) || tilt * 0.5 * height * (1 + u_max * u_max) > 0.125 ||
      !(max_range > 0 && max_range < 1e6) || !(std::abs(ox) < 1e15 && std::abs(oy) < 1e15 && std::isfinite(oz))) {
    return false;
  }
  bgr.create(height, width, CV_8UC3);
  const Eigen::Vector3d b = -R.col(1) / f, e = -R.col(2) / f;
  const Eigen::Vector3d a = R.col(0) + (0.5 - 0.5 * width) * b + (0.5 - 0.5 * height) * e;
  const double ez = e.z();  // < 0: rows go down
  const double r_ref = 0.5 * (height - 1);  // the azimuth of a column is taken at the image's middle row
  const bool floor_visible = oz > 0;
  const double floor_z = floor_visible ? 0.0 : -kInf;
  const double z_lo = caster.z_bottom(), z_hi = caster.z_top();
  const float range_f = static_cast<float>(max_range), k_dim = static_cast<float>(0.6 / max_range);
  uint8_t sky[3], beyond[3];
  put(sky, kSkyColor, 1.0);
  put(beyond, {148, 148, 140}, dim(max_range, max_range));

  Scratch& s = scratch;
  s.columns.resize(width);
  LevelColumn* const cols = s.columns.data();
  int r_sky = height, r_below = 0;  // rows above r_sky look up in every column, rows from r_below down in every one
  bool level = true;
  for (int c = 0; c < width; ++c) {
    LevelColumn& col = cols[c];
    const Eigen::Vector3d d0 = a + c * b;  // row 0 of this column
    col.hx = d0.x() + r_ref * e.x(), col.hy = d0.y() + r_ref * e.y();
    col.H2 = col.hx * col.hx + col.hy * col.hy;
    col.H = std::sqrt(col.H2), col.inv_H = 1.0 / col.H;
    col.dz0 = d0.z();
    level = level && col.dz0 == cols[0].dz0;
    auto slope = [&](int r) { return (col.dz0 + r * ez) * col.inv_H; };
    int r_floor = 0;
    if (col.dz0 >= 0) r_floor = static_cast<int>(std::min(col.dz0 / -ez, static_cast<double>(height)));
    while (r_floor > 0 && slope(r_floor - 1) < 0) --r_floor;
    while (r_floor < height && slope(r_floor) >= 0) ++r_floor;
    col.r_floor = r_floor;
    r_sky = std::min(r_sky, r_floor), r_below = std::max(r_below, r_floor);
  }

  // Sky and floor, row by row (the obstacles are drawn over them below).
  if (!floor_visible) r_sky = r_below = height;
  if (r_sky > 0) {
    uint8_t* row0 = bgr.ptr<uint8_t>(0);
    for (int c = 0; c < width; ++c) row0[3 * c] = sky[0], row0[3 * c + 1] = sky[1], row0[3 * c + 2] = sky[2];
    for (int r = 1; r < r_sky; ++r) std::copy(row0, row0 + 3 * width, bgr.ptr<uint8_t>(r));
  }
  if (r_sky < height) {
    LevelFloor F{width, oz, ez, max_range, 0.6 / max_range, 0, 0, 0, cols, {beyond[0], beyond[1], beyond[2]},
                 {pack(kFloorLight), pack(kFloorDark)}};
    const double fx = std::floor(ox), fy = std::floor(oy), off = 2 * std::ceil(0.5 * max_range) + 2;
    F.x0 = ox - fx + off, F.y0 = oy - fy + off;
    F.parity0 = (static_cast<int64_t>(fx) + static_cast<int64_t>(fy)) & 1;
    for (int r = r_sky; r < r_below; ++r) {  // the horizon crosses these rows (a camera not quite level)
      uint8_t* row = bgr.ptr<uint8_t>(r);
      for (int c = 0; c < width; ++c) {
        if (r >= cols[c].r_floor) {
          floor_pixel(F, r, c, row + 3 * c);
        } else {
          row[3 * c] = sky[0], row[3 * c + 1] = sky[1], row[3 * c + 2] = sky[2];
        }
      }
    }
    for (int r = r_below; r < height; ++r) {
      if (level) {
        floor_row<true>(F, r, bgr.ptr<uint8_t>(r));
      } else {
        floor_row<false>(F, r, bgr.ptr<uint8_t>(r));
      }
    }
  }

  // Obstacles, column by column. A side face is seen by one run of rows (those where the ray is within the span's
  // height range where it enters the span's footprint), at the same distance s_in on every row; spans come near to
  // far, so a row sees the side of the first span whose run holds it. Top and bottom faces ("caps") are found row by
  // row into a per-row depth buffer. A row sees the nearer of the two (on a tie, the earlier span), as if every span
  // had been drawn into one depth buffer in turn.
  if (s.hit.size() != static_cast<size_t>(height)) s.best.assign(height, kInf), s.hit.assign(height, kNoHit);
  double* const best = s.best.data();  // caps only: kInf and kNoHit where none was seen; reset after each column
  int32_t* const hit = s.hit.data();
  std::vector<SideRun>& sides = s.sides;
  std::vector<std::pair<int, int>>& covered = s.covered;
  const Eigen::Vector2d origin2(ox, oy);
  const size_t step = bgr.step[0];
  for (int c = 0; c < width; ++c) {
    const LevelColumn& col = cols[c];
    const double dz0 = col.dz0, H = col.H, inv_H = col.inv_H;
    const double ux = col.hx * inv_H, uy = col.hy * inv_H;
    const int r_floor = col.r_floor;
    // Per row r the ray rises m(r) = (dz0 + r ez) / H per metre of s (decreasing with r). The floor is not a
    // distance here: a span is behind it when the ray is below z = 0 where it enters the span. The range limit is
    // applied when colouring (the nearest surface found beyond max_range is not drawn).
    auto slope = [&](int r) { return (dz0 + r * ez) * inv_H; };
    auto row_of = [&](double m) { return (m * H - dz0) / ez; };  // where slope(r) = m, as a real number
    sides.clear();
    int caps_lo = height, caps_hi = 0;  // rows [caps_lo, caps_hi) may have a cap in best/hit
    // The first side run that holds row r (nullptr if none).
    auto side_at = [&](int r) -> const SideRun* {
      for (const SideRun& run : sides) {
        if (r >= run.ra && r < run.rb) return &run;
      }
      return nullptr;
    };

    // Span i on rows [r0, r1), row by row (only caps, or nothing, can be seen there; the side test is kept for
    // exactness).
    auto rows = [&](const Span& sp, int32_t i, int r0, int r1) {
      const double s_in = std::max(sp.s_in, 0.0);
      for (int r = r0; r < r1; ++r) {
        const SideRun* run = side_at(r);
        const double b = run != nullptr ? std::min(best[r], run->s) : best[r];
        if (sp.s_in >= b) continue;
        const double m = slope(r), z_in = oz + m * s_in;
        if (z_in <= floor_z) continue;  // the floor is nearer
        int32_t h = kNoHit;
        double d = 0;
        if (z_in >= sp.z_min && z_in <= sp.z_max) {
          if (sp.s_in <= 0) continue;
          d = s_in, h = i;
        } else if (z_in > sp.z_max && m < 0) {
          const double st = (sp.z_max - oz) / m;
          if (st <= sp.s_out && st < b) d = st, h = i | kCapFlag;
        } else if (z_in < sp.z_min && m > 0) {
          const double sb = (sp.z_min - oz) / m;
          if (sb <= sp.s_out && sb < b) d = sb, h = i | kCapFlag;
        }
        if (h != kNoHit) {
          best[r] = d, hit[r] = h;
          caps_lo = std::min(caps_lo, r), caps_hi = std::max(caps_hi, r + 1);
        }
      }
    };
    // Span i: only the rows whose ray passes through its height range.
    auto fill = [&](const Span& sp, int32_t i) {
      const double s_in = std::max(sp.s_in, 0.0);
      double lo, hi;  // slopes m of the rays that meet the span's vertical extent within [s_in, s_out]
      if (s_in <= 0) {
        if (oz >= sp.z_min && oz <= sp.z_max) return;  // the camera is inside: invisible
        lo = oz > sp.z_max ? -kInf : (sp.z_min - oz) / sp.s_out;
        hi = oz > sp.z_max ? (sp.z_max - oz) / sp.s_out : kInf;
      } else {
        hi = (sp.z_max - oz) / (sp.z_max < oz ? sp.s_out : s_in);
        lo = (sp.z_min - oz) / (sp.z_min > oz ? sp.s_out : s_in);
      }
      // One row of margin on each side; the tests per row are exact.
      const double r_first = std::ceil(row_of(hi)) - 1, r_last = std::floor(row_of(lo)) + 1;
      const int r0 = static_cast<int>(std::clamp(r_first, 0.0, static_cast<double>(height)));
      const int r1 = static_cast<int>(std::clamp(r_last + 1, 0.0, static_cast<double>(height)));
      if (r0 >= r1) return;
      if (sp.s_in <= 0) return rows(sp, i, r0, r1);
      // The side face is seen by the rows where the ray is within [z_min, z_max] (and above the floor) at s_in:
      // one run [ra, rb), as the height at s_in decreases with the row. Above it only the top face can be seen,
      // by rays going down; below it only the bottom face, by rays going up.
      auto z_at = [&](int r) { return oz + slope(r) * s_in; };
      const int ra = first_row(r0, r1, std::ceil(row_of((sp.z_max - oz) / s_in)),
                               [&](int r) { return z_at(r) <= sp.z_max; });
      const int rb = first_row(ra, r1, std::ceil(row_of((std::max(sp.z_min, floor_z) - oz) / s_in)), [&](int r) {
        const double z = z_at(r);
        return !(z >= sp.z_min && z > floor_z);
      });
      rows(sp, i, std::max(r0, r_floor), ra);
      rows(sp, i, rb, std::min(r1, r_floor));
      if (ra < rb) sides.push_back({ra, rb, i, s_in});
    };

    // Rows [top, bot] may still change; the others cannot, whatever spans come later (s_in > s_done): they see a
    // side face, or a cap nearer than s_done, or their ray is above every obstacle's top, or below every bottom or
    // the floor, from s_done on. The walk stops when no row is left.
    int top = 0, bot = height - 1;
    double s_check = -kInf;  // nothing can become final before the walk reaches this, unless new spans come
    auto high = [&](int r, double s_done) {
      const double m = slope(r);
      return m >= 0 && oz + m * s_done > z_hi;
    };
    auto low = [&](int r, double s_done) {
      const double m = slope(r), z = oz + m * s_done;
      return m <= 0 && (z <= floor_z || z < z_lo);
    };
    const double z_low = std::max(floor_z, z_lo);
    caster.spans_until(origin2, Eigen::Vector2d(ux, uy), max_range, s.tmp, s.pending,
                       [&](const std::vector<Span>& spans, size_t first, double s_done) {
                         for (size_t i = first; i < spans.size(); ++i) fill(spans[i], static_cast<int32_t>(i));
                         if (first == spans.size() && s_done < s_check) return true;
                         while (top <= bot) {
                           if (const SideRun* run = side_at(top)) {
                             top = run->rb;
                           } else if (best[top] <= s_done) {
                             ++top;
                           } else if (high(top, s_done)) {
                             top = first_row(top, bot + 1, std::ceil(row_of((z_hi - oz) / s_done)),
                                             [&](int r) { return !high(r, s_done); });
                           } else {
                             if (low(top, s_done)) top = bot + 1;
                             break;
                           }
                         }
                         while (top <= bot) {
                           if (const SideRun* run = side_at(bot)) {
                             bot = run->ra - 1;
                           } else if (best[bot] <= s_done) {
                             --bot;
                           } else if (low(bot, s_done)) {
                             bot = first_row(top, bot, std::ceil(row_of((z_low - oz) / s_done)),
                                             [&](int r) { return low(r, s_done); }) - 1;
                           } else {
                             if (high(bot, s_done)) bot = top - 1;
                             break;
                           }
                         }
                         if (top > bot) return false;
                         auto when = [&](int r) {  // when row r can become final without new spans
                           const double m = slope(r);
                           return std::min(best[r], m > 0 ? (z_hi - oz) / m : m < 0 ? (z_low - oz) / m : kInf);
                         };
                         // The walk cannot be over before both rows are final.
                         s_check = std::max(when(top), when(bot));
                         return true;
                       });

    // The obstacles' colours; t = s * sqrt(1 + m^2) is the 3D distance. Sky and floor are drawn already.
    const Span* const spans = s.tmp.data();
    uint8_t* const column = bgr.data + 3 * c;
    // The gain of row r seeing span sp at distance d (its cap when cap), exactly; -1 beyond max_range.
    auto gain = [&](const Span& sp, bool cap, double d, int r) -> float {
      const float m = static_cast<float>(slope(r)), q = std::sqrt(1 + m * m);
      const float t = static_cast<float>(d) * q;
      if (!(t < range_f)) return -1;
      const float cosine =
          cap ? std::abs(m) : std::abs(static_cast<float>(sp.normal.x() * ux + sp.normal.y() * uy));
      return (0.35f + 0.65f * cosine / q) * (1 - k_dim * t);
    };
    auto draw_exact = [&](const Span& sp, bool cap, double d, int r) {
      const float g = gain(sp, cap, d, r);
      uint8_t* px = column + r * step;
      if (g >= 0) {
        put_packed(px, pack(sp.color), static_cast<uint32_t>(static_cast<int32_t>(g * 8192.0f)));
      } else {
        const uint8_t* src = (slope(r) < 0 && floor_visible) ? beyond : sky;
        px[0] = src[0], px[1] = src[1], px[2] = src[2];
      }
    };
    // Side faces: the visible part of each run, [ra, rb) less the runs before it.
    covered.clear();
    for (const SideRun& run : sides) {
      const Span& sp = spans[run.span];
      const uint64_t color = pack(sp.color);
      int r = run.ra;
      for (size_t k = 0; k <= covered.size() && r < run.rb; ++k) {
        // covered is sorted and disjoint: the piece [r, next covered begin) is visible
        const int piece_end = std::min(run.rb, k < covered.size() ? covered[k].first : height);
        if (k < covered.size() && covered[k].second <= r) continue;
        if (piece_end > r) {
          const int end = piece_end;
          float g0;
          if (end - r > 2 && (g0 = gain(sp, false, run.s, r)) >= 0 && gain(sp, false, run.s, end - 1) >= 0) {
            // The gain is a smooth function of the row (and t, convex in m, is below max_range inside the run when
            // it is at both ends). Exact every 16 rows, linear in between: the difference is far below one grey
            // level. Gain in 19-bit fixed point.
            uint8_t* px = column + r * step;
            while (r < end) {
              const int n = std::min(16, end - 1 - r);
              const float g1 = n > 0 ? gain(sp, false, run.s, r + n) : g0;
              int32_t g = static_cast<int32_t>(g0 * 524288.0f);
              const int32_t dg = n > 0 ? static_cast<int32_t>((g1 - g0) * (524288.0f / static_cast<float>(n))) : 0;
              const int stop = n > 0 ? r + n : r + 1;
              for (; r < stop; ++r, g += dg, px += step) put_packed(px, color, static_cast<uint32_t>(g) >> 6);
              g0 = g1;
            }
          } else {
            for (; r < end; ++r) draw_exact(sp, false, run.s, r);
          }
        }
        if (k < covered.size()) r = std::max(r, covered[k].second);
      }
      // Add [ra, rb) to covered, keeping it sorted and disjoint.
      auto it = std::lower_bound(covered.begin(), covered.end(), run.ra,
                                 [](const std::pair<int, int>& iv, int v) { return iv.second < v; });
      int lo = run.ra, hi = run.rb;
      auto jt = it;
      while (jt != covered.end() && jt->first <= hi) lo = std::min(lo, jt->first), hi = std::max(hi, jt->second), ++jt;
      it = covered.erase(it, jt);
      covered.insert(it, {lo, hi});
    }
    // Caps, where nearer than the side (on a tie, the earlier span wins).
    for (int r = caps_lo; r < caps_hi; ++r) {
      const int32_t h = hit[r];
      if (h < 0) continue;
      const SideRun* run = side_at(r);
      const int32_t i = h & ~kCapFlag;
      if (run == nullptr || best[r] < run->s || (best[r] == run->s && i < run->span)) {
        draw_exact(spans[i], (h & kCapFlag) != 0, best[r], r);
      }
      best[r] = kInf, hit[r] = kNoHit;
    }
  }
  return true;
}

}  // namespace

void render_camera(const RayCaster& caster, const CameraModel& model, const Eigen::Isometry3d& camera_in_world,
                   cv::Mat& bgr) {
  if (!render_level(caster, model, camera_in_world, bgr)) detail::render_camera_generic(caster, model, camera_in_world, bgr);
}

}  // namespace driftlab::sim
