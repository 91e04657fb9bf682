// What a new user hit (docs/ROBUSTNESS.md, bad-input table): no command writes over
// one of its inputs, output paths are resolved and checked before any work, text files as editors
// write them, numbers at the edges and library text never reaching the user. Each case exits 2
// naming the flag, the file (and line) the user gave, or gives the right result.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

namespace fs = std::filesystem;

// `text` as the file at `path`, its folder created (Write of convert_test.cc does not create it).
void WriteCreatingFolder(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

// A TUM trajectory on a 10 m square with a slow turn, `scale` times the GT's size.
std::string Tum(double scale, int n = 40) {
  std::string text;
  for (int i = 0; i < n; ++i) {
    const double a = 0.05 * i;
    text +=
        fmt::format("{} {} {} {} 0 0 {} {}\n", i * 0.1, scale * 10 * std::cos(a),
                    scale * 10 * std::sin(a), scale * 0.1 * i, std::sin(a / 2), std::cos(a / 2));
  }
  return text;
}

void ExpectExit2Naming(const CliResult& r, const std::vector<std::string>& parts) {
  EXPECT_EQ(r.exit_code, 2) << r.err;
  for (const auto& p : parts) EXPECT_NE(r.err.find(p), std::string::npos) << p << "\n" << r.err;
  EXPECT_EQ(r.err.find(".cc:"), std::string::npos) << r.err;  // no source path
  EXPECT_EQ(r.err.find("filesystem error"), std::string::npos) << r.err;
}

// `eval --json g.txt` with --gt g.txt replaced the GT with JSON; `run --gt DIR/trajectory.txt
// --out DIR` replaced it with the corrected trajectory. Every command compares each output with
// each input, links and `..` resolved, before reading anything.
TEST(CliInputsKept, AnOutputThatIsAnInputIsRefusedInEveryCommand) {
  const auto dir = TempDir();
  WriteCreatingFolder(dir / "g.txt", Tum(1.0));
  const std::string gt = (dir / "g.txt").string();
  const std::string before = ReadText(gt);
  fs::create_symlink(gt, dir / "link.json");
  for (const std::string json : {gt, (dir / "link.json").string(), (dir / "x/../g.txt").string()}) {
    ExpectExit2Naming(RunCli({"eval", "--gt", gt, "--est", gt, "--json", json}),
                      {"--json " + json, "--gt " + gt});
  }
  // run / detect: a file of --out DIR that an input names (the check comes before the dataset is
  // even opened).
  const std::string out = dir.string();
  ExpectExit2Naming(RunCli({"run", "--dataset", "images:" + (dir / "none").string(), "--poses", gt,
                            "--gt", (dir / "trajectory.txt").string(), "--out", out}),
                    {"--out " + (dir / "trajectory.txt").string(), "--gt"});
  WriteCreatingFolder(dir / "trajectory.txt", "gt kept\n");
  ExpectExit2Naming(RunCli({"run", "--dataset", "images:" + (dir / "none").string(), "--poses",
                            (dir / "poses_raw.txt").string(), "--out", out}),
                    {"--out", "poses_raw.txt", "--poses"});
  ExpectExit2Naming(RunCli({"detect", "--dataset", "images:" + (dir / "none").string(), "--map",
                            (dir / "loops.csv").string(), "--out", out}),
                    {"--out", "loops.csv", "--map"});
  ExpectExit2Naming(RunCli({"convert", "--in", gt, "--out", gt, "--to", "kitti"}),
                    {"--out " + gt, "--in " + gt});
  WriteCreatingFolder(dir / "g.g2o", "VERTEX_SE2 0 0 0 0\n");
  ExpectExit2Naming(
      RunCli({"optimize", "--g2o", (dir / "g.g2o").string(), "--out", (dir / "g.g2o").string()}),
      {"--out", "--g2o"});
  ExpectExit2Naming(RunCli({"render", "--world", "street", "--trajectory",
                            (dir / "poses_gt.txt").string(), "--out", out}),
                    {"--out", "poses_gt.txt", "--trajectory"});
  // A texture folder that is --out or one of the folders render writes frames into.
  WriteCreatingFolder(dir / "image_0" / "000000.png", "texture\n");
  for (const fs::path& textures : {dir, dir / "image_0", dir / "image_0" / "."}) {
    ExpectExit2Naming(RunCli({"render", "--world", "aerial", "--frames", "2", "--textures",
                              textures.string(), "--out", out}),
                      {"--out", "--textures"});
  }
  EXPECT_EQ(ReadText(dir / "image_0" / "000000.png"), "texture\n");
  EXPECT_EQ(ReadText(gt), before);
  EXPECT_EQ(ReadText(dir / "trajectory.txt"), "gt kept\n");
}

// `--out DIR/missing/..` is DIR: it bypassed the guard against a folder of other files and
// replaced the user's trajectory.txt. The folder checked is the folder written.
TEST(CliInputsKept, OutThroughAMissingFolderAndDotDotIsGuardedAsTheFolderItNames) {
  const fs::path& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty());
  const auto dir = TempDir();
  WriteCreatingFolder(dir / "notes.txt", "mine\n");
  WriteCreatingFolder(dir / "trajectory.txt", "mine too\n");
  const std::string out = (dir / "missing" / "..").string();
  const CliResult r = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                              (seq / "poses_raw.txt").string(), "--out", out, "--quiet"});
  ExpectExit2Naming(r, {"--out " + out, "expected an empty folder"});
  EXPECT_EQ(ReadText(dir / "trajectory.txt"), "mine too\n");
  EXPECT_FALSE(fs::exists(dir / "missing"));
}

