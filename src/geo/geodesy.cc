// SPDX-License-Identifier: MIT
#include "geo/geodesy.h"

#include <GeographicLib/Geocentric.hpp>
#include <sstream>

#include "util/errors.h"

namespace horizonreg {

GeodeticPoint GeodeticFromEcef(const Eigen::Vector3d& ecef_m) {
  const GeographicLib::Geocentric earth(kWgs84A, kWgs84F);
  GeodeticPoint p;
  earth.Reverse(ecef_m.x(), ecef_m.y(), ecef_m.z(), p.lat_deg, p.lon_deg, p.height_m);
  return p;
}

LocalFrame::LocalFrame(const GeodeticPoint& origin) : origin_(origin) {
  if (!std::isfinite(origin.lat_deg) || origin.lat_deg < -90.0 || origin.lat_deg > 90.0) {
    std::ostringstream msg;
    msg << "latitude " << origin.lat_deg << " is outside [-90, 90]";
    throw InvalidArgument(msg.str());
  }
  if (!std::isfinite(origin.lon_deg) || std::abs(origin.lon_deg) > 540.0) {
    std::ostringstream msg;
    msg << "longitude " << origin.lon_deg << " is outside [-540, 540]";
    throw InvalidArgument(msg.str());
  }
  if (!std::isfinite(origin.height_m)) throw InvalidArgument("observer height is not finite");
  origin_ecef_ = EcefFromGeodetic(origin);
  const double lat = DegToRad(origin.lat_deg), lon = DegToRad(origin.lon_deg);
  const double sp = std::sin(lat), cp = std::cos(lat), sl = std::sin(lon), cl = std::cos(lon);
  enu_from_ecef_ << -sl, cl, 0.0,  //
      -sp * cl, -sp * sl, cp,      //
      cp * cl, cp * sl, sp;
}

}  // namespace horizonreg
