// sparseloop bench: runs the benchmark suite (scripts/benchmark.py) with this binary's build
// folder, regenerating docs/BENCHMARKS.md. The experiments live in the script; this command only
// finds it and the interpreter (scripts/benchmark additionally does the Release build first).
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "cli/report_script.h"

namespace sparseloop::cli {

namespace {

namespace fs = std::filesystem;

int RunBench(int argc, char** argv) {
  CLI::App app{"Run the benchmark suite and regenerate docs/BENCHMARKS.md (see scripts/benchmark)"};
  bool quick = false, family = false, reuse = false;
  std::string out, python;
  int jobs = 2;
  app.add_flag("--quick", quick, "the subset that runs in under 10 minutes on 2 cores");
  app.add_flag("--family", family,
               "only the drift family at full size (docs/BENCHMARKS_DRIFT.md, ~30 minutes)")
      ->excludes("--quick");
  app.add_flag("--reuse", reuse, "keep experiments whose outputs already exist");
  app.add_option("--out", out,
                 "output folder (default out/bench-quick|family|full in the source tree)");
  app.add_option("--jobs", jobs, "experiments run in parallel")->capture_default_str();
  app.add_option("--python", python,
                 "python with matplotlib and numpy (default: as `report` finds it: "
                 "$SPARSELOOP_PYTHON, python3, /usr/bin/python3)");
  Parse(app, argc, argv);
  if (python.empty()) python = FindPython();
  if (python.empty()) {
    std::cerr << "sparseloop bench: no python3 with matplotlib and numpy found (tried "
                 "$SPARSELOOP_PYTHON, python3, /usr/bin/python3; install python3-matplotlib or "
                 "give --python)\n";
    return 2;
  }
  const fs::path script = fs::path(SPARSELOOP_SOURCE_DIR) / "scripts" / "benchmark.py";
  if (!fs::is_regular_file(script)) {
    std::cerr << "sparseloop bench: " << script.string()
              << " not found: bench runs from a source build (use scripts/benchmark)\n";
    return 2;
  }
  // The build folder is the parent of this executable's bin/ folder.
  const fs::path build = fs::read_symlink("/proc/self/exe").parent_path().parent_path();
  std::vector<std::string> args = {python,         script.string(), "--build",
                                   build.string(), "--jobs",        std::to_string(jobs)};
  if (quick) args.emplace_back("--quick");
  if (family) args.emplace_back("--family");
  if (reuse) args.emplace_back("--reuse");
  if (!out.empty()) args.insert(args.end(), {"--out", out});
  std::vector<char*> c_args;
  for (auto& a : args) c_args.push_back(a.data());
  c_args.push_back(nullptr);
  std::cout.flush();
  execvp(python.c_str(), c_args.data());
  std::cerr << "sparseloop bench: cannot run " << python << " (install python3-matplotlib)\n";
  return 2;
}

}  // namespace

SPARSELOOP_REGISTER_COMMAND("bench", "run the benchmark suite (regenerates docs/BENCHMARKS.md)",
                            RunBench);

}  // namespace sparseloop::cli
