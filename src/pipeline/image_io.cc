// SPDX-License-Identifier: MIT
#include "pipeline/image_io.h"

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "dem/terrain.h"
#include "util/errors.h"

namespace horizonreg {

namespace {

using Size = std::optional<std::pair<int, int>>;

Size Positive(int64_t w, int64_t h) {
  if (w <= 0 || h <= 0 || w > 0x7fffffff || h > 0x7fffffff) return std::nullopt;
  return std::make_pair(static_cast<int>(w), static_cast<int>(h));
}

// Little- or big-endian unsigned integers of n bytes at i (the caller checks the bounds).
uint32_t Le(const std::vector<unsigned char>& b, size_t i, int n) {
  uint32_t v = 0;
  for (int k = n - 1; k >= 0; --k) v = (v << 8) | b[i + k];
  return v;
}
uint32_t Be(const std::vector<unsigned char>& b, size_t i, int n) {
  uint32_t v = 0;
  for (int k = 0; k < n; ++k) v = (v << 8) | b[i + k];
  return v;
}

// BMP: BITMAPINFOHEADER and later (signed 32-bit, negative height = top-down)
// or the OS/2 BITMAPCOREHEADER (16-bit).
Size BmpSize(const std::vector<unsigned char>& b) {
  if (b.size() < 26 || b[0] != 'B' || b[1] != 'M') return std::nullopt;
  if (Le(b, 14, 4) == 12) return Positive(Le(b, 18, 2), Le(b, 20, 2));
  const int64_t h = static_cast<int32_t>(Le(b, 22, 4));
  return Positive(static_cast<int32_t>(Le(b, 18, 4)), h < 0 ? -h : h);
}

// WebP: the lossy (VP8), lossless (VP8L) or extended (VP8X canvas) header.
Size WebpSize(const std::vector<unsigned char>& b) {
  if (b.size() < 30 || std::memcmp(&b[0], "RIFF", 4) != 0 || std::memcmp(&b[8], "WEBP", 4) != 0) return std::nullopt;
  if (std::memcmp(&b[12], "VP8 ", 4) == 0) return Positive(Le(b, 26, 2) & 0x3fff, Le(b, 28, 2) & 0x3fff);
  if (std::memcmp(&b[12], "VP8L", 4) == 0 && b[20] == 0x2f) {
    const uint32_t bits = Le(b, 21, 4);
    return Positive((bits & 0x3fff) + 1, ((bits >> 14) & 0x3fff) + 1);
  }
  if (std::memcmp(&b[12], "VP8X", 4) == 0) return Positive(Le(b, 24, 3) + 1, Le(b, 27, 3) + 1);
  return std::nullopt;
}

// TIFF (classic, either byte order): ImageWidth and ImageLength of the first
// IFD, the page OpenCV decodes.
Size TiffSize(const std::vector<unsigned char>& b) {
  if (b.size() < 8) return std::nullopt;
  const bool le = b[0] == 'I' && b[1] == 'I' && b[2] == 42 && b[3] == 0;
  if (!le && !(b[0] == 'M' && b[1] == 'M' && b[2] == 0 && b[3] == 42)) return std::nullopt;
  const auto u = [&](size_t i, int n) { return le ? Le(b, i, n) : Be(b, i, n); };
  const size_t ifd = u(4, 4);
  if (ifd > b.size() || b.size() - ifd < 2) return std::nullopt;
  const size_t n = u(ifd, 2);
  int64_t w = 0, h = 0;
  for (size_t e = ifd + 2, k = 0; k < n && e + 12 <= b.size(); ++k, e += 12) {
    const uint32_t tag = u(e, 2), type = u(e + 2, 2);
    if ((tag != 256 && tag != 257) || (type != 3 && type != 4)) continue;
    (tag == 256 ? w : h) = type == 3 ? u(e + 8, 2) : u(e + 8, 4);
  }
  return Positive(w, h);
}

}  // namespace

std::optional<std::pair<int, int>> DeclaredImageSize(const std::vector<unsigned char>& b) {
  if (const Size s = BmpSize(b)) return s;
  if (const Size s = WebpSize(b)) return s;
  if (const Size s = TiffSize(b)) return s;
  const auto be16 = [&](size_t i) { return (b[i] << 8) | b[i + 1]; };
  if (b.size() >= 24 && b[0] == 0x89 && b[1] == 'P' && b[2] == 'N' && b[3] == 'G' && b[12] == 'I' && b[13] == 'H' &&
      b[14] == 'D' && b[15] == 'R') {
    const auto be32 = [&](size_t i) { return (static_cast<uint32_t>(be16(i)) << 16) | static_cast<uint32_t>(be16(i + 2)); };
    const uint32_t w = be32(16), h = be32(20);
    if (w == 0 || h == 0 || w > 0x7fffffff || h > 0x7fffffff) return std::nullopt;
    return std::make_pair(static_cast<int>(w), static_cast<int>(h));
  }
  if (b.size() < 4 || b[0] != 0xFF || b[1] != 0xD8) return std::nullopt;
  size_t i = 2;
  while (i + 9 < b.size()) {
    if (b[i] != 0xFF) return std::nullopt;
    const int marker = b[i + 1];
    if (marker == 0xFF) {  // fill byte
      ++i;
      continue;
    }
    if (marker == 0xD8 || (marker >= 0xD0 && marker <= 0xD7) || marker == 0x01) {  // no length
      i += 2;
      continue;
    }
    const size_t length = be16(i + 2);
    const bool sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (sof) return std::make_pair(be16(i + 7), be16(i + 5));
    if (marker == 0xDA || length < 2) return std::nullopt;  // scan data before a frame header
    i += 2 + length;
  }
  return std::nullopt;
}

cv::Mat ReadImage(const std::string& path, double max_pixels, std::vector<std::string>* warnings) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (std::filesystem::is_directory(st)) throw InvalidArgument("image: '" + path + "' is a directory, not a file");
  if (!std::filesystem::exists(st)) throw IoError("image: cannot open '" + path + "': no such file");
  if (!std::filesystem::is_regular_file(st)) throw InvalidArgument("image: '" + path + "' is not a regular file");
  std::ifstream f(path, std::ios::binary);
  std::vector<uchar> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (!f.good() && !f.eof()) throw IoError("image: cannot read '" + path + "'");
  if (bytes.empty()) throw IoError("image: '" + path + "' is empty");
  const bool jpeg = bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
  if (jpeg) {
    // A complete JPEG ends with the EOI marker FF D9 (allow a little trailing padding).
    bool eoi = false;
    for (size_t i = bytes.size() >= 64 ? bytes.size() - 64 : 0; i + 1 < bytes.size(); ++i)
      eoi = eoi || (bytes[i] == 0xFF && bytes[i + 1] == 0xD9);
    if (!eoi) throw IoError("image: '" + path + "' is a truncated JPEG (no end-of-image marker)");
  }
  if (const auto size = DeclaredImageSize(bytes);
      size && static_cast<double>(size->first) * size->second > max_pixels) {
    char m[160];
    std::snprintf(m, sizeof(m), "%d x %d = %.0f million pixels, more than the %.0f million allowed (--max-image-mpx)",
                  size->first, size->second, size->first * 1e-6 * size->second, max_pixels * 1e-6);
    throw InvalidArgument("image: '" + path + "' is " + m);
  }
  EnsureGdalRegistered();  // before OpenCV's first decode registers GDAL's drivers itself
  cv::Mat image;
  // The codec libraries print their warnings ("Corrupt JPEG data: ...") on
  // the standard error themselves: they are caught there and returned in our
  // words. The redirection is process-wide, so decodes take turns.
  static std::mutex stderr_mutex;
  std::string captured;
  {
    std::lock_guard<std::mutex> lock(stderr_mutex);
    std::fflush(stderr);
    FILE* sink = std::tmpfile();
    const int saved = sink ? ::dup(STDERR_FILENO) : -1;
    const bool redirected = saved >= 0 && ::dup2(::fileno(sink), STDERR_FILENO) >= 0;
    try {
      // IMREAD_COLOR applies the EXIF orientation (phones store portrait photos
      // sideways with a rotation tag) and gives 8-bit BGR for any input depth.
      image = cv::imdecode(bytes, cv::IMREAD_COLOR);
    } catch (const cv::Exception&) {
      image.release();  // reported below with the file name
    }
    if (redirected) {
      std::fflush(stderr);
      ::dup2(saved, STDERR_FILENO);
      std::rewind(sink);
      char buf[512];
      size_t n;
      while ((n = std::fread(buf, 1, sizeof(buf), sink)) > 0 && captured.size() < 4096) captured.append(buf, n);
    }
    if (saved >= 0) ::close(saved);
    if (sink) std::fclose(sink);
  }
  if (!captured.empty() && warnings) {
    for (char& c : captured)
      if (c == '\n' || c == '\r') c = ' ';
    while (!captured.empty() && captured.back() == ' ') captured.pop_back();
    warnings->push_back("image: '" + path + "' was decoded with errors (" + captured.substr(0, 200) + ")");
  }
  if (image.empty()) throw IoError("image: '" + path + "' is not a readable image");
  if (image.type() != CV_8UC3) throw IoError("image: '" + path + "' has an unsupported pixel type");
  return image;
}

}  // namespace horizonreg
