#pragma once
// The HTML run report, CLI-internal (the library never starts a process): locates
// scripts/report.py and a python3 with matplotlib, and runs it on a run directory. The script
// writes DIR/report.html (self-contained: plots embedded) and DIR/report_*.png.
#include <filesystem>
#include <string>
#include <vector>

namespace sparseloop::cli {

struct ReportOptions {
  std::filesystem::path script;  // report.py; empty: FindReportScript()
  std::string python;            // interpreter; empty: FindPython()
  // GT units: an accepted loop is drawn as false beyond this GT distance; 0 (default): the run's
  // own threshold, summary.json gt_loop_distance (10 without one), and the run's own verdicts.
  double false_loop_distance = 0.0;
  void Check() const;
};

struct ReportResult {
  // kBadInput: the script refused the folder (exit 2: e.g. a truncated loops.csv).
  enum class Status { kOk, kNoPython, kNoScript, kScriptFailed, kBadInput };
  Status status = Status::kNoScript;
  std::filesystem::path html;  // DIR/report.html when kOk
  int exit_code = -1;          // of the script
  std::string message;         // what went wrong (empty when kOk)
};

// $SPARSELOOP_REPORT_SCRIPT, <exe dir>/../share/sparseloop/report.py, <exe dir>/report.py, then
// <source tree>/scripts/report.py (compile-time path). Empty when none exists.
std::filesystem::path FindReportScript();
// $SPARSELOOP_PYTHON, python3 on PATH, /usr/bin/python3: the first that can import matplotlib.
// Empty when none can.
std::string FindPython();

// Runs the script on `dir` (the script's stdout is redirected to stderr: the library never
// prints to stdout). Throws std::invalid_argument when `dir` is not a folder.
ReportResult MakeReport(const std::filesystem::path& dir, const ReportOptions& options = {});

}  // namespace sparseloop::cli
