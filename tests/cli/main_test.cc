#include <fstream>
#include <regex>
#include <sstream>

#include <gtest/gtest.h>

#include "cli/cli_runner.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

TEST(Cli, NoArgumentsPrintsUsageAndExits2) {
  const CliResult r = RunCli({});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("Usage: sparseloop <command>"), std::string::npos);
}

TEST(Cli, UnknownCommandExits2) {
  const CliResult r = RunCli({"frobnicate"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown command 'frobnicate'"), std::string::npos);
}

// Every subcommand prints its own help (options listed) to stdout and exits 0.
TEST(Cli, EverySubcommandHelpExits0WithOptions) {
  for (const char* command :
       {"bench", "config", "convert", "detect", "eval", "optimize", "render", "report", "run"}) {
    SCOPED_TRACE(command);
    const CliResult r = RunCli({command, "--help"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("--help"), std::string::npos) << r.out;
    EXPECT_EQ(r.err.find("This should be caught"), std::string::npos) << r.err;
  }
}

// `bench --quick --family` is a usage error (exit 2, both flags named), before any python runs.
TEST(Cli, BenchQuickAndFamilyExcludeEachOther) {
  const CliResult r = RunCli({"bench", "--quick", "--family"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--family"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--quick"), std::string::npos) << r.err;
  EXPECT_NE(RunCli({"bench", "--help"}).out.find("--family"), std::string::npos);
}

TEST(Cli, UnknownOptionExits2AndPointsToHelp) {
  const CliResult r = RunCli({"eval", "--no-such-flag"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("sparseloop eval --help"), std::string::npos) << r.err;
}

// `sparseloop --version`: the version of CMakeLists.txt's project() and the git commit captured
// at configure time (12 hex digits, or "unknown" outside a git checkout).
TEST(Cli, VersionPrintsProjectVersionAndGitCommit) {
  std::ifstream cmake(SourceDir() / "CMakeLists.txt");
  std::stringstream text;
  text << cmake.rdbuf();
  std::smatch version;
  const std::string cmake_text = text.str();
  ASSERT_TRUE(std::regex_search(cmake_text, version,
                                std::regex(R"(project\(sparseloop VERSION ([0-9.]+))")));
  const CliResult r = RunCli({"--version"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(std::regex_match(
      r.out, std::regex("sparseloop " +
                        std::regex_replace(version[1].str(), std::regex(R"(\.)"), R"(\.)") +
                        R"( \(git commit ([0-9a-f]{12}|unknown)\)\n)")))
      << r.out;
  EXPECT_NE(RunCli({"--help"}).out.find("sparseloop --version"), std::string::npos);
}

// The line of `help` that documents `option`.
std::string HelpLine(const std::string& help, const std::string& option) {
  std::istringstream lines(help);
  for (std::string line; std::getline(lines, line);) {
    if (line.find(option) != std::string::npos) return line;
  }
  return {};
}

// `run --help` says when --poses is required; -K and --search show the detector's defaults.
TEST(Cli, HelpShowsRequiredPosesAndDefaults) {
  const std::string run = RunCli({"run", "--help"}).out;
  // Required unless a rosbag: dataset names its pose topic (checked when run starts, below).
  EXPECT_NE(HelpLine(run, "--poses").find("required unless"), std::string::npos) << run;
  for (const std::string& help : {run, RunCli({"detect", "--help"}).out}) {
    EXPECT_NE(HelpLine(help, "-K,--features").find("=300"), std::string::npos) << help;
    EXPECT_NE(HelpLine(help, "--search").find("=paper"), std::string::npos) << help;
  }
  const CliResult no_poses = RunCli({"run", "--dataset", "images:/x", "--out", "/tmp/x"});
  EXPECT_EQ(no_poses.exit_code, 2);
  EXPECT_NE(no_poses.err.find("--poses is required"), std::string::npos) << no_poses.err;
}

// Integer options out of range: a short message naming the flag, not a 300-digit range; a
// negative --frames is an error, not the default.
TEST(Cli, IntegerOptionsOutOfRangeGiveAShortError) {
  const auto dir = TempDir();
  const struct {
    std::vector<std::string> args;
    std::string message;
  } cases[] = {
      {{"optimize", "--g2o", "in.g2o", "--out", (dir / "o.g2o").string(), "--max-iterations", "0"},
       "--max-iterations: must be an integer >= 1, got '0'"},
      {{"optimize", "--g2o", "in.g2o", "--out", (dir / "o.g2o").string(), "--threads", "x"},
       "--threads: must be an integer >= 1, got 'x'"},
      {{"render", "--world", "aerial", "--frames", "-5", "--out", (dir / "r").string()},
       "--frames: must be an integer >= 0, got '-5'"},
      {{"render", "--world", "aerial", "--step", "0", "--out", (dir / "r").string()},
       "--step: must be an integer >= 1, got '0'"},
      {{"detect", "--dataset", "images:/x", "-K", "0", "--out", (dir / "d").string()},
       "must be an integer >= 1, got '0'"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.args[0] + " " + c.message);
    const CliResult r = RunCli(c.args);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r.err;
    EXPECT_LT(r.err.size(), 200u) << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "r"));  // nothing rendered
}

}  // namespace
}  // namespace sparseloop::test
