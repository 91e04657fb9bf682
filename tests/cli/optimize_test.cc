// End-to-end tests of `sparseloop optimize`.
#include <fstream>

#include <gtest/gtest.h>

#include "cli/cli_runner.h"
#include "sparseloop/posegraph/g2o.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

// A square of four SE2 poses with a loop edge; the initial guess is perturbed.
constexpr const char* kSquare =
    "VERTEX_SE2 0 0 0 0\n"
    "VERTEX_SE2 1 1.2 0.1 1.4\n"
    "VERTEX_SE2 2 1.1 1.3 3.0\n"
    "VERTEX_SE2 3 -0.2 0.9 -1.5\n"
    "EDGE_SE2 0 1 1 0 1.5707963267948966 100 0 0 100 0 100\n"
    "EDGE_SE2 1 2 1 0 1.5707963267948966 100 0 0 100 0 100\n"
    "EDGE_SE2 2 3 1 0 1.5707963267948966 100 0 0 100 0 100\n"
    "EDGE_SE2 3 0 1 0 1.5707963267948966 100 0 0 100 0 100\n";

TEST(CliOptimize, SquareConvergesToKnownAnswer) {
  const auto dir = TempDir();
  std::ofstream(dir / "square.g2o") << kSquare;
  const CliResult r = RunCli(
      {"optimize", "--g2o", (dir / "square.g2o").string(), "--out", (dir / "out.g2o").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("Termination:          converged"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("initial"), std::string::npos);
  const PoseGraph g = ReadG2o(dir / "out.g2o");
  ASSERT_EQ(g.num_vertices(), 4u);
  // Consistent measurements: the unit square exactly.
  EXPECT_LT((g.Pose(1).translation - Eigen::Vector3d(1, 0, 0)).norm(), 1e-6);
  EXPECT_LT((g.Pose(2).translation - Eigen::Vector3d(1, 1, 0)).norm(), 1e-6);
  EXPECT_LT((g.Pose(3).translation - Eigen::Vector3d(0, 1, 0)).norm(), 1e-6);
  // No temporary file left behind.
  size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 2u);
}

// A large graph takes tens of seconds: progress goes to stderr (never stdout), --quiet silences it.
TEST(CliOptimize, ProgressOnStderrQuietWithQuiet) {
  const auto dir = TempDir();
  std::ofstream(dir / "square.g2o") << kSquare;
  const std::vector<std::string> args = {"optimize", "--g2o", (dir / "square.g2o").string(),
                                         "--out", (dir / "out.g2o").string()};
  const CliResult r = RunCli(args);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("4 vertices, 4 edges read"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("solving"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("iter   0 cost"), std::string::npos) << r.err;  // one line per iteration
  EXPECT_EQ(r.out.find("iter   0"), std::string::npos) << r.out;
  std::vector<std::string> quiet = args;
  quiet.push_back("--quiet");
  const CliResult q = RunCli(quiet);
  ASSERT_EQ(q.exit_code, 0) << q.err;
  EXPECT_EQ(q.err, "");
  EXPECT_NE(q.out.find("Termination:          converged"), std::string::npos) << q.out;
}

TEST(CliOptimize, BadInputExitsTwoWithLine) {
  const auto dir = TempDir();
  std::ofstream(dir / "bad.g2o") << "VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0\n";
  const CliResult r = RunCli(
      {"optimize", "--g2o", (dir / "bad.g2o").string(), "--out", (dir / "out.g2o").string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("bad.g2o:2"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.g2o"));
  const CliResult robust = RunCli({"optimize", "--g2o", (dir / "bad.g2o").string(), "--out",
                                   (dir / "out.g2o").string(), "--robust", "tukey"});
  EXPECT_EQ(robust.exit_code, 2);
  EXPECT_NE(robust.err.find("--robust must be trivial (or none), huber or cauchy"),
            std::string::npos)
      << robust.err;
}

// A solve without a finite cost (here an information of 1e300: the cost overflows) is a failure:
// exit 1 saying so, and --out is not written (a NaN cost was reported as converged, exit 0).
TEST(CliOptimize, ASolveWithoutAFiniteCostExits1AndWritesNothing) {
  const auto dir = TempDir();
  std::ofstream(dir / "huge.g2o") << "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1e10 0 0\n"
                                     "EDGE_SE2 0 1 1 0 0 1e300 0 0 1e300 0 1e300\n";
  const CliResult r = RunCli(
      {"optimize", "--g2o", (dir / "huge.g2o").string(), "--out", (dir / "out.g2o").string()});
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.err.find("optimize: the solve failed"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("not written"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.g2o"));
}

TEST(CliOptimize, ParkingGarage) {
  SL_REQUIRE_DATA("pose_graphs/parking-garage.g2o");
  const auto dir = TempDir();
  const CliResult r =
      RunCli({"optimize", "--g2o", (DataDir() / "pose_graphs/parking-garage.g2o").string(), "--out",
              (dir / "out.g2o").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("converged"), std::string::npos) << r.out;
  EXPECT_EQ(ReadG2o(dir / "out.g2o").num_vertices(), 1661u);
}

}  // namespace
}  // namespace sparseloop::test
