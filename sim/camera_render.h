// An RGB camera's view of a World, rendered from the RayCaster's geometry.
// Thread-safety: render_camera is reentrant (its scratch memory is per thread).
#pragma once

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "sim/raycaster.h"

namespace driftlab::sim {

/// A pinhole camera without distortion. Pixel (col, row) looks along (1, -u, -v) in the camera's forward frame with
/// u = (col + 0.5 - width/2) / f, v = (row + 0.5 - height/2) / f, f = (width/2) / tan(hfov/2) [pixels].
struct CameraModel {
  int width = 320;
  int height = 240;
  double hfov = 1.2;       ///< horizontal field of view [rad]
  double max_range = 20;   ///< farther surfaces are not drawn (sky/background colour) [m]
};

/// Sky (and ceiling) colour, RGB.
inline constexpr std::array<uint8_t, 3> kSkyColor{135, 206, 235};

/// camera_in_world: pose of the camera's optical-forward frame in the world, x forward, y left, z up (not the optical
/// convention). Renders into `bgr` (CV_8UC3, resized as needed). Obstacles in their colours, shaded by the angle to
/// their surface normal and dimmed with distance; the floor as a checkerboard (1 m squares) and a uniform sky/ceiling
/// colour above. Geometry is exact up to a quarter of a pixel in azimuth (the view is cut into thin vertical slices
/// that share their footprint crossings); any camera orientation works, a level camera is the fast case.
void render_camera(const RayCaster& caster, const CameraModel& model, const Eigen::Isometry3d& camera_in_world,
                   cv::Mat& bgr);

namespace detail {
/// render_camera without its level-camera fast path (any orientation; for tests and benchmarks).
void render_camera_generic(const RayCaster& caster, const CameraModel& model, const Eigen::Isometry3d& camera_in_world,
                           cv::Mat& bgr);
}  // namespace detail

}  // namespace driftlab::sim
