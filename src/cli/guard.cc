// SPDX-License-Identifier: MIT
#include "cli/guard.h"

#include <CLI/CLI.hpp>
#include <iostream>

#include "util/errors.h"

namespace horizonreg::cli {
namespace {

std::string OneLine(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  return s;
}

}  // namespace

int ParseOrExit(CLI::App& app, int argc, char** argv) {
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
  return -1;
}

int RunGuarded(const std::function<int()>& command) {
  try {
    return command();
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

void AddMaxImageOption(CLI::App& command, double& max_image_mpx) {
  command.add_option("--max-image-mpx", max_image_mpx, "Refuse photos larger than this, million pixels")
      ->check(CLI::Range(0.01, 10000.0))
      ->capture_default_str();
}

void AddMaxDemOption(CLI::App& command, double& max_dem_mb) {
  command.add_option("--max-dem-mb", max_dem_mb, "Refuse DEM windows that need more memory, MB")
      ->check(CLI::Range(1.0, 1e7))
      ->capture_default_str();
}

}  // namespace horizonreg::cli
