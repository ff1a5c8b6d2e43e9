// core/geo.h: the local tangent frame round-trips within a millimetre over kilometres and gets distances on the
// sphere right; the standard atmosphere's pressure and altitude invert each other and match its table values.
#include "core/geo.h"

#include <gtest/gtest.h>

#include <cmath>

namespace driftlab::geo {
namespace {

TEST(LocalFrame, RoundTripsAndMeasuresDistancesOnTheSphere) {
  const LocalFrame f({47.397742, 8.545594, 488.0});  // PX4 SITL's default home (Zurich)
  for (const Enu e : {Enu{0, 0, 0}, Enu{5, -3, 2}, Enu{1500, 2500, -10}, Enu{-4000, 300, 100}}) {
    const Enu back = f.to_local(f.to_global(e));
    EXPECT_NEAR(back.east, e.east, 1e-3);
    EXPECT_NEAR(back.north, e.north, 1e-3);
    EXPECT_NEAR(back.up, e.up, 1e-9);
  }
  // One arc-minute of latitude north of the origin is 6371 km * pi / 10800 north, nothing east.
  const Enu n = f.to_local({47.397742 + 1.0 / 60, 8.545594, 488.0});
  EXPECT_NEAR(n.north, kEarthRadius_m * M_PI / 10800, 1e-6);
  EXPECT_NEAR(n.east, 0, 1e-6);
  // East of the origin the metres per degree of longitude shrink by cos(latitude).
  const Enu e = f.to_local({47.397742, 8.545594 + 0.01, 488.0});
  EXPECT_NEAR(e.east, kEarthRadius_m * 0.01 * M_PI / 180 * std::cos(47.397742 * M_PI / 180), 0.01);
}

TEST(StandardAtmosphere, PressureAndAltitudeInvertEachOther) {
  EXPECT_NEAR(pressure_at(0), 101325, 1e-9);
  EXPECT_NEAR(pressure_at(1000), 89875, 5);   // the ICAO table: 898.75 hPa at 1000 m
  EXPECT_NEAR(pressure_at(5000), 54020, 10);  // 540.2 hPa at 5000 m
  for (double h : {-100.0, 0.0, 488.0, 2000.0}) EXPECT_NEAR(altitude_of(pressure_at(h)), h, 1e-6);
}

}  // namespace
}  // namespace driftlab::geo
