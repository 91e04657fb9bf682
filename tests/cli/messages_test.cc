// Error messages (docs/ROBUSTNESS.md, bad-input table): an invalid option value exits 2 with a
// message that names the flag the user typed, never a C++ expression or a source path.
#include <fstream>
#include <string>
#include <tuple>
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
    ExpectNamesTheFlag({command, "--dataset", images, "--poses", gt, "--intrinsics",
                        "1e-300,1e-300,320,240", "--out", out},
                       "--intrinsics: fx must be at least 1 pixel, got 1e-300");
    ExpectNamesTheFlag({command, "--dataset", images, "--poses", gt, "-K", "3", "--out", out},
                       "-K must be in [5, 10000], got 3");
    ExpectNamesTheFlag(
        {command, "--dataset", images, "--poses", gt, "--min-path-ratio", "-1", "--out", out},
        "--min-path-ratio must be >= 0, got -1");
  }
  // Checked when parsed, not after the run (the image folder is empty).
  ExpectNamesTheFlag({"run", "--dataset", images, "--poses", gt, "--intrinsics", "50,50,32,24",
                      "--gt-loop-distance", "nan", "--out", out},
                     "--gt-loop-distance must be a distance in (0, 1e12], got nan");
  // 1e308 passed the check and failed after every frame (4 x it is the default minimum path).
  ExpectNamesTheFlag({"run", "--dataset", images, "--poses", gt, "--intrinsics", "50,50,32,24",
                      "--gt-loop-distance", "1e308", "--out", out},
                     "--gt-loop-distance must be a distance in (0, 1e12], got 1e+308");
  // render: values whose cost grew without bound (--laps 1e9 ran for minutes, --size 1e7 took
  // gigabytes), or that failed on a library field's name (--drift 1e300).
  for (const auto& [flag, value, message] :
       std::vector<std::tuple<std::string, std::string, std::string>>{
           {"--laps", "1000000000", "--laps must be in [1, 1000], got 1000000000"},
           {"--size", "1e7", "--size must be in (1, 100000] metres, got 10000000"},
           {"--altitude", "1e308", "--altitude must be in (1, 10000] metres, got 1e+308"},
           {"--drift", "1e300", "--drift must be in [0, 50], got 1e+300"}}) {
    ExpectNamesTheFlag({"render", "--world", "aerial", "--frames", "3", "--poses-only", flag, value,
                        "--out", (dir / "r").string()},
                       message);
  }
  ExpectNamesTheFlag({"report", dir.string(), "--python", (dir / "no_python").string()},
                     "--python " + (dir / "no_python").string() +
                         ": expected an executable Python interpreter, got no such file");
  ExpectNamesTheFlag({"optimize", "--g2o", (dir / "g.g2o").string(), "--out",
                      (dir / "o.g2o").string(), "--loss-scale", "-1"},
                     "--loss-scale must be in [1e-6, 1e6] sigmas, got -1");
  // 1e-308 (anything <= 1e-160: Ceres squares it) "converged" with cost -nan, exit 0.
  ExpectNamesTheFlag({"optimize", "--g2o", (dir / "g.g2o").string(), "--out",
                      (dir / "o.g2o").string(), "--robust", "cauchy", "--loss-scale", "1e-308"},
                     "--loss-scale must be in [1e-6, 1e6] sigmas, got 1e-308");
  ExpectNamesTheFlag({"eval", "--gt", gt, "--est", gt, "--max-dt", "-1"},
                     "--max-dt must be >= 0 s, got -1");
  ExpectNamesTheFlag({"eval", "--gt", gt, "--est", gt, "--rpe-delta", "-3"},
                     "--rpe-delta must be > 0, got -3");
  // 1e20 (and 1.9e19) frames overflowed size_t and hung; 2^64 was "failed: std::bad_alloc".
  for (const char* huge : {"1e20", "1.9e19", "18446744073709551616"}) {
    ExpectNamesTheFlag({"eval", "--gt", gt, "--est", gt, "--rpe-delta", huge},
                       "--rpe-delta in frames must be an integer from 1 to 1e+09, got ");
  }
  ExpectNamesTheFlag({"eval", "--gt", gt, "--est", gt, "--derive-loops", "5,10", "--view-angle",
                      "-3", "--loops", (dir / "loops.csv").string()},
                     "--view-angle must be in (0, 180], got -3");
  ExpectNamesTheFlag({"render", "--world", "aerial", "--altitude", "-4", "--out", out},
                     "--altitude must be in (1, 10000] metres, got -4");
  ExpectNamesTheFlag({"render", "--world", "aerial", "--noise", "-4", "--out", out},
                     "--noise must be >= 0, got -4");
  ExpectNamesTheFlag({"report", dir.string(), "--false-loop-distance", "-1"},
                     "--false-loop-distance must be > 0, got -1");
}

}  // namespace
}  // namespace sparseloop::test
