#pragma once
// Runs the real sparseloop binary and captures its exit code, stdout and stderr.
#include <string>
#include <vector>

namespace sparseloop::test {

struct CliResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

// RunCli({"eval", "--gt", path}) runs `sparseloop eval --gt path`.
CliResult RunCli(const std::vector<std::string>& args);

}  // namespace sparseloop::test
