// A run folder holds one run (docs/ROBUSTNESS.md, bad-input table): a rerun of `run` / `detect`
// into an old --out removes the previous run's files first (and says so), a foreign non-empty
// folder or the dataset's own folder is refused, `run` logs the GT file it evaluates, and a
// positions-only --poses / --gt fails before any frame.
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

namespace fs = std::filesystem;

// The rendered sequence without its ground truth: images, times and calibration only.
fs::path SequenceWithoutGt(const fs::path& dir) {
  const fs::path& seq = RenderedLoopSequence();
  const fs::path copy = dir / "nogt";
  fs::create_directories(copy);
  fs::create_directory_symlink(seq / "image_0", copy / "image_0");
  fs::copy_file(seq / "times.txt", copy / "times.txt");
  fs::copy_file(seq / "calib.txt", copy / "calib.txt");
  return copy;
}

TEST(CliRunFolder, RerunRemovesThePreviousRunsFilesAndSaysSo) {
  const fs::path& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty()) << "render failed";
  const auto dir = TempDir();
  const fs::path out = dir / "out";
  const std::string raw = (seq / "poses_raw.txt").string();
  CliResult r =
      RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses", raw, "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* f : {"poses_gt.txt", "gt_loops.txt", "pr_curve.csv"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  std::ofstream(out / "report.html") << "<html>old run</html>";

  // Same folder, a dataset without GT: nothing of the GT run may stay for `report` to mix in.
  const fs::path nogt = SequenceWithoutGt(dir);
  r = RunCli({"run", "--dataset", "kitti:" + nogt.string(), "--poses", raw, "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* f : {"poses_gt.txt", "gt_loops.txt", "pr_curve.csv", "report.html"})
    EXPECT_FALSE(fs::exists(out / f)) << f << " left over from the previous run";
  EXPECT_TRUE(fs::exists(out / "trajectory.txt"));
  EXPECT_NE(r.err.find("removed"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("poses_gt.txt"), std::string::npos) << r.err;
  EXPECT_FALSE(ReadJson(out / "summary.json").contains("loops_correct"));

  // `detect` into a `run` folder: not its own output, refused, and the folder is untouched.
  r = RunCli(
      {"detect", "--dataset", "kitti:" + nogt.string(), "--poses", raw, "--out", out.string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--out " + out.string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("sparseloop detect"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(out / "trajectory.txt"));
}

TEST(CliRunFolder, ForeignFolderAndTheDatasetFolderAreRefused) {
  const fs::path& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty()) << "render failed";
  const auto dir = TempDir();
  const std::string raw = (seq / "poses_raw.txt").string();
  fs::create_directories(dir / "mine");
  std::ofstream(dir / "mine" / "notes.txt") << "keep me";
  for (const char* command : {"run", "detect"}) {
    SCOPED_TRACE(command);
    const CliResult r = RunCli({command, "--dataset", "kitti:" + seq.string(), "--poses", raw,
                                "--out", (dir / "mine").string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("notes.txt"), std::string::npos) << r.err;
    EXPECT_TRUE(fs::exists(dir / "mine" / "notes.txt"));
    EXPECT_FALSE(fs::exists(dir / "mine" / "loops.csv"));
  }
  // An input the user keeps in the folder (scripts/benchmark writes its --config there) is not
  // foreign, and stays.
  fs::create_directories(dir / "with_config");
  std::ofstream(dir / "with_config" / "config.json") << R"({"detector": {"check_every": 1}})";
  const CliResult with_config = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses", raw,
                                        "--config", (dir / "with_config" / "config.json").string(),
                                        "--out", (dir / "with_config").string()});
  EXPECT_EQ(with_config.exit_code, 0) << with_config.err;
  EXPECT_TRUE(fs::exists(dir / "with_config" / "config.json"));
  // --out = the dataset folder (here a copy without GT: the run would add GT-looking files).
  const fs::path nogt = SequenceWithoutGt(dir);
  const CliResult r = RunCli(
      {"run", "--dataset", "kitti:" + nogt.string() + "/", "--poses", raw, "--out", nogt.string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("the dataset's"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(nogt / "trajectory_kitti.txt"));
}

TEST(CliRunFolder, RunLogsTheGtFileItEvaluates) {
  const fs::path& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty()) << "render failed";
  const auto dir = TempDir();
  const fs::path gt = seq / "poses_gt.txt";  // the dataset's own GT is poses.txt
  const CliResult r = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                              (seq / "poses_raw.txt").string(), "--gt", gt.string(), "--out",
                              (dir / "out").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("evaluating against --gt " + gt.string()), std::string::npos) << r.err;
  EXPECT_EQ(ReadJson(dir / "out" / "summary.json")["gt_file"].get<std::string>(), gt.string());
}

TEST(CliRunFolder, PositionsOnlyPosesOrGtFailAtTheStart) {
  const fs::path& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty()) << "render failed";
  const auto dir = TempDir();
  {
    std::ofstream positions(dir / "positions.txt");
    for (int i = 0; i < 60; ++i) positions << i << " " << i << " 0 0\n";
  }
  const std::string positions = (dir / "positions.txt").string();
  for (const char* flag : {"--poses", "--gt"}) {
    SCOPED_TRACE(flag);
    const std::string poses =
        std::string(flag) == "--poses" ? positions : (seq / "poses_raw.txt").string();
    std::vector<std::string> args = {"run", "--dataset", "kitti:" + seq.string(), "--poses",
                                     poses, "--out",     (dir / "out").string()};
    if (std::string(flag) == "--gt") args.insert(args.end(), {"--gt", positions});
    const CliResult r = RunCli(args);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find(std::string(flag) + " " + positions +
                         ": expected a trajectory with orientations"),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(dir / "out" / "loops.csv"));  // failed before the run
  }
}

}  // namespace
}  // namespace sparseloop::test
