#pragma once
// Small helpers shared by the subcommands (parsing only; no algorithm lives in the CLI).
#include <CLI/CLI.hpp>

namespace sparseloop::cli {

// Parses argv into `app`; throws CLI::ParseError (mapped to exit 0 for --help, 2 otherwise).
inline void Parse(CLI::App& app, int argc, char** argv) { app.parse(argc, argv); }

}  // namespace sparseloop::cli
