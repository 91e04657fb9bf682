// sparseloop report: one-page HTML report of a run folder (plots by scripts/report.py).
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
