// SPDX-License-Identifier: MIT
// horizonreg: a launcher that links nothing and replaces itself (execv) by
// the executable that serves the command, so that each command loads only
// the libraries it needs:
//   horizonreg-horizon  `horizon` without --plot: GDAL only, no OpenCV
//                       (a single-point profile as a whole process is
//                       dominated by start-up: scripts/bench_process.sh)
//   horizonreg-track    `track`: OpenCV's video I/O (FFmpeg, GStreamer)
//   horizonreg-full     everything else (and --help, --version)
// All live beside this executable.
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

int main(int argc, char** argv) {
  const char* target = "horizonreg-full";
  if (argc > 1 && std::strcmp(argv[1], "track") == 0) target = "horizonreg-track";
  if (argc > 1 && std::strcmp(argv[1], "horizon") == 0) {
    target = "horizonreg-horizon";
    for (int i = 2; i < argc; ++i)
      if (std::strcmp(argv[i], "--plot") == 0 || std::strncmp(argv[i], "--plot=", 7) == 0) target = "horizonreg-full";
  }
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::filesystem::path helper = (ec ? std::filesystem::path(argv[0]) : self).parent_path() / target;
  execv(helper.c_str(), argv);
  std::fprintf(stderr, "horizonreg: cannot run %s: %s\n", helper.c_str(), std::strerror(errno));
  return 1;
}
