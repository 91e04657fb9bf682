// Output paths (docs/ROBUSTNESS.md, bad-input table): every output is a regular file, checked
// before any work; a symlink is written through to its target; a FIFO, a directory or a device
// given as an output is refused (exit 2) naming the flag and the path, and left untouched.
#include <sys/stat.h>

#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

namespace fs = std::filesystem;

void WritePositions(const fs::path& path) {
  std::ofstream out(path);
  const double xs[] = {0, 10, 20, 30, 40, 50, 0.5, 20.2};
  for (int i = 0; i < 8; ++i) out << i << " " << xs[i] << " 0 0\n";
}

CliResult Eval(const fs::path& gt, const fs::path& json) {
  return RunCli({"eval", "--gt", gt.string(), "--est", gt.string(), "--align", "none", "--json",
                 json.string()});
}

void ExpectRefused(const CliResult& r, const std::string& flag, const fs::path& path,
                   const std::string& kind) {
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(flag + " " + path.string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(kind), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(".cc:"), std::string::npos) << r.err;  // no source path
}

TEST(CliOutputs, EvalJsonFifoAndDirectoryAreRefusedAndKept) {
  const auto dir = TempDir();
  WritePositions(dir / "gt.txt");
  const auto fifo = dir / "metrics.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  ExpectRefused(Eval(dir / "gt.txt", fifo), "--json", fifo, "FIFO");
  EXPECT_TRUE(fs::is_fifo(fifo));
  fs::create_directories(dir / "sub");
  ExpectRefused(Eval(dir / "gt.txt", dir / "sub"), "--json", dir / "sub", "directory");
  EXPECT_TRUE(fs::is_directory(dir / "sub"));
  // Checked before the inputs are even read: a missing --gt is not what is reported.
  ExpectRefused(Eval(dir / "missing.txt", fifo), "--json", fifo, "FIFO");
  // A file in a missing folder.
  const CliResult r = Eval(dir / "gt.txt", dir / "no_dir" / "m.json");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--json"), std::string::npos) << r.err;
}

TEST(CliOutputs, EvalJsonThroughASymlinkWritesTheTarget) {
  const auto dir = TempDir();
  WritePositions(dir / "gt.txt");
  fs::create_directories(dir / "results");
  fs::create_symlink("results/metrics.json", dir / "latest.json");
  const CliResult r = Eval(dir / "gt.txt", dir / "latest.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_symlink(dir / "latest.json"));
  std::ifstream in(dir / "results" / "metrics.json");
  ASSERT_TRUE(in.good());
  EXPECT_DOUBLE_EQ(nlohmann::json::parse(in)["ate_rmse_m"].get<double>(), 0.0);
}

TEST(CliOutputs, ConvertAndOptimizeOutFifoRefused) {
  const auto dir = TempDir();
  WritePositions(dir / "gt.txt");
  const auto fifo = dir / "out.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  ExpectRefused(RunCli({"convert", "--in", (dir / "gt.txt").string(), "--to", "kitti", "--out",
                        fifo.string()}),
                "--out", fifo, "FIFO");
  ExpectRefused(
      RunCli({"optimize", "--g2o", (dir / "missing.g2o").string(), "--out", fifo.string()}),
      "--out", fifo, "FIFO");
  EXPECT_TRUE(fs::is_fifo(fifo));
}

// `detect` / `run` check --out before a single frame is processed: the dataset here has an
// unreadable image that processing would report first.
TEST(CliOutputs, DetectAndRunCheckOutBeforeProcessingFrames) {
  const auto dir = TempDir();
  fs::create_directories(dir / "images");
  std::ofstream(dir / "images" / "0.pgm") << "not an image";
  WritePositions(dir / "raw.txt");
  std::ofstream(dir / "plain_file") << "x";
  const std::string dataset = "images:" + (dir / "images").string();
  const auto not_a_dir = dir / "plain_file";
  for (const char* command : {"detect", "run"}) {
    SCOPED_TRACE(command);
    const CliResult r =
        RunCli({command, "--dataset", dataset, "--intrinsics", "50,50,32,24", "--poses",
                (dir / "raw.txt").string(), "--out", not_a_dir.string()});
    ExpectRefused(r, "--out", not_a_dir, "not a directory");
  }
  // A FIFO where an output file of the folder goes.
  fs::create_directories(dir / "out");
  ASSERT_EQ(::mkfifo((dir / "out" / "summary.json").c_str(), 0600), 0);
  const CliResult r = RunCli({"detect", "--dataset", dataset, "--intrinsics", "50,50,32,24",
                              "--out", (dir / "out").string()});
  ExpectRefused(r, "--out", dir / "out" / "summary.json", "FIFO");
}

}  // namespace
}  // namespace sparseloop::test
