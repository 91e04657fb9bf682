#include "cli/cli_runner.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "test_util.h"

namespace sparseloop::test {

namespace {
std::string Quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}
}  // namespace

CliResult RunCli(const std::vector<std::string>& args) {
  // A folder of its own: the test's TempDir() may hold the command's input files.
  const auto dir = TempDir(".cli_output");
  std::string cmd = Quote(ConfiguredCliPath().string());
  for (const auto& a : args) cmd += " " + Quote(a);
  cmd += " >" + Quote((dir / "stdout").string()) + " 2>" + Quote((dir / "stderr").string());
  const int status = std::system(cmd.c_str());
  CliResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = ReadText(dir / "stdout");
  r.err = ReadText(dir / "stderr");
  return r;
}

const std::filesystem::path& RenderedLoopSequence() {
  namespace fs = std::filesystem;
  static const fs::path dir = [] {
    const fs::path root = std::getenv("SPARSELOOP_TEST_TMP")
                              ? fs::path(std::getenv("SPARSELOOP_TEST_TMP"))
                              : fs::temp_directory_path() / "sparseloop_tests";
    const fs::path final_dir = root / "rendered_loop_sequence_v1";
    if (fs::exists(final_dir / "done")) return final_dir;
    // Rendered beside it and renamed: tests running in parallel never see half a sequence.
    const fs::path tmp = root / ("rendered_loop_sequence.tmp." + std::to_string(::getpid()));
    fs::remove_all(tmp);
    fs::create_directories(root);
    std::string cmd = Quote(ConfiguredCliPath().string()) +
                      " render --world aerial --plan circuit --frames 60 --laps 2 --seed 1 --out " +
                      Quote(tmp.string()) + " >/dev/null 2>&1";
    if (std::system(cmd.c_str()) != 0) return fs::path();
    std::ofstream(tmp / "done") << "1\n";
    std::error_code ec;
    fs::rename(tmp, final_dir, ec);  // fails when another process was first: use theirs
    if (ec) fs::remove_all(tmp);
    return final_dir;
  }();
  return dir;
}

nlohmann::json ReadJson(const std::filesystem::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  return nlohmann::json::parse(in);
}

}  // namespace sparseloop::test
