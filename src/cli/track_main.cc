// SPDX-License-Identifier: MIT
// horizonreg-track: runs `horizonreg track`, which execs it with its own
// arguments. A separate executable because OpenCV's video I/O loads ~100
// more shared libraries (FFmpeg, GStreamer), ~30 ms of start-up that every
// other command would pay (scripts/bench_process.sh).
#include <CLI/CLI.hpp>

#include "cli/commands.h"
#include "cli/guard.h"

int main(int argc, char** argv) {
  using namespace horizonreg;
  CLI::App app{"horizonreg: outdoor AR registration from terrain horizons"};
  app.name("horizonreg");
  app.require_subcommand(1);
  cli::TrackArgs track_args;
  cli::AddTrackCommand(app, track_args);
  if (const int code = cli::ParseOrExit(app, argc, argv); code >= 0) return code;
  return cli::RunGuarded([&] { return cli::RunTrack(track_args); });
}