// A 4,400-character --out passed the up-front check, every frame was processed, then "File name
// too long" (exit 1). Now: exit 2 before any input is read.
TEST(CliOutputs, AnOverlongOutIsRefusedBeforeAnyWork) {
  const auto dir = TempDir();
  fs::path deep = dir;
  for (int i = 0; i < 22; ++i) deep /= std::string(200, 'd');
  for (const char* command : {"run", "detect"}) {
    ExpectExit2Naming(RunCli({command, "--dataset", "images:" + (dir / "none").string(), "--poses",
                              (dir / "none.txt").string(), "--out", deep.string()}),
                      {"--out", "characters"});
  }
  ExpectExit2Naming(
      RunCli({"eval", "--gt", "g", "--est", "g", "--json", (dir / std::string(300, 'j')).string()}),
      {"--json", "characters"});
}

// --config: a key given twice is an error with its line (JSON allows it; the last value silently
// won); a folder says so (it read as a JSON syntax error); a value that fails its check inside the
// file names the key by its whole path (four keys end in rotation_sigma_rad).
TEST(CliConfig, DuplicateKeysFoldersAndBadValuesNameTheFileLineAndKeyPath) {
  const auto dir = TempDir();
  const std::string images = "images:" + (dir / "none").string();
  const auto run = [&](const fs::path& config) {
    return RunCli({"run", "--dataset", images, "--poses", (dir / "p.txt").string(), "--config",
                   config.string(), "--out", (dir / "out").string()});
  };
  WriteCreatingFolder(
      dir / "dup.json",
      "{\n  \"detector\": {\n    \"check_every\": 1,\n    \"check_every\": 2\n  }\n}\n");
  ExpectExit2Naming(run(dir / "dup.json"), {(dir / "dup.json").string() + ":4:",
                                            "\"detector.check_every\" a second time"});
  fs::create_directories(dir / "cfg_dir");
  ExpectExit2Naming(run(dir / "cfg_dir"), {(dir / "cfg_dir").string(), "got a directory"});
  WriteCreatingFolder(dir / "bad.json",
                      "{\"odometry\": {\"rotation_sigma_rad\": 0.01},\n"
                      " \"direction_loop\": {\"rotation_sigma_rad\": -1}}\n");
  ExpectExit2Naming(run(dir / "bad.json"),
                    {(dir / "bad.json").string(), "\"direction_loop.rotation_sigma_rad\""});
  // The same keys in separate objects are not duplicates; a BOM is accepted.
  WriteCreatingFolder(dir / "ok.json",
                      "\xEF\xBB\xBF{\"odometry\": {\"rotation_sigma_rad\": 0.01},"
                      " \"direction_loop\": {\"rotation_sigma_rad\": 0.02}}\n");
  const CliResult ok = run(dir / "ok.json");
  EXPECT_EQ(ok.err.find("ok.json"), std::string::npos) << ok.err;  // fails later, on the dataset
}

// --intrinsics 1e308 and poses scaled by 1e200 ended in "packed keyframe 0: ..."; now the flag and
// the file's line are named before any frame.
TEST(CliMessages, HugeIntrinsicsAndPosesNameTheFlagOrTheLine) {
  const auto dir = TempDir();
  WriteCreatingFolder(dir / "p.txt", "0 0 0 0 0 0 0 1\n1 1e200 0 0 0 0 0 1\n");
  WriteCreatingFolder(dir / "images" / "0.png", "");
  ExpectExit2Naming(RunCli({"run", "--dataset", "images:" + (dir / "images").string(), "--poses",
                            (dir / "p.txt").string(), "--intrinsics", "1e308,1e308,16,16", "--out",
                            (dir / "out").string()}),
                    {"--intrinsics: fx must be at most"});
  ExpectExit2Naming(
      RunCli({"eval", "--gt", (dir / "p.txt").string(), "--est", (dir / "p.txt").string()}),
      {(dir / "p.txt").string() + ":2: expected a coordinate within"});
}

