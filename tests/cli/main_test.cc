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
       {"bench", "convert", "detect", "eval", "optimize", "render", "report", "run"}) {
    SCOPED_TRACE(command);
    const CliResult r = RunCli({command, "--help"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("--help"), std::string::npos) << r.out;
    EXPECT_EQ(r.err.find("This should be caught"), std::string::npos) << r.err;
  }
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

}  // namespace
}  // namespace sparseloop::test
