// SPDX-License-Identifier: MIT
// Small text helpers for the CSV and number parsing of input files.
#pragma once

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "util/errors.h"

namespace horizonreg {

// The number in `s` (surrounding spaces allowed), nullopt if `s` is not
// exactly one finite or non-finite number ("nan" parses as NaN).
inline std::optional<double> ParseDouble(const std::string& s) {
  size_t begin = 0, end = s.size();
  while (begin < end && std::isspace(static_cast<unsigned char>(s[begin]))) ++begin;
  while (end > begin && std::isspace(static_cast<unsigned char>(s[end - 1]))) --end;
  if (begin == end) return std::nullopt;
  const std::string t = s.substr(begin, end - begin);
  size_t used = 0;
  try {
    const double v = std::stod(t, &used);
    if (used == t.size()) return v;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

// `s` without leading and trailing white space.
inline std::string Trim(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return s.substr(b, e - b);
}

// The cells of one CSV line: commas separate, double quotes group (a doubled
// quote inside is one quote), carriage returns are dropped.
inline std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (c == '"') {
      if (quoted && i + 1 < line.size() && line[i + 1] == '"') {
        out.back() += '"';
        ++i;
      } else {
        quoted = !quoted;
      }
    } else if (c == ',' && !quoted) {
      out.emplace_back();
    } else if (c != '\r') {
      out.back() += c;
    }
  }
  return out;
}

// Throws InvalidArgument "<what>: '<path>' is a directory, not a file" when
// it is one (a stream opens a directory on Linux, and its size reads as
// 8 EB, its first read as an internal error).
inline void RequireNotDirectory(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InvalidArgument(what + ": '" + path + "' is a directory, not a file");
}

// The whole file as text. Throws IoError "<what>: cannot open '<path>'", and
// InvalidArgument when the file is a directory or larger than max_bytes
// (checked before reading: input files are bounded, never read into an
// out-of-memory kill).
inline std::string ReadTextFile(const std::string& path, const std::string& what, size_t max_bytes = size_t{1} << 30) {
  RequireNotDirectory(path, what);
  std::ifstream f(path, std::ios::binary);
  if (!f) throw IoError(what + ": cannot open '" + path + "'");
  const std::string limit = "the " + std::to_string(max_bytes >> 20) + " MB such a file may have";
  f.seekg(0, std::ios::end);
  const std::streamoff size = f.tellg();
  if (size > 0 && static_cast<size_t>(size) > max_bytes)
    throw InvalidArgument(what + ": '" + path + "' is " + std::to_string(size >> 20) + " MB, more than " + limit);
  f.clear();
  f.seekg(0, std::ios::beg);
  // Read in blocks up to the bound: a device or pipe (/dev/zero, a FIFO)
  // has no size to check first.
  std::string out;
  char block[1 << 16];
  while (f.read(block, sizeof(block)) || f.gcount() > 0) {
    out.append(block, static_cast<size_t>(f.gcount()));
    if (out.size() > max_bytes) throw InvalidArgument(what + ": '" + path + "' is larger than " + limit);
    if (f.eof()) break;
  }
  if (f.bad()) throw IoError(what + ": cannot read '" + path + "'");
  return out;
}

// A CSV table with a header line: (line number, column -> cell) per row,
// empty cells left out; blank lines and lines starting with '#' skipped, a
// UTF-8 byte-order mark dropped, cells trimmed. Throws InvalidArgument
// "<what> '<path>', line N: ..." for a column not in `known` (when `known` is
// not empty), a column named twice, or a row whose cell count differs from the
// header's.
inline std::vector<std::pair<int, std::map<std::string, std::string>>> ReadCsvRecords(
    const std::string& text, const std::string& what, const std::string& path, const std::vector<std::string>& known) {
  std::vector<std::pair<int, std::map<std::string, std::string>>> out;
  std::istringstream in(text);
  std::string line;
  std::vector<std::string> header;
  int n = 0;
  const auto bad = [&](const std::string& why) {
    throw InvalidArgument(what + " '" + path + "', line " + std::to_string(n) + ": " + why);
  };
  while (std::getline(in, line)) {
    ++n;
    if (n == 1 && line.size() >= 3 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);
    if (Trim(line).empty() || Trim(line)[0] == '#') continue;
    std::vector<std::string> cells = SplitCsvLine(line);
    for (auto& c : cells) c = Trim(c);
    if (header.empty()) {
      header = cells;
      for (size_t i = 0; i < header.size(); ++i) {
        if (!known.empty() && std::find(known.begin(), known.end(), header[i]) == known.end()) {
          std::string list;
          for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
          bad("unknown column '" + header[i] + "' (known: " + list + ")");
        }
        if (std::find(header.begin(), header.begin() + i, header[i]) != header.begin() + i)
          bad("column '" + header[i] + "' appears twice");
      }
      continue;
    }
    if (cells.size() != header.size())
      bad(std::to_string(cells.size()) + " cells, the header has " + std::to_string(header.size()));
    std::map<std::string, std::string> r;
    for (size_t i = 0; i < cells.size(); ++i)
      if (!cells[i].empty()) r[header[i]] = cells[i];
    out.emplace_back(n, std::move(r));
  }
  if (header.empty()) throw InvalidArgument(what + " '" + path + "': empty (expected a header line)");
  return out;
}

}  // namespace horizonreg
