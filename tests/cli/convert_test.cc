// End-to-end tests of `sparseloop convert`.
#include <sys/stat.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "cli/cli_runner.h"
#include "sparseloop/io/trajectory_io.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

void Write(const std::filesystem::path& path, const std::string& content) {
  std::ofstream(path) << content;
}

// RunCli() recreates TempDir() on every call, so input/output files live in a sibling folder.
std::filesystem::path FilesDir() {
  const auto dir = std::filesystem::path(TempDir().string() + ".files");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

TEST(CliConvert, TumToKittiAndBack) {
  const auto dir = FilesDir();
  Write(dir / "in.txt",
        "# t x y z qx qy qz qw\n0.5 1 2 3 0 0 0 1\n0.6 4 5 6 0 0 0.7071067811865476 "
        "0.7071067811865476\n");
  const CliResult r = RunCli({"convert", "--in", (dir / "in.txt").string(), "--out",
                              (dir / "out.txt").string(), "--to", "kitti"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("wrote 2 poses (tum -> kitti)"), std::string::npos) << r.out;
  EXPECT_EQ(DetectTrajectoryFormat(dir / "out.txt"), TrajectoryFormat::kKitti);
  const Trajectory k = ReadTrajectory(dir / "out.txt");
  ASSERT_EQ(k.size(), 2u);
  EXPECT_EQ(k.poses[1].world_from_cam.translation, Eigen::Vector3d(4, 5, 6));
  // 90 degrees about z: x -> y.
  EXPECT_TRUE((k.poses[1].world_from_cam.rotation * Eigen::Vector3d::UnitX())
                  .isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  const CliResult e = RunCli({"convert", "--in", (dir / "in.txt").string(), "--out",
                              (dir / "out.csv").string(), "--to", "euroc"});
  ASSERT_EQ(e.exit_code, 0) << e.err;
  const Trajectory back = ReadTrajectory(dir / "out.csv");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_NEAR(back.poses[1].timestamp, 0.6, 1e-9);
}

TEST(CliConvert, MalformedInputExits2WithFileAndLine) {
  const auto dir = FilesDir();
  Write(dir / "bad.txt", "0.5 1 2 3 0 0 0 1\n0.6 1 2 3 0 0 0 1.5\n");
  const CliResult r = RunCli({"convert", "--in", (dir / "bad.txt").string(), "--out",
                              (dir / "out.txt").string(), "--to", "kitti"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find((dir / "bad.txt").string() + ":2:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("unit quaternion"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.txt"));
}

TEST(CliConvert, BadFormatNameAndPositionsToTumExit2) {
  const auto dir = FilesDir();
  Write(dir / "pos.txt", "0 1 2 3\n1 2 3 4\n");
  CliResult r = RunCli({"convert", "--in", (dir / "pos.txt").string(), "--out",
                        (dir / "o.txt").string(), "--to", "g2o"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown trajectory format 'g2o'"), std::string::npos) << r.err;
  r = RunCli({"convert", "--in", (dir / "pos.txt").string(), "--out", (dir / "o.txt").string(),
              "--to", "tum"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("positions-only"), std::string::npos) << r.err;
  r = RunCli({"convert", "--in", (dir / "pos.txt").string(), "--out", (dir / "o.txt").string(),
              "--to", "positions"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(ReadTrajectory(dir / "o.txt").poses[1].world_from_cam.translation,
            Eigen::Vector3d(2, 3, 4));
}

// A shell command line; its exit code (124: `timeout` stopped a command that hung).
int Shell(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// --in a pipe: the input is read once (format detection and reading share it), so a FIFO and
// /dev/stdin give the poses; both were read twice (a FIFO hung on the second open, /dev/stdin
// gave "at least one data line, got none").
TEST(CliConvert, AFifoOrStdinIsReadOnce) {
  const auto dir = FilesDir();
  Write(dir / "in.txt", "0.5 1 2 3 0 0 0 1\n0.6 4 5 6 0 0 0 1\n");
  const std::string cli = "timeout 60 '" + ConfiguredCliPath().string() + "'";
  const std::string out = (dir / "out.txt").string();
  EXPECT_EQ(Shell("cat '" + (dir / "in.txt").string() + "' | " + cli +
                  " convert --in /dev/stdin --to kitti --out '" + out + "' >/dev/null 2>&1"),
            0);
  ASSERT_TRUE(std::filesystem::exists(out));
  EXPECT_EQ(ReadTrajectory(out).size(), 2u);
  std::filesystem::remove(out);
  const std::string fifo = (dir / "fifo").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // The writer in the background: it blocks until convert opens the FIFO.
  EXPECT_EQ(Shell("(cat '" + (dir / "in.txt").string() + "' > '" + fifo + "' &) ; " + cli +
                  " convert --in '" + fifo + "' --to kitti --out '" + out + "' >/dev/null 2>&1"),
            0);
  ASSERT_TRUE(std::filesystem::exists(out));
  EXPECT_EQ(ReadTrajectory(out).size(), 2u);
}

TEST(CliConvert, MissingInputExits2) {
  const auto dir = FilesDir();
  const CliResult r = RunCli({"convert", "--in", (dir / "none.txt").string(), "--out",
                              (dir / "o.txt").string(), "--to", "tum"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("none.txt"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace sparseloop::test
