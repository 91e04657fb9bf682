// Error messages (docs/ROBUSTNESS.md, bad-input table): an invalid option value exits 2 with a
// message that names the flag the user typed, never a C++ expression or a source path.
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli/cli_runner.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

namespace fs = std::filesystem;

void ExpectNamesTheFlag(const std::vector<std::string>& args, const std::string& expected) {
  SCOPED_TRACE(args[0] + " ... " + expected);
  const CliResult r = RunCli(args);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(expected), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(".cc:"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("Check failed"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("::"), std::string::npos) << r.err;  // no API names
}

TEST(CliMessages, OptionErrorsNameTheFlagNeverASourcePath) {
  const auto dir = TempDir();
  {
    std::ofstream traj(dir / "gt.txt");
    for (int i = 0; i < 20; ++i) traj << i << " " << i << " 0 0\n";
    std::ofstream g2o(dir / "g.g2o");
    g2o << "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n";
  }
  fs::create_directories(dir / "images");
  const std::string gt = (dir / "gt.txt").string();
  const std::string out = (dir / "out").string();
  const std::string images = "images:" + (dir / "images").string();
  for (const char* command : {"run", "detect"}) {
    ExpectNamesTheFlag({command, "--dataset", images, "--poses", gt, "--intrinsics",
                        "-5,500,320,240", "--out", out},
                       "--intrinsics: fx must be positive and finite, got -5");
    ExpectNamesTheFlag({command, "--dataset", images, "--poses", gt, "-K", "3", "--out", out},
                       "-K must be in [5, 10000], got 3");
    ExpectNamesTheFlag(
        {command, "--dataset", images, "--poses", gt, "--min-path-ratio", "-1", "--out", out},
        "--min-path-ratio must be >= 0, got -1");
  }
  // Checked when parsed, not after the run (the image folder is empty).
  ExpectNamesTheFlag({"run", "--dataset", images, "--poses", gt, "--intrinsics", "50,50,32,24",
                      "--gt-loop-distance", "nan", "--out", out},
                     "--gt-loop-distance must be a distance > 0, got nan");
  ExpectNamesTheFlag({"optimize", "--g2o", (dir / "g.g2o").string(), "--out",
                      (dir / "o.g2o").string(), "--loss-scale", "-1"},
                     "--loss-scale must be > 0, got -1");
  ExpectNamesTheFlag({"eval", "--gt", gt, "--est", gt, "--max-dt", "-1"},
                     "--max-dt must be >= 0 s, got -1");
  ExpectNamesTheFlag({"eval", "--gt", gt, "--est", gt, "--rpe-delta", "-3"},
                     "--rpe-delta must be > 0, got -3");
  ExpectNamesTheFlag({"eval", "--gt", gt, "--est", gt, "--derive-loops", "5,10", "--view-angle",
                      "-3", "--loops", (dir / "loops.csv").string()},
                     "--view-angle must be in (0, 180], got -3");
  ExpectNamesTheFlag({"render", "--world", "aerial", "--altitude", "-4", "--out", out},
                     "--altitude must be > 1 metre, got -4");
  ExpectNamesTheFlag({"render", "--world", "aerial", "--noise", "-4", "--out", out},
                     "--noise must be >= 0, got -4");
  ExpectNamesTheFlag({"report", dir.string(), "--false-loop-distance", "-1"},
                     "--false-loop-distance must be > 0, got -1");
}

}  // namespace
}  // namespace sparseloop::test
