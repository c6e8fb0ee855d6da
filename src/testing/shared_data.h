// SPDX-License-Identifier: MIT
// Test helpers: where the real data beside the checkout lives.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>

namespace horizonreg::testing {

// The ../shared folder (DEMs, scenes), from $HORIZONREG_SHARED set by CTest,
// or nullopt when it is absent (a user's fresh clone). Tests that need it
// call GTEST_SKIP() with a visible message in that case.
inline std::optional<std::filesystem::path> SharedDir() {
  const char* env = std::getenv("HORIZONREG_SHARED");
#ifdef HORIZONREG_DEFAULT_SHARED
  const char* fallback = HORIZONREG_DEFAULT_SHARED;
#else
  const char* fallback = "../shared";
#endif
  std::filesystem::path p = env != nullptr && *env != '\0' ? env : fallback;
  std::error_code ec;
  if (std::filesystem::is_directory(p / "dem", ec)) return std::filesystem::canonical(p, ec);
  return std::nullopt;
}

}  // namespace horizonreg::testing

// Skips the current test with a visible message when ../shared is absent.
#define HR_REQUIRE_SHARED(var)                                                           \
  const auto var##_opt = ::horizonreg::testing::SharedDir();                             \
  if (!var##_opt) GTEST_SKIP() << "SKIPPED: ../shared (real DEMs and scenes) is absent"; \
  const std::filesystem::path var = *var##_opt
