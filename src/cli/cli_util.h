#pragma once
// Small helpers shared by the subcommands (parsing only; no algorithm lives in the CLI).
#include <cctype>
#include <filesystem>
#include <iostream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "sparseloop/core/error.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/output_paths.h"

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

// A JSON document as the commands write it (summary.json, eval --json, render.json): indented, one
// trailing newline. A path or name that is not UTF-8 (a file named with byte 0xFF) is written with
// U+FFFD in its place: JSON holds UTF-8 only, and the run's work must not be lost to it.
inline std::string JsonText(const nlohmann::json& j) {
  return j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

// The files a command writes into its --out folder `dir`, each named by `flag`, as outputs for
// CheckOutputsAreNotInputs ("--out DIR/trajectory.txt: ... got the file of --gt ...").
inline std::vector<NamedPath> FilesIn(const std::string& flag, const std::string& dir,
                                      const std::vector<std::string>& names) {
  std::vector<NamedPath> files;
  for (const std::string& name : names) files.push_back({flag, std::filesystem::path(dir) / name});
  return files;
}

// A --map database and the -wal / -shm files SQLite keeps beside it, as inputs.
inline std::vector<NamedPath> MapFiles(const std::string& flag, const std::string& map) {
  if (map.empty()) return {};
  return {{flag, map}, {flag, map + "-wal"}, {flag, map + "-shm"}};
}

// Option fields named in library messages, with the flag that sets each: {"loss_scale",
// "--loss-scale"}. A field is matched as a whole word ("GT loop distance" matches as a phrase).
using FlagNames = std::vector<std::pair<std::string, std::string>>;

// The message with the first field of `names` it mentions replaced by that field's flag:
// "loss_scale must be > 0, got -1" -> "--loss-scale must be > 0, got -1". Unchanged when it
// mentions none.
inline std::string NameFlagsIn(const std::string& message, const FlagNames& names) {
  const auto is_word = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
  };
  for (const auto& [field, flag] : names) {
    for (size_t pos = message.find(field); pos != std::string::npos;
         pos = message.find(field, pos + 1)) {
      const size_t end = pos + field.size();
      if ((pos == 0 || !is_word(message[pos - 1])) &&
          (end == message.size() || !is_word(message[end]))) {
        return message.substr(0, pos) + flag + message.substr(end);
      }
    }
  }
  return message;
}

// Runs `check` (options' Check(), filled from flags) and rewrites an std::invalid_argument so it
// names the flag the user typed instead of the library's field (exit 2 either way).
template <typename Check>
void CheckNamingFlags(const FlagNames& names, Check&& check) {
  try {
    check();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(NameFlagsIn(e.what(), names));
  }
}

}  // namespace sparseloop::cli
