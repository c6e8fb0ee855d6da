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
//
// And it sets glibc's malloc to back the heap with transparent huge pages
// and to grow it 64 MB at a time (GLIBC_TUNABLES, unless the caller set
// it: `GLIBC_TUNABLES=` keeps glibc's defaults). A one-shot process touches
// its 100-150 MB once: in 4 KB pages each first touch is a page fault,
// dearer still in a virtual machine. Measured (real photos, `register
// --trust-position`, medians of 2-3 runs, 2 cores): timing_ms.total 170-204
// -> 104-131 ms, CPU 0.45-0.51 -> 0.30-0.37 s, the JSON identical; max RSS
// 116 -> 132 MB; huge pages without the larger growth 166 ms, the larger
// growth without huge pages 181 ms.
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
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
  setenv("GLIBC_TUNABLES", "glibc.malloc.hugetlb=1:glibc.malloc.top_pad=67108864", 0);  // 0: the caller's stays
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::filesystem::path helper = (ec ? std::filesystem::path(argv[0]) : self).parent_path() / target;
  execv(helper.c_str(), argv);
  std::fprintf(stderr, "horizonreg: cannot run %s: %s\n", helper.c_str(), std::strerror(errno));
  return 1;
}