// eval with the estimate = GT x 1e12 (a monocular estimate's unit is arbitrary): an exact Sim(3)
// alignment (it printed "degenerate" and an ATE of 2e31 m at x 1e30, inf / nan at x 1e200).
TEST(CliEval, AnEstimateAtAnyScaleAlignsExactly) {
  const auto dir = TempDir();
  WriteCreatingFolder(dir / "gt.txt", Tum(1.0));
  for (const double scale : {1e-9, 1e12}) {
    SCOPED_TRACE(scale);
    WriteCreatingFolder(dir / "est.txt", Tum(scale));
    const CliResult r = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--est",
                                (dir / "est.txt").string(), "--json", (dir / "m.json").string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = ReadJson(dir / "m.json");
    EXPECT_EQ(j["alignment"]["status"], "ok") << j.dump(2);
    EXPECT_NEAR(j["alignment"]["scale"].get<double>() * scale, 1.0, 1e-6) << j.dump(2);
    EXPECT_LT(j["ate"]["rmse"].get<double>(), 1e-6) << j.dump(2);
  }
}

// Text files as people write them: a UTF-8 BOM and CR-only line endings (the BOM made line 1 "not
// a number", CR-only made the file one line: `eval --gt f --est f` said "1 poses", ATE 0).
TEST(CliEval, ByteOrderMarkAndCrOnlyFilesReadEveryPose) {
  const auto dir = TempDir();
  std::string cr = Tum(1.0);
  for (char& c : cr)
    if (c == '\n') c = '\r';
  WriteCreatingFolder(dir / "cr.txt", "\xEF\xBB\xBF" + cr);
  const CliResult r =
      RunCli({"eval", "--gt", (dir / "cr.txt").string(), "--est", (dir / "cr.txt").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("(40 poses"), std::string::npos) << r.out;
}

// Paths that are not what the user thought: a loop of links named as an image, `images:FILE`, a
// device as --map. Each names the path and what it is, never a library's words.
TEST(CliMessages, LinkLoopsFilesAndDevicesSayWhatThePathIs) {
  const auto dir = TempDir();
  fs::create_directories(dir / "images");
  fs::create_symlink(dir / "images" / "0.png", dir / "images" / "0.png");  // points at itself
  const auto images = [&](const std::string& spec, const std::vector<std::string>& extra = {}) {
    std::vector<std::string> args = {
        "detect", "--dataset",           spec, "--intrinsics", "100,100,16,16",
        "--out",  (dir / "out").string()};
    args.insert(args.end(), extra.begin(), extra.end());
    return RunCli(args);
  };
  ExpectExit2Naming(images("images:" + (dir / "images").string()),
                    {(dir / "images" / "0.png").string(), "symbolic links"});
  WriteCreatingFolder(dir / "file.txt", "x");
  ExpectExit2Naming(images("images:" + (dir / "file.txt").string()),
                    {(dir / "file.txt").string(), "got a regular file"});
  fs::create_symlink(dir / "loop", dir / "loop");  // a folder link that points at itself
  ExpectExit2Naming(images("images:" + (dir / "loop").string()),
                    {(dir / "loop").string(), "symbolic links"});
  fs::remove(dir / "images" / "0.png");
  WriteCreatingFolder(dir / "images" / "0.png", "");
  ExpectExit2Naming(images("images:" + (dir / "images").string(), {"--map", "/dev/null"}),
                    {"/dev/null: expected a map database file", "a device"});
}

// Options whose value let a library print: Ceres threads are bounded (100000 let glog print
// "Logging before InitGoogleLogging()"). The search grid's cell, whose 1 mm on a 10 m scene ran
// past 30 s per keyframe, is no configuration key; its clamp is checked against brute force in
// SearchAreaOracle.IdenticalToBruteForceOnRandomTrajectories (a cell of 1e-300 among its trials).
TEST(CliMessages, OptionsThatWouldHangOrLetALibraryPrintAreBounded) {
  const fs::path& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty());
  const auto dir = TempDir();
  const CliResult r = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                              (seq / "poses_raw.txt").string(), "--set",
                              "optimizer.num_threads=100000", "--out", (dir / "o1").string()});
  ExpectExit2Naming(r, {"--set optimizer.num_threads=100000", "[1, 256]"});
  EXPECT_EQ(r.err.find("InitGoogleLogging"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace sparseloop::test
