#include <gtest/gtest.h>

#include "cli/cli_runner.h"

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

}  // namespace
}  // namespace sparseloop::test
