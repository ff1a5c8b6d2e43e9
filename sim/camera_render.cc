// The renderer exploits that every obstacle is a vertical prism (a footprint extruded between two heights): along
// a vertical half-plane from the camera, a horizontal 2D ray crosses the same footprints at the same distances
// whatever the elevation. So the view is cut into thin azimuth slices (a quarter pixel wide or less); each slice's
// footprint crossings (RayCaster::spans) are computed once per frame, and each pixel only compares its own height
// along the slice with the crossings' height ranges: a side, top or bottom face, or the floor. A level camera uses
// one slice per column; a tilted camera uses whichever slices its pixels fall in, so any orientation works.
// A (nearly) level camera takes a faster path (render_level below): each column is a vertical half-plane, its spans
// are computed along the column's exact azimuth, and each span fills the run of rows that can see it.
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

/// Per-thread memory reused from frame to frame.
struct Scratch {
  uint64_t frame = 0;
  std::vector<SliceRef> slices;
  std::vector<Span> pool, tmp;
  // Level fast path: one column's rows.
  std::vector<double> best;
  std::vector<int32_t> hit;  // index into tmp; kFloorHit, kNoHit
  cv::Mat transposed;        // the image with rows and columns swapped: a column is contiguous
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

/// put() for 0 <= gain <= 1.
inline void put_unit(uint8_t* px, const std::array<uint8_t, 3>& rgb, float gain) {
  put_fixed(px, rgb, static_cast<uint32_t>(static_cast<int32_t>(gain * 65536.0f)));
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

constexpr int32_t kNoHit = -1, kFloorHit = -2;
constexpr int32_t kCapFlag = 1 << 30;  // set on `hit` when the top or bottom face was hit (not the side)

/// The level fast path: with the camera's up axis (nearly) vertical, every image column is a vertical half-plane,
/// so its footprint crossings are computed once, exactly along the column's own azimuth, and each span paints the
/// contiguous range of rows that can see it (a per-row depth buffer, spans near to far). Per pixel this makes the
/// same comparisons as the generic path. Returns false (nothing drawn) when the camera is not level enough: the
/// column's azimuth may then drift by at most an eighth of a pixel from top to bottom (the generic path's error).
bool render_level(const RayCaster& caster, const CameraModel& model, const Eigen::Isometry3d& camera_in_world,
                  cv::Mat& bgr) {
  const int width = std::max(1, model.width), height = std::max(1, model.height);
  const double f = 0.5 * width / std::tan(0.5 * model.hfov);
  const Eigen::Matrix3d R = camera_in_world.linear();
  const double tilt = std::hypot(R(0, 2), R(1, 2));
  const double u_max = 0.5 * width / f;
  if (!(R(2, 2) > 0.5) || !std::isfinite(f) || !(f > 0) || tilt * 0.5 * height * (1 + u_max * u_max) > 0.125) {
    return false;
  }
  bgr.create(height, width, CV_8UC3);
  const double max_range = model.max_range;
  const Eigen::Vector3d o = camera_in_world.translation();
  const double ox = o.x(), oy = o.y(), oz = o.z();
  const Eigen::Vector3d b = -R.col(1) / f, e = -R.col(2) / f;
  const Eigen::Vector3d a = R.col(0) + (0.5 - 0.5 * width) * b + (0.5 - 0.5 * height) * e;
  const double ez = e.z();  // < 0: rows go down
  const double r_ref = 0.5 * (height - 1);  // the azimuth of a column is taken at the image's middle row

  Scratch& s = scratch;
  s.best.resize(height), s.hit.resize(height);
  double* const best = s.best.data();
  int32_t* const hit = s.hit.data();
  const bool floor_visible = oz > 0;
  const double floor_z = floor_visible ? 0.0 : -std::numeric_limits<double>::infinity();
  const float range_f = static_cast<float>(max_range), k_dim = static_cast<float>(0.6 / max_range);
  uint8_t sky[3], beyond[3];
  put(sky, kSkyColor, 1.0);
  put(beyond, {148, 148, 140}, dim(max_range, max_range));
  s.transposed.create(width, height, CV_8UC3);

  for (int c = 0; c < width; ++c) {
    const Eigen::Vector3d d0 = a + c * b;  // row 0 of this column
    const double hx = d0.x() + r_ref * e.x(), hy = d0.y() + r_ref * e.y();
    const double H = std::sqrt(hx * hx + hy * hy), inv_H = 1.0 / H;
    const double ux = hx * inv_H, uy = hy * inv_H;
    const double dz0 = d0.z();
    caster.spans(Eigen::Vector2d(ox, oy), Eigen::Vector2d(ux, uy), max_range, s.tmp);

    // Per row r the ray rises m(r) = (dz0 + r ez) / H per metre of s (decreasing with r). The floor is not a
    // distance here: a span is behind it when the ray is below z = 0 where it enters the span. The range limit is
    // applied when colouring (the nearest surface found beyond max_range is not drawn).
    auto slope = [&](int r) { return (dz0 + r * ez) * inv_H; };
    int r_floor = 0;  // first row whose ray goes down (and so meets the floor, when oz > 0)
    if (dz0 >= 0) r_floor = std::clamp(static_cast<int>(dz0 / -ez), 0, height);
    while (r_floor > 0 && slope(r_floor - 1) < 0) --r_floor;
    while (r_floor < height && slope(r_floor) >= 0) ++r_floor;
    std::fill(hit, hit + r_floor, kNoHit);
    std::fill(hit + r_floor, hit + height, floor_visible ? kFloorHit : kNoHit);

    // Spans near to far; each one only visits the rows whose ray passes through its height range.
    const Span* const spans = s.tmp.data();
    const int num_spans = static_cast<int>(s.tmp.size());
    for (int i = 0; i < num_spans; ++i) {
      const Span& sp = spans[i];
      const double s_in = std::max(sp.s_in, 0.0);
      double lo, hi;  // slopes m of the rays that meet the span's vertical extent within [s_in, s_out]
      if (s_in <= 0) {
        if (oz >= sp.z_min && oz <= sp.z_max) continue;  // the camera is inside: invisible
        lo = oz > sp.z_max ? -std::numeric_limits<double>::infinity() : (sp.z_min - oz) / sp.s_out;
        hi = oz > sp.z_max ? (sp.z_max - oz) / sp.s_out : std::numeric_limits<double>::infinity();
      } else {
        hi = (sp.z_max - oz) / (sp.z_max < oz ? sp.s_out : s_in);
        lo = (sp.z_min - oz) / (sp.z_min > oz ? sp.s_out : s_in);
      }
      // One row of margin on each side; the test below is exact.
      const double r_first = std::ceil((hi * H - dz0) / ez) - 1, r_last = std::floor((lo * H - dz0) / ez) + 1;
      const int r0 = static_cast<int>(std::clamp(r_first, 0.0, static_cast<double>(height)));
      const int r1 = static_cast<int>(std::clamp(r_last + 1, 0.0, static_cast<double>(height)));
      for (int r = r0; r < r1; ++r) {
        if (hit[r] >= 0 && sp.s_in >= best[r]) continue;  // best[r] is set with hit[r]
        const double m = slope(r), z_in = oz + m * s_in;
        if (z_in <= floor_z) continue;  // the floor is nearer
        if (z_in >= sp.z_min && z_in <= sp.z_max) {
          if (sp.s_in <= 0) continue;
          best[r] = s_in, hit[r] = i;
        } else if (z_in > sp.z_max && m < 0) {
          const double st = (sp.z_max - oz) / m;
          if (st <= sp.s_out && (hit[r] < 0 || st < best[r])) best[r] = st, hit[r] = i | kCapFlag;
        } else if (z_in < sp.z_min && m > 0) {
          const double sb = (sp.z_min - oz) / m;
          if (sb <= sp.s_out && (hit[r] < 0 || sb < best[r])) best[r] = sb, hit[r] = i | kCapFlag;
        }
      }
    }

    // Colours, run by run of rows that see the same thing; t = s * sqrt(1 + m^2) is the 3D distance.
    uint8_t* const col = s.transposed.ptr<uint8_t>(c);
    for (int r = 0; r < height;) {
      const int32_t h = hit[r];
      int end = r + 1;
      while (end < height && hit[end] == h) ++end;
      if (h == kFloorHit) {
        for (; r < end; ++r) {
          const double m = slope(r), sf = oz / -m;
          const float mf = static_cast<float>(m), t = static_cast<float>(sf) * std::sqrt(1 + mf * mf);
          uint8_t* px = col + 3 * r;
          if (t < range_f) {
            put_unit(px, light_square(ox + sf * ux, oy + sf * uy) ? kFloorLight : kFloorDark, 1 - k_dim * t);
          } else {
            px[0] = beyond[0], px[1] = beyond[1], px[2] = beyond[2];
          }
        }
      } else if (h >= 0) {
        const Span& sp = spans[h & ~kCapFlag];
        const float nu = std::abs(static_cast<float>(sp.normal.x() * ux + sp.normal.y() * uy));
        // The gain of a row, exactly; -1 beyond max_range.
        auto gain = [&](int row) -> float {
          const float m = static_cast<float>(slope(row)), q = std::sqrt(1 + m * m);
          const float t = static_cast<float>(best[row]) * q;
          if (!(t < range_f)) return -1;
          return (0.35f + 0.65f * ((h & kCapFlag) ? std::abs(m) : nu) / q) * (1 - k_dim * t);
        };
        if ((h & kCapFlag) == 0 && end - r > 2 && gain(r) >= 0 && gain(end - 1) >= 0) {
          // A side face: the same s on every row, the gain a smooth function of the row (and t, convex in m,
          // is below max_range inside the run when it is at both ends). Exact every 8 rows, linear in between:
          // the difference is far below one grey level.
          for (; r < end;) {
            const int n = std::min(8, end - 1 - r);
            const float g0 = gain(r), g1 = n > 0 ? gain(r + n) : g0;
            int32_t g = static_cast<int32_t>(g0 * 65536.0f);
            const int32_t dg = n > 0 ? static_cast<int32_t>((g1 - g0) * 65536.0f) / n : 0;
            const int stop = n > 0 ? r + n : r + 1;
            for (; r < stop; ++r, g += dg) put_fixed(col + 3 * r, sp.color, static_cast<uint32_t>(g));
          }
        } else {
          for (; r < end; ++r) {
            const float g = gain(r);
            uint8_t* px = col + 3 * r;
            if (g >= 0) {
              put_unit(px, sp.color, g);
            } else {
              const uint8_t* src = (slope(r) < 0 && floor_visible) ? beyond : sky;
              px[0] = src[0], px[1] = src[1], px[2] = src[2];
            }
          }
        }
      } else {
        for (; r < end; ++r) {
          const uint8_t* src = (r >= r_floor && floor_visible) ? beyond : sky;
          uint8_t* px = col + 3 * r;
          px[0] = src[0], px[1] = src[1], px[2] = src[2];
        }
      }
    }
  }
  cv::transpose(s.transposed, bgr);
  return true;
}

}  // namespace

void render_camera(const RayCaster& caster, const CameraModel& model, const Eigen::Isometry3d& camera_in_world,
                   cv::Mat& bgr) {
  if (!render_level(caster, model, camera_in_world, bgr)) detail::render_camera_generic(caster, model, camera_in_world, bgr);
}

}  // namespace driftlab::sim
