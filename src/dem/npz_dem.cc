// SPDX-License-Identifier: MIT
#include "dem/npz_dem.h"

#include <cpl_vsi.h>

#include <cctype>
#include <cstdint>
#include <cstring>

#include "util/errors.h"

namespace horizonreg {
namespace {

struct NpyArray {
  std::string dtype;
  std::vector<int> shape;
  std::vector<double> values;
};

std::string ReadMember(const std::string& path, const std::string& member) {
  // Braces delimit the archive path, since GDAL only guesses .zip by its extension.
  const std::string vsi = "/vsizip/{" + path + "}/" + member;
  VSILFILE* f = VSIFOpenL(vsi.c_str(), "rb");
  if (f == nullptr) throw IoError("dem: '" + path + "' has no member '" + member + "' (not a DEM .npz)");
  std::string data;
  char chunk[65536];
  size_t n;
  while ((n = VSIFReadL(chunk, 1, sizeof(chunk), f)) > 0) data.append(chunk, n);
  VSIFCloseL(f);
  return data;
}

template <typename T>
void Convert(const std::string& raw, size_t offset, size_t count, std::vector<double>& out) {
  out.resize(count);
  for (size_t i = 0; i < count; ++i) {
    T v;
    std::memcpy(&v, raw.data() + offset + i * sizeof(T), sizeof(T));
    out[i] = static_cast<double>(v);
  }
}

NpyArray ParseNpy(const std::string& path, const std::string& member, const std::string& raw) {
  auto bad = [&](const std::string& why) { return IoError("dem: '" + path + "' member '" + member + "': " + why); };
  if (raw.size() < 10 || raw.compare(0, 6, "\x93NUMPY") != 0) throw bad("not a NumPy array");
  const int major = static_cast<unsigned char>(raw[6]);
  size_t header_len, offset;
  if (major == 1) {
    header_len = static_cast<unsigned char>(raw[8]) | (static_cast<unsigned char>(raw[9]) << 8);
    offset = 10;
  } else {
    if (raw.size() < 12) throw bad("truncated header");
    header_len = 0;
    for (int i = 0; i < 4; ++i) header_len |= static_cast<size_t>(static_cast<unsigned char>(raw[8 + i])) << (8 * i);
    offset = 12;
  }
  if (raw.size() < offset + header_len) throw bad("truncated header");
  const std::string header = raw.substr(offset, header_len);
  offset += header_len;
  // The header is a Python dict literal: {'descr': '<i2', 'fortran_order': False, 'shape': (344, 403), }
  auto value_after = [&](const std::string& key) -> std::string {
    const size_t k = header.find("'" + key + "'");
    if (k == std::string::npos) throw bad("no '" + key + "' in the header");
    const size_t colon = header.find(':', k);
    if (colon == std::string::npos) throw bad("bad header");
    return header.substr(colon + 1);
  };
  NpyArray a;
  const std::string descr = value_after("descr");
  const size_t q0 = descr.find('\''), q1 = descr.find('\'', q0 + 1);
  if (q0 == std::string::npos || q1 == std::string::npos) throw bad("no dtype");
  a.dtype = descr.substr(q0 + 1, q1 - q0 - 1);
  if (value_after("fortran_order").find("True") < value_after("fortran_order").find(','))
    throw bad("Fortran order not supported");
  const std::string shape = value_after("shape");
  const size_t p0 = shape.find('('), p1 = shape.find(')');
  if (p0 == std::string::npos || p1 == std::string::npos) throw bad("no shape");
  size_t count = 1;
  for (size_t i = p0 + 1; i < p1;) {
    if (std::isdigit(static_cast<unsigned char>(shape[i]))) {
      size_t used = 0;
      a.shape.push_back(std::stoi(shape.substr(i), &used));
      count *= static_cast<size_t>(a.shape.back());
      i += used;
    } else {
      ++i;
    }
  }
  size_t item;
  if (a.dtype == "<i2")
    item = 2;
  else if (a.dtype == "<i4" || a.dtype == "<f4")
    item = 4;
  else if (a.dtype == "<f8" || a.dtype == "<i8")
    item = 8;
  else
    throw bad("unsupported dtype " + a.dtype);
  if (raw.size() < offset + count * item) throw bad("truncated data");
  if (a.dtype == "<i2")
    Convert<int16_t>(raw, offset, count, a.values);
  else if (a.dtype == "<i4")
    Convert<int32_t>(raw, offset, count, a.values);
  else if (a.dtype == "<f4")
    Convert<float>(raw, offset, count, a.values);
  else if (a.dtype == "<i8")
    Convert<int64_t>(raw, offset, count, a.values);
  else
    Convert<double>(raw, offset, count, a.values);
  return a;
}

double Scalar(const std::string& path, const std::string& name) {
  NpyArray a = ParseNpy(path, name + ".npy", ReadMember(path, name + ".npy"));
  if (a.values.size() != 1) throw IoError("dem: '" + path + "' member '" + name + "' is not a scalar");
  return a.values[0];
}

}  // namespace

NpzDem ReadNpzDem(const std::string& path) {
  NpyArray elev = ParseNpy(path, "elevation.npy", ReadMember(path, "elevation.npy"));
  if (elev.shape.size() != 2 || elev.shape[0] < 2 || elev.shape[1] < 2)
    throw IoError("dem: '" + path + "' elevation is not a 2-D array of at least 2x2");
  NpzDem d;
  d.height = elev.shape[0];
  d.width = elev.shape[1];
  d.elevation_m = std::move(elev.values);
  d.west_deg = Scalar(path, "xmin");
  d.east_deg = Scalar(path, "xmax");
  d.north_deg = Scalar(path, "ymin");  // matplotlib's layout: ymin is the northern edge
  d.south_deg = Scalar(path, "ymax");
  if (!(d.east_deg > d.west_deg) || !(d.north_deg > d.south_deg))
    throw IoError("dem: '" + path + "' has an inconsistent extent");
  return d;
}

}  // namespace horizonreg
