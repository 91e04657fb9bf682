#pragma once
// Small helpers shared by the subcommands (parsing only; no algorithm lives in the CLI).
#include <iostream>

#include <CLI/CLI.hpp>

namespace sparseloop::cli {

// Parses argv into `app`. `--help` prints the command's help to stdout and throws
// CLI::CallForHelp (main maps it to exit 0); other CLI::ParseError exceptions propagate (exit 2).
inline void Parse(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::cout << app.help();
    throw;
  } catch (const CLI::CallForAllHelp&) {
    std::cout << app.help("", CLI::AppFormatMode::All);
    throw;
  }
}

}  // namespace sparseloop::cli
