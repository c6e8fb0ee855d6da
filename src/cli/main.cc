// SPDX-License-Identifier: MIT
// horizonreg: the command-line tool. Dispatches to one Run<Command>() per
// subcommand and turns errors into one line on stderr and an exit code:
// 0 success, 2 bad usage or unreadable/invalid input, 1 internal failure.
#include <CLI/CLI.hpp>
#include <iostream>

#include "cli/commands.h"
#include "util/errors.h"

namespace {

std::string OneLine(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  return s;
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
  cli::AddHorizonCommand(app, horizon_args);
  cli::AddSkylineCommand(app, skyline_args);
  cli::AddRegisterCommand(app, register_args);
  cli::AddOverlayCommand(app, overlay_args);
  cli::AddRenderCommand(app, render_args);
  cli::AddTrackCommand(app, track_args);
  cli::AddDemoCommand(app, demo_args);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "horizonreg: " << OneLine(e.what()) << " (see --help)\n";
    return 2;
  }
  try {
    if (app.got_subcommand("horizon")) return cli::RunHorizon(horizon_args);
    if (app.got_subcommand("skyline")) return cli::RunSkyline(skyline_args);
    if (app.got_subcommand("register")) return cli::RunRegister(register_args);
    if (app.got_subcommand("overlay")) return cli::RunOverlay(overlay_args);
    if (app.got_subcommand("render")) return cli::RunRender(render_args);
    if (app.got_subcommand("track")) return cli::RunTrack(track_args);
    if (app.got_subcommand("demo")) return cli::RunDemo(demo_args);
    std::cerr << "horizonreg: no command given (see --help)\n";
    return 2;
  } catch (const InvalidArgument& e) {
    std::cerr << "horizonreg: " << OneLine(e.what()) << "\n";
    return 2;
  } catch (const IoError& e) {
    std::cerr << "horizonreg: " << OneLine(e.what()) << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << "horizonreg: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "horizonreg: internal error: " << OneLine(e.what()) << "\n";
    return 1;
  } catch (...) {
    std::cerr << "horizonreg: internal error of unknown type\n";
    return 1;
  }
}
