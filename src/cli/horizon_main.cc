// SPDX-License-Identifier: MIT
// horizonreg-horizon: runs `horizonreg horizon` (without --plot) for the
// launcher. Links GDAL but not OpenCV: a whole `horizonreg horizon` process
// starts in about half the time of the full executable.
#include <CLI/CLI.hpp>

#include "cli/commands.h"
#include "cli/guard.h"

int main(int argc, char** argv) {
  using namespace horizonreg;
  CLI::App app{"horizonreg: outdoor AR registration from terrain horizons"};
  app.name("horizonreg");
  app.require_subcommand(1);
  cli::HorizonArgs args;
  cli::AddHorizonCommand(app, args);
  if (const int code = cli::ParseOrExit(app, argc, argv); code >= 0) return code;
  return cli::RunGuarded([&] { return cli::RunHorizon(args); });
}
