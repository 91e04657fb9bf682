// sparseloop report: one-page HTML report of a run folder (plots by scripts/report.py).
#include <unistd.h>

#include <filesystem>
#include <iostream>

#include <CLI/CLI.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "cli/report_script.h"

namespace sparseloop::cli {

int RunReport(int argc, char** argv) {
  CLI::App app{"Write DIR/report.html: trajectories, loops, errors, timings, P/R"};
  std::string dir, script, python;
  cli::ReportOptions options;
  app.add_option("dir", dir,
                 "run folder (poses_gt.txt, poses_raw.txt, trajectory.txt, "
                 "loops.csv, summary.json, timings.csv)")
      ->required();
  app.add_option("--script", script, "report.py to use (default: installed or source tree)");
  app.add_option("--python", python, "python interpreter (default: first with matplotlib)");
  app.add_option("--false-loop-distance", options.false_loop_distance,
                 "GT distance beyond which an accepted loop is drawn as false (default: the "
                 "run's own, summary.json gt_loop_distance; else 10)");
  Parse(app, argc, argv);
  CheckNamingFlags({{"false_loop_distance", "--false-loop-distance"}}, [&] { options.Check(); });
  if (!python.empty()) {
    // A missing interpreter was "report.py failed with exit code -1" (exit 1).
    std::error_code ec;
    const bool file = std::filesystem::is_regular_file(python, ec);
    if (!file || ::access(python.c_str(), X_OK) != 0) {
      std::cerr << "sparseloop report: --python " << python
                << ": expected an executable Python interpreter, got "
                << (file                                  ? "a file that is not executable"
                    : std::filesystem::exists(python, ec) ? "something other than a file"
                                                          : "no such file")
                << "\n";
      return 2;
    }
  }
  options.script = script;
  options.python = python;
  const auto result = cli::MakeReport(dir, options);
  if (result.status != cli::ReportResult::Status::kOk) {
    std::cerr << "sparseloop report: " << result.message << "\n";
    return result.status == cli::ReportResult::Status::kScriptFailed ? 1 : 2;  // kBadInput: 2
  }
  std::cout << result.html.string() << "\n";
  return 0;
}

SPARSELOOP_REGISTER_COMMAND("report", "write an HTML report of a run folder", RunReport);

}  // namespace sparseloop::cli
