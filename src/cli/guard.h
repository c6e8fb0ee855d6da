// SPDX-License-Identifier: MIT
// The command line's error contract, shared by horizonreg and
// horizonreg-track: errors become one line on stderr and an exit code (0
// success, 2 bad usage or unreadable/invalid input, 1 internal failure).
#pragma once

#include <functional>
#include <string>

namespace CLI {
class App;
}

namespace horizonreg::cli {

// Parses argv into app; on --help/--version prints and returns their code,
// on a parse error prints one line and returns 2; else returns -1.
int ParseOrExit(CLI::App& app, int argc, char** argv);

// Runs a command, mapping its exceptions to one line on stderr and an exit
// code.
int RunGuarded(const std::function<int()>& command);

// The resource limits every command that reads photos or DEMs takes:
// --max-image-mpx (photos larger than this many million pixels are refused)
// and --max-dem-mb (DEM windows needing more memory are refused).
void AddMaxImageOption(CLI::App& command, double& max_image_mpx);
void AddMaxDemOption(CLI::App& command, double& max_dem_mb);

}  // namespace horizonreg::cli
