#include "cli/report_script.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>
#include <cstdlib>

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"

extern char** environ;

namespace sparseloop::cli {

namespace fs = std::filesystem;

void ReportOptions::Check() const {
  SL_CHECK_MSG(false_loop_distance >= 0.0, "false_loop_distance must be > 0, got {}",
               false_loop_distance);  // 0: summary.json's
}

namespace {

// Runs argv (PATH lookup), stdout -> stderr, optionally stderr -> /dev/null. Returns the exit
// code, or -1 when the program could not be started.
int Run(const std::vector<std::string>& args, bool quiet) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (quiet) {
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  } else {
    posix_spawn_file_actions_adddup2(&actions, STDERR_FILENO, STDOUT_FILENO);
  }
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) < 0) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

fs::path FindReportScript() {
  std::vector<fs::path> candidates;
  if (const char* env = std::getenv("SPARSELOOP_REPORT_SCRIPT")) candidates.emplace_back(env);
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    candidates.push_back(exe.parent_path() / ".." / "share" / "sparseloop" / "report.py");
    candidates.push_back(exe.parent_path() / "report.py");
  }
#ifdef SPARSELOOP_SOURCE_DIR
  candidates.push_back(fs::path(SPARSELOOP_SOURCE_DIR) / "scripts" / "report.py");
#endif
  for (const auto& c : candidates) {
    if (fs::is_regular_file(c, ec)) return fs::weakly_canonical(c, ec);
  }
  return {};
}

std::string FindPython() {
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("SPARSELOOP_PYTHON")) candidates.emplace_back(env);
  candidates.emplace_back("python3");
  candidates.emplace_back("/usr/bin/python3");
  for (const auto& py : candidates) {
    if (Run({py, "-c", "import matplotlib, numpy"}, /*quiet=*/true) == 0) return py;
  }
  return {};
}

ReportResult MakeReport(const fs::path& dir, const ReportOptions& options) {
  options.Check();
  SL_CHECK_MSG(fs::is_directory(dir), "report needs an existing run folder, got '{}'",
               dir.string());
  ReportResult result;
  const fs::path script = options.script.empty() ? FindReportScript() : options.script;
  if (script.empty() || !fs::is_regular_file(script)) {
    result.status = ReportResult::Status::kNoScript;
    result.message =
        "report.py not found (looked in $SPARSELOOP_REPORT_SCRIPT, <bin>/../share/sparseloop, "
        "<bin>, and the source tree's scripts/)";
    return result;
  }
  const std::string python = options.python.empty() ? FindPython() : options.python;
  if (python.empty()) {
    result.status = ReportResult::Status::kNoPython;
    result.message =
        "no python3 with matplotlib and numpy found (tried $SPARSELOOP_PYTHON, python3, "
        "/usr/bin/python3); install python3-matplotlib";
    return result;
  }
  Logger().info("report: {} {} {}", python, script.string(), dir.string());
  std::vector<std::string> args = {python, script.string(), dir.string()};
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {  // loops are scored by this binary's `eval` (the one definition)
    args.push_back("--sparseloop");
    args.push_back(exe.string());
  }
  if (options.false_loop_distance > 0.0) {
    args.push_back("--false-loop-distance");
    args.push_back(fmt::format("{}", options.false_loop_distance));
  }
  result.exit_code = Run(args, /*quiet=*/false);
  if (result.exit_code == 2) {  // the run folder is malformed (the script said where)
    result.status = ReportResult::Status::kBadInput;
    result.message = "report.py: the run folder's files disagree or are malformed (see above)";
    return result;
  }
  if (result.exit_code != 0) {
    result.status = ReportResult::Status::kScriptFailed;
    result.message = "report.py failed with exit code " + std::to_string(result.exit_code);
    return result;
  }
  result.status = ReportResult::Status::kOk;
  result.html = dir / "report.html";
  return result;
}

}  // namespace sparseloop::cli
