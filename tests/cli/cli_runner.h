#pragma once
// Runs the real sparseloop binary and captures its exit code, stdout and stderr.
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/io_test_util.h"  // ReadText, WriteText

namespace sparseloop::test {

struct CliResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

// The intrinsics of the castle-P30 images (real data: castle_p30_768) as --intrinsics takes them.
inline constexpr const char* kCastleIntrinsics = "689.87,691.04,379.798,251.327";

// RunCli({"eval", "--gt", path}) runs `sparseloop eval --gt path`.
CliResult RunCli(const std::vector<std::string>& args);

// A small rendered KITTI-layout sequence with loops (`sparseloop render --world aerial --plan
// circuit --frames 60 --laps 2`: images, poses.txt GT, poses_raw.txt drifting raw poses), rendered
// once per machine into the test temp root and shared read-only by the tests (about 7 s).
const std::filesystem::path& RenderedLoopSequence();

// A JSON file the CLI wrote (summary.json, eval --json); a test failure when it cannot be opened.
nlohmann::json ReadJson(const std::filesystem::path& path);

}  // namespace sparseloop::test
