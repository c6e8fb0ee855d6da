// SPDX-License-Identifier: MIT
// horizonreg: the command-line tool. Dispatches to one Run<Command>() per
// subcommand and turns errors into one line on stderr and an exit code:
// 0 success, 2 bad usage or unreadable/invalid input, 1 internal failure
// (cli/guard.h). `track` runs in horizonreg-track (track_main.cc).
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <iostream>

#include "cli/commands.h"
#include "cli/guard.h"

namespace {

// Replaces this process by horizonreg-track (beside this executable) with
// the same arguments; returns 1 with a message only when that fails.
int ExecTrack(char** argv) {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::filesystem::path helper = (ec ? std::filesystem::path(argv[0]) : self).parent_path() / "horizonreg-track";
  execv(helper.c_str(), argv);
  std::cerr << "horizonreg: track needs " << helper.string() << ": " << std::strerror(errno) << "\n";
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace horizonreg;
  CLI::App app{"horizonreg: outdoor AR registration from terrain horizons"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "horizonreg 0.1.0");
  cli::HorizonArgs horizon_args;
  cli::DemoArgs demo_args;
  cli::SkylineArgs skyline_args;
  cli::RegisterArgs register_args;
  cli::OverlayArgs overlay_args;
  cli::RenderArgs render_args;
  cli::TrackArgs track_args;
  cli::BatchArgs batch_args;
  cli::LocateArgs locate_args;
  cli::AddHorizonCommand(app, horizon_args);
  cli::AddSkylineCommand(app, skyline_args);
  cli::AddRegisterCommand(app, register_args);
  cli::AddOverlayCommand(app, overlay_args);
  cli::AddRenderCommand(app, render_args);
  cli::AddTrackCommand(app, track_args);
  cli::AddBatchCommand(app, batch_args);
  cli::AddLocateCommand(app, locate_args);
  cli::AddDemoCommand(app, demo_args);
  if (const int code = cli::ParseOrExit(app, argc, argv); code >= 0) return code;
  if (app.got_subcommand("track")) return ExecTrack(argv);  // checked here, run there
  return cli::RunGuarded([&] {
    if (app.got_subcommand("horizon")) return cli::RunHorizon(horizon_args);
    if (app.got_subcommand("skyline")) return cli::RunSkyline(skyline_args);
    if (app.got_subcommand("register")) return cli::RunRegister(register_args);
    if (app.got_subcommand("overlay")) return cli::RunOverlay(overlay_args);
    if (app.got_subcommand("render")) return cli::RunRender(render_args);
    if (app.got_subcommand("batch")) return cli::RunBatch(batch_args);
    if (app.got_subcommand("locate")) return cli::RunLocate(locate_args);
    if (app.got_subcommand("demo")) return cli::RunDemo(demo_args);
    std::cerr << "horizonreg: no command given (see --help)\n";
    return 2;
  });
}
