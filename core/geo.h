// Geodetic helpers shared by the simulator's GNSS and barometer and the drone's estimator, so that what one encodes
// the other decodes with the same formulas: a local east-north-up tangent frame at a reference point (the
// azimuthal equidistant projection PX4's map_projection uses, on a sphere of radius 6371 km: exact along great
// circles through the reference, within millimetres over the few kilometres a flight covers), and the standard
// atmosphere's pressure at an altitude (the formula PX4 and ArduPilot use). Thread-safety: pure functions.
#pragma once

#include <algorithm>
#include <cmath>

namespace driftlab::geo {

inline constexpr double kEarthRadius_m = 6371000.0;
inline constexpr double kSeaLevelPressure_pa = 101325.0;

struct LatLonAlt {
  double latitude_deg = 0, longitude_deg = 0, altitude_m = 0;  ///< WGS-84 [degrees], above mean sea level [m]
};

struct Enu {
  double east = 0, north = 0, up = 0;  ///< [m]
};

/// A local tangent frame: x east, y north, z up, its origin at `origin`.
class LocalFrame {
 public:
  explicit LocalFrame(const LatLonAlt& origin)
      : origin_(origin),
        lat0_(origin.latitude_deg * M_PI / 180),
        lon0_(origin.longitude_deg * M_PI / 180),
        sin_lat0_(std::sin(lat0_)),
        cos_lat0_(std::cos(lat0_)) {}

  const LatLonAlt& origin() const { return origin_; }

  Enu to_local(const LatLonAlt& p) const {
    const double lat = p.latitude_deg * M_PI / 180, lon = p.longitude_deg * M_PI / 180;
    const double sin_lat = std::sin(lat), cos_lat = std::cos(lat), cos_dlon = std::cos(lon - lon0_);
    const double arg = std::clamp(sin_lat0_ * sin_lat + cos_lat0_ * cos_lat * cos_dlon, -1.0, 1.0);
    const double c = std::acos(arg);
    const double k = std::abs(c) > 1e-12 ? c / std::sin(c) : 1.0;
    return {k * cos_lat * std::sin(lon - lon0_) * kEarthRadius_m,
            k * (cos_lat0_ * sin_lat - sin_lat0_ * cos_lat * cos_dlon) * kEarthRadius_m,
            p.altitude_m - origin_.altitude_m};
  }

  LatLonAlt to_global(const Enu& e) const {
    const double x = e.north / kEarthRadius_m, y = e.east / kEarthRadius_m;
    const double c = std::sqrt(x * x + y * y);
    LatLonAlt out{origin_.latitude_deg, origin_.longitude_deg, origin_.altitude_m + e.up};
    if (c > 1e-15) {
      const double sin_c = std::sin(c), cos_c = std::cos(c);
      const double lat = std::asin(cos_c * sin_lat0_ + x * sin_c * cos_lat0_ / c);
      const double lon = lon0_ + std::atan2(y * sin_c, c * cos_lat0_ * cos_c - x * sin_lat0_ * sin_c);
      out.latitude_deg = lat * 180 / M_PI;
      out.longitude_deg = lon * 180 / M_PI;
    }
    return out;
  }

 private:
  LatLonAlt origin_;
  double lat0_, lon0_, sin_lat0_, cos_lat0_;
};

/// Static pressure of the standard atmosphere (troposphere) at an altitude above mean sea level [Pa].
inline double pressure_at(double altitude_m) {
  return kSeaLevelPressure_pa * std::pow(1 - 2.25577e-5 * altitude_m, 5.25588);
}

/// The altitude above mean sea level of a static pressure, the inverse of pressure_at [m].
inline double altitude_of(double pressure_pa) {
  return (1 - std::pow(pressure_pa / kSeaLevelPressure_pa, 1 / 5.25588)) / 2.25577e-5;
}

}  // namespace driftlab::geo
