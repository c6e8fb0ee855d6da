// SPDX-License-Identifier: MIT
// Camera bodies' sensor sizes, from lensfun's database (Debian's
// liblensfun-data-v1): for photos whose EXIF gives the lens's focal length but
// no 35 mm equivalent (Canon bodies write none), the crop factor turns one
// into the other.
#pragma once

#include <optional>
#include <string>

namespace horizonreg {

// The crop factor (full-frame diagonal over the sensor's) of the body named by
// EXIF Make and Model, as lensfun knows it; nullopt when the body is unknown,
// the names are empty or the database is not installed. The database is read
// once per process, at the first call (the maker's own files first, a few
// milliseconds; the whole database, about 40 ms, only for a maker whose files
// are not named after it). Thread-safe; never throws; lensfun's messages never
// reach the user.
std::optional<double> CameraCropFactor(const std::string& make, const std::string& model);

}  // namespace horizonreg
