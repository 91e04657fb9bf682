#pragma once
// Small helpers shared by the subcommands (parsing only; no algorithm lives in the CLI).
#include <filesystem>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "sparseloop/core/error.h"
#include "sparseloop/io/atomic_file.h"

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

// An integer option of at least `min`. CLI11's PositiveNumber / NonNegativeNumber say "Value 0
// not in range 0.000000 to <300 digits>"; this says "must be an integer >= 1, got '0'".
inline CLI::Validator IntegerAtLeast(long long min) {
  return CLI::Validator(
      [min](std::string& text) -> std::string {
        long long value = 0;
        size_t used = 0;
        try {
          value = std::stoll(text, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        if (used == 0 || used != text.size() || value < min) {
          return "must be an integer >= " + std::to_string(min) + ", got '" + text + "'";
        }
        return {};
      },
      min == 1   ? "POSITIVE"
      : min == 0 ? "NON-NEGATIVE"
                 : ">=" + std::to_string(min));
}

// Runs `check` and turns a FileError into std::invalid_argument (exit 2) that starts with the
// flag the user typed: "--json out.fifo: expected a regular file ..., got a FIFO (named pipe)".
template <typename Check>
void NameTheFlag(const std::string& flag, Check&& check) {
  try {
    check();
  } catch (const FileError& e) {
    throw std::invalid_argument(flag + " " + e.what());
  }
}

// Output checks done before any work, so that a bad output path fails at once, not after the run.
inline void CheckOutputFileFlag(const std::string& flag, const std::string& path) {
  NameTheFlag(flag, [&] { CheckOutputFile(path); });
}
// `dir` (an --out folder) and the files the command will write into it.
inline void CheckOutputDirFlag(const std::string& flag, const std::string& dir,
                               const std::vector<std::string>& file_names = {}) {
  NameTheFlag(flag, [&] { CheckOutputDirectory(dir, file_names); });
}

}  // namespace sparseloop::cli
