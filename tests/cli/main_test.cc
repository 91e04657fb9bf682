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

}  // namespace
}  // namespace sparseloop::test
