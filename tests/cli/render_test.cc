// End-to-end tests of `sparseloop render` and `sparseloop report`.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "cli/report_script.h"
#include "sparseloop/io/dataset.h"
#include "sparseloop/io/trajectory_io.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

namespace fs = std::filesystem;

// RunCli() recreates TempDir() on every call, so outputs that must survive several runs live in a
// sibling folder "<test>_<name>".
fs::path OutDir(const std::string& name) {
  const fs::path test_dir = TempDir();
  const fs::path dir = test_dir.parent_path() / (test_dir.filename().string() + "_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// `render ARGS --out OutDir(a)` and `render ARGS EXTRA --out OutDir(b)`, both expected to succeed
// (a comparison of two renders that differ only in EXTRA); returns the two folders.
std::pair<fs::path, fs::path> RenderTwo(const std::string& a, const std::string& b,
                                        const std::vector<std::string>& args,
                                        const std::vector<std::string>& extra) {
  const std::pair<fs::path, fs::path> dirs{OutDir(a), OutDir(b)};
  for (const fs::path* out : {&dirs.first, &dirs.second}) {
    std::vector<std::string> all = {"render"};
    all.insert(all.end(), args.begin(), args.end());
    if (out == &dirs.second) all.insert(all.end(), extra.begin(), extra.end());
    all.insert(all.end(), {"--out", out->string()});
    const CliResult r = RunCli(all);
    EXPECT_EQ(r.exit_code, 0) << r.err;
  }
  return dirs;
}

std::vector<std::string> ReadLines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

TEST(RenderCli, AerialSequenceIsAKittiFolder) {
  const auto out = TempDir() / "aerial";
  const CliResult r = RunCli({"render", "--world", "aerial", "--plan", "figure8", "--frames", "6",
                              "--seed", "3", "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("wrote 6 frames (640x480)"), std::string::npos) << r.out;
  const Dataset d = OpenDataset("kitti:" + out.string());
  EXPECT_EQ(d.frames.size(), 6u);
  EXPECT_TRUE(d.has_gt());
  EXPECT_EQ(ReadTrajectory(out / "poses_raw.txt").size(), 6u);
  EXPECT_TRUE(fs::exists(out / "mapped" / "000005.txt"));
}

TEST(RenderCli, SameSeedSameBytes) {
  const auto a = OutDir("a");
  const auto b = OutDir("b");
  for (const auto& out : {a, b}) {
    const CliResult r = RunCli({"render", "--world", "aerial", "--frames", "3", "--seed", "9",
                                "--threads", out == a ? "1" : "2", "--out", out.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  for (const char* f : {"image_0/000002.png", "poses_raw.txt", "mapped/000001.txt"}) {
    std::ifstream fa(a / f, std::ios::binary), fb(b / f, std::ios::binary);
    const std::string sa((std::istreambuf_iterator<char>(fa)), {});
    const std::string sb((std::istreambuf_iterator<char>(fb)), {});
    EXPECT_FALSE(sa.empty());
    EXPECT_TRUE(sa == sb) << f << " differs between runs";
  }
}

// --poses-only writes the same raw trajectory as a full render (same seed), --drift scales it:
// 0 gives raw == GT, larger values drift further from GT.
TEST(RenderCli, PosesOnlyMatchesFullRenderAndDriftScales) {
  const auto full = OutDir("full");
  ASSERT_EQ(RunCli({"render", "--world", "aerial", "--frames", "40", "--seed", "5", "--no-mapped",
                    "--out", full.string()})
                .exit_code,
            0);
  auto end_error = [](const fs::path& dir) {
    const Trajectory gt = ReadTrajectory(dir / "poses_gt.txt");
    const Trajectory raw = ReadTrajectory(dir / "poses_raw.txt");
    return (gt.poses.back().world_from_cam.translation -
            raw.poses.back().world_from_cam.translation)
        .norm();
  };
  std::vector<double> errors;
  std::vector<std::string> drift1_scale;
  for (const char* drift : {"1", "0", "3"}) {
    const auto out = OutDir(std::string("drift") + drift);
    const CliResult r = RunCli({"render", "--world", "aerial", "--frames", "40", "--seed", "5",
                                "--poses-only", "--drift", drift, "--out", out.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_FALSE(fs::exists(out / "image_0"));
    errors.push_back(end_error(out));
    if (std::string(drift) == "1") drift1_scale = ReadLines(out / "raw_scale.txt");
  }
  EXPECT_DOUBLE_EQ(errors[0], end_error(full));  // same drift as the full render
  EXPECT_EQ(drift1_scale, ReadLines(full / "raw_scale.txt"));
  EXPECT_LT(errors[1], 1e-6);       // --drift 0: raw == GT
  EXPECT_GT(errors[2], errors[0]);  // more drift, farther from GT
  EXPECT_EQ(RunCli({"render", "--world", "aerial", "--frames", "4", "--poses-only", "--drift", "-1",
                    "--out", (TempDir() / "x").string()})
                .exit_code,
            2);
}

// raw_scale.txt is the raw trajectory's scale at each frame: each raw step is the GT step times
// the scale (up to the simulated translation noise), and the file explains the raw step lengths
// far better than no scale at all (the oracle of posegraph_accuracy takes its loops' scale here).
TEST(RenderCli, RawScaleIsTheScaleOfTheRawSteps) {
  const auto out = OutDir("raw_scale");
  const CliResult r = RunCli({"render", "--world", "aerial", "--frames", "300", "--seed", "3",
                              "--poses-only", "--drift", "8", "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Trajectory gt = ReadTrajectory(out / "poses_gt.txt");
  const Trajectory raw = ReadTrajectory(out / "poses_raw.txt");
  std::vector<double> scale;
  for (const std::string& line : ReadLines(out / "raw_scale.txt")) scale.push_back(std::stod(line));
  ASSERT_EQ(scale.size(), gt.size());
  std::vector<double> with_scale, without;
  for (size_t i = 0; i + 1 < gt.size(); ++i) {
    const double g =
        (gt.poses[i + 1].world_from_cam.translation - gt.poses[i].world_from_cam.translation)
            .norm();
    if (g < 1e-6) continue;
    const double e =
        (raw.poses[i + 1].world_from_cam.translation - raw.poses[i].world_from_cam.translation)
            .norm();
    with_scale.push_back(std::abs(e / (g * scale[i + 1]) - 1.0));
    without.push_back(std::abs(e / g - 1.0));
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  ASSERT_GT(with_scale.size(), 200u);
  EXPECT_LT(median(with_scale), 0.12);  // 8 % translation noise per axis
  EXPECT_GT(median(without), 2.0 * median(with_scale));
}

// A --start / --step slice is recorded in the folder (render.json), not only on stderr.
TEST(RenderCli, StartSliceIsRecordedInRenderJson) {
  for (const bool poses_only : {true, false}) {
    SCOPED_TRACE(poses_only ? "--poses-only" : "full render");
    const auto out = OutDir(poses_only ? "poses_only" : "full");
    std::vector<std::string> args = {
        "render",  "--world", "aerial",    "--frames", poses_only ? "30" : "8",
        "--start", "5",       "--step",    "2",        "--seed",
        "7",       "--out",   out.string()};
    if (poses_only) args.push_back("--poses-only");
    const CliResult r = RunCli(args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::ifstream in(out / "render.json");
    ASSERT_TRUE(in.good());
    const auto j = nlohmann::json::parse(in);
    EXPECT_EQ(j["start"].get<int>(), 5);
    EXPECT_EQ(j["step"].get<int>(), 2);
    EXPECT_EQ(j["seed"].get<int>(), 7);
    EXPECT_EQ(j["world"].get<std::string>(), "aerial");
    EXPECT_EQ(j["plan"].get<std::string>(), "circuit");
    EXPECT_EQ(j["poses_only"].get<bool>(), poses_only);
    // frames = poses written: (30 - 5) / 2 rounded up = 13; the full render 8 -> 2 poses.
    EXPECT_EQ(j["frames"].get<size_t>(), ReadTrajectory(out / "poses_gt.txt").size());
  }
}

// Per raw step: the GT step's length and the raw step's rotation error as a rotation vector
// (rad), gt_rel^-1 raw_rel, from a render folder's poses_gt.txt and poses_raw.txt.
struct StepErrors {
  std::vector<double> length;
  std::vector<Eigen::Vector3d> rotation;
  std::vector<Eigen::Vector3d> raw_translation;
};
StepErrors ReadStepErrors(const fs::path& dir) {
  const Trajectory gt = ReadTrajectory(dir / "poses_gt.txt");
  const Trajectory raw = ReadTrajectory(dir / "poses_raw.txt");
  EXPECT_EQ(gt.size(), raw.size());
  StepErrors e;
  for (size_t i = 0; i + 1 < std::min(gt.size(), raw.size()); ++i) {
    const Rigid3d g = gt.poses[i].world_from_cam.Inverse() * gt.poses[i + 1].world_from_cam;
    const Rigid3d r = raw.poses[i].world_from_cam.Inverse() * raw.poses[i + 1].world_from_cam;
    e.length.push_back(g.translation.norm());
    e.rotation.push_back(LogSO3(g.rotation.conjugate() * r.rotation));
    e.raw_translation.push_back(r.translation);
  }
  return e;
}

// --rotation-bias-per-frame P,Y,R: without the per-metre drift (--drift 0) every raw step is the
// GT step turned by exactly the bias about the camera axis it names (x pitch, y yaw, z roll).
TEST(RenderCli, RotationBiasPerFrameTurnsEveryRawStepAboutItsAxis) {
  const char* biases[] = {"0.5,0,0", "0,0.5,0", "0,0,0.5"};
  for (int axis = 0; axis < 3; ++axis) {
    SCOPED_TRACE(biases[axis]);
    const auto out = OutDir(fmt::format("axis{}", axis));
    const CliResult r =
        RunCli({"render", "--world", "aerial", "--frames", "12", "--seed", "4", "--poses-only",
                "--drift", "0", "--rotation-bias-per-frame", biases[axis], "--out", out.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const StepErrors e = ReadStepErrors(out);
    ASSERT_EQ(e.rotation.size(), 11u);
    const Eigen::Vector3d expected = 0.5 * M_PI / 180.0 * Eigen::Vector3d::Unit(axis);
    for (size_t i = 0; i < e.rotation.size(); ++i)
      EXPECT_LT((e.rotation[i] - expected).norm(), 1e-12) << "step " << i;
    std::ifstream in(out / "render.json");
    const auto j = nlohmann::json::parse(in);
    EXPECT_EQ(j["rotation_bias_deg_per_frame"][axis].get<double>(), 0.5);
    EXPECT_EQ(j["rotation_bias_deg_per_100m"], nlohmann::json({0.0, 0.0, 0.0}));  // times --drift 0
  }
}

// --rotation-bias P,Y,R replaces the default heading bias (0,0.6,0 deg per 100 m) and is scaled
// by --drift like it: with the same seed (same noise), each step's rotation error changes by
// exactly (new - default) * drift * step length / 100 m, and nothing else changes.
TEST(RenderCli, RotationBiasPer100mReplacesTheHeadingBias) {
  const auto [plain, biased] = RenderTwo(
      "plain", "biased",
      {"--world", "aerial", "--frames", "30", "--seed", "6", "--poses-only", "--drift", "3"},
      {"--rotation-bias", "2,0,-1.5"});
  ASSERT_FALSE(::testing::Test::HasFailure());
  const StepErrors a = ReadStepErrors(plain), b = ReadStepErrors(biased);
  ASSERT_EQ(a.rotation.size(), 29u);
  ASSERT_EQ(b.rotation.size(), 29u);
  const Eigen::Vector3d change_deg =
      3.0 * (Eigen::Vector3d(2, 0, -1.5) - Eigen::Vector3d(0, 0.6, 0));
  for (size_t i = 0; i < a.rotation.size(); ++i) {
    const Eigen::Vector3d expected = change_deg * a.length[i] / 100.0 * M_PI / 180.0;
    EXPECT_GT(expected.norm(), 1e-5);
    EXPECT_LT((b.rotation[i] - a.rotation[i] - expected).norm(), 1e-10) << "step " << i;
    EXPECT_LT((b.raw_translation[i] - a.raw_translation[i]).norm(), 1e-9) << "step " << i;
  }
  std::ifstream in(biased / "render.json");
  EXPECT_EQ(nlohmann::json::parse(in)["rotation_bias_deg_per_100m"],
            nlohmann::json({6.0, 0.0, -4.5}));
}

// No bias per frame and the default heading bias spelled out: the raw poses of today, byte for
// byte (the heading drift of every existing render is unchanged).
TEST(RenderCli, ExplicitDefaultBiasesReproduceTheRawPosesExactly) {
  const auto [plain, spelled] = RenderTwo(
      "default_bias", "spelled_bias",
      {"--world", "aerial", "--frames", "40", "--seed", "3", "--drift", "2", "--poses-only"},
      {"--rotation-bias", "0,0.6,0", "--rotation-bias-per-frame", "0,0,0"});
  ASSERT_FALSE(::testing::Test::HasFailure());
  const std::string raw = ReadText(plain / "poses_raw.txt");
  EXPECT_FALSE(raw.empty());
  EXPECT_EQ(raw, ReadText(spelled / "poses_raw.txt"));
  EXPECT_EQ(ReadText(plain / "raw_scale.txt"), ReadText(spelled / "raw_scale.txt"));
  std::ifstream in(plain / "render.json");
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["rotation_bias_deg_per_100m"], nlohmann::json({0.0, 1.2, 0.0}));  // times --drift
  EXPECT_EQ(j["rotation_bias_deg_per_frame"], nlohmann::json({0.0, 0.0, 0.0}));
}

// A bad bias is exit 2 with a message naming the flag.
TEST(RenderCli, RotationBiasFlagsNameThemselvesInErrors) {
  const auto out = TempDir() / "x";
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--rotation-bias-per-frame", "1,2"}, "--rotation-bias-per-frame expects PITCH,YAW,ROLL"},
      {{"--rotation-bias-per-frame", "1,2,3,4"}, "--rotation-bias-per-frame expects"},
      {{"--rotation-bias-per-frame", "0,0,nan"}, "--rotation-bias-per-frame expects"},
      {{"--rotation-bias-per-frame", "0,0,180"}, "--rotation-bias-per-frame must be finite"},
      {{"--rotation-bias", "x,0,0"}, "--rotation-bias expects PITCH,YAW,ROLL"},
      {{"--rotation-bias", "1,,2"}, "--rotation-bias expects"},
      {{"--rotation-bias", "0,1,0", "--raw", out.string()}, "cannot be combined with --raw"},
  };
  for (const auto& [flags, message] : cases) {
    std::vector<std::string> args = {"render", "--world",      "aerial", "--frames",
                                     "3",      "--poses-only", "--out",  out.string()};
    args.insert(args.end(), flags.begin(), flags.end());
    const CliResult r = RunCli(args);
    EXPECT_EQ(r.exit_code, 2) << flags[1];
    EXPECT_NE(r.err.find(message), std::string::npos) << flags[1] << ": " << r.err;
  }
}

TEST(RenderCli, BadArgumentsExit2) {
  const auto out = TempDir() / "x";
  EXPECT_EQ(RunCli({"render", "--world", "moon", "--out", out.string()}).exit_code, 2);
  const CliResult street = RunCli({"render", "--world", "street", "--out", out.string()});
  EXPECT_EQ(street.exit_code, 2);
  EXPECT_NE(street.err.find("--trajectory"), std::string::npos) << street.err;
  EXPECT_EQ(
      RunCli({"render", "--world", "aerial", "--plan", "spiral", "--out", out.string()}).exit_code,
      2);
}

TEST(RenderCli, StreetAlongKitti00) {
  SL_REQUIRE_DATA("kitti_gt_poses/00.txt");
  const auto out = TempDir() / "street";
  const CliResult r = RunCli({"render", "--world", "street", "--trajectory",
                              (DataDir() / "kitti_gt_poses" / "00.txt").string(), "--frames", "2",
                              "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Dataset d = OpenDataset("kitti:" + out.string());
  ASSERT_EQ(d.frames.size(), 2u);
  EXPECT_EQ(d.intrinsics.width, 1241);
  EXPECT_DOUBLE_EQ(d.intrinsics.fx, 718.856);
}

// A fabricated run folder: GT circle, drifted raw, corrected = GT + small noise, loops (one false).
void FabricateRun(const fs::path& dir) {
  std::ofstream gt(dir / "poses_gt.txt"), raw(dir / "poses_raw.txt"), cor(dir / "trajectory.txt");
  const int n = 400;
  for (int i = 0; i < n; ++i) {
    const double a = 4.0 * M_PI * i / n;  // two laps
    const double x = 50 * std::cos(a), z = 50 * std::sin(a);
    const double drift = 1.0 + 0.001 * i;
    gt << fmt::format("1 0 0 {} 0 1 0 0 0 0 1 {}\n", x, z);
    raw << fmt::format("1 0 0 {} 0 1 0 0 0 0 1 {}\n", drift * x + 0.05 * i, drift * z);
    cor << fmt::format("{} 1 0 0 {} 0 1 0 0 0 0 1 {}\n", i, x + 0.3 * std::sin(i), z);
  }
  std::ofstream loops(dir / "loops.csv");
  loops << "query,match,score,inliers\n";
  for (int i = 210; i < 390; i += 20) loops << i << "," << i - 200 << ",0.8,50\n";
  loops << "300,50,0.3,20\n";  // false: opposite side of the circle
  std::ofstream summary(dir / "summary.json");
  // timing_ms as detect / run write it (ms per keyframe).
  summary << R"({"frames": 400, "timing_ms": {"extract": {"median": 4.2}, "search": {"median": 0.3},
               "match": {"median": 2.5}, "total": {"median": 12.0}}})";
  std::ofstream gt_loops(dir / "gt_loops.txt");
  for (int i = 200; i < 400; ++i) gt_loops << i << " " << i - 200 << "\n";
}

TEST(ReportCli, WritesHtmlAndPlots) {
  if (cli::FindPython().empty()) {
    if (InCi()) FAIL() << "python3 with matplotlib required in CI";
    GTEST_SKIP() << "no python3 with matplotlib";
  }
  const auto dir = OutDir("run");
  FabricateRun(dir);
  const CliResult r = RunCli({"report", dir.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_TRUE(fs::exists(dir / "report.html"));
  std::ifstream html(dir / "report.html");
  const std::string page((std::istreambuf_iterator<char>(html)), {});
  for (const char* png :
       {"report_topview.png", "report_error.png", "report_timing.png", "report_pr.png"}) {
    EXPECT_NE(page.find(png), std::string::npos) << png;
    EXPECT_GT(fs::file_size(dir / png), 5000u) << png;
  }
  EXPECT_NE(page.find("1 accepted loops false"), std::string::npos) << "the fabricated false loop";
  // Re-scored by `sparseloop eval` at another distance: the false loop (about 70 m) is correct.
  ASSERT_EQ(RunCli({"report", dir.string(), "--false-loop-distance", "100"}).exit_code, 0);
  EXPECT_NE(ReadText(dir / "report.html").find("0 accepted loops false (GT distance &gt; 100)"),
            std::string::npos);
}

// The report agrees with the run: its threshold and counts are summary.json's, rejected loops are
// drawn as rejected, report.html is one self-contained file, a truncated loops.csv is an error.
TEST(ReportCli, AgreesWithTheRunAndIsSelfContained) {
  if (cli::FindPython().empty()) {
    if (InCi()) FAIL() << "python3 with matplotlib required in CI";
    GTEST_SKIP() << "no python3 with matplotlib";
  }
  const fs::path& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty());
  const auto run = OutDir("run");
  CliResult r =
      RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
              (seq / "poses_raw.txt").string(), "--gt-loop-distance", "35", "--out", run.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream in(run / "summary.json");
  const auto summary = nlohmann::json::parse(in);
  const int loops = summary["loops"].get<int>();
  const int accepted = summary["accepted_loops"].get<int>();
  r = RunCli({"report", run.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::string page = ReadText(run / "report.html");
  EXPECT_NE(page.find(fmt::format("{} loops, {} accepted", loops, accepted)), std::string::npos);
  EXPECT_NE(page.find(fmt::format("{} accepted loops false (GT distance &gt; 35)",
                                  summary["accepted_loops_false"].get<int>())),
            std::string::npos)
      << "the run's threshold (35), not the report's own 10";
  // The error plot is eval's alignment and association (the report has none of its own).
  for (const char* label : {"raw", "corrected"}) {
    EXPECT_NE(page.find(fmt::format("{}: RMSE {:.2f} m", label,
                                    summary["eval"][label]["ate_rmse_m"].get<double>())),
              std::string::npos)
        << label;
  }
  EXPECT_NE(page.find("data:image/png;base64,"), std::string::npos);
  EXPECT_EQ(page.find("src=\"report_"), std::string::npos) << "a linked image";

  // One loop rejected by the pose graph is drawn and counted as rejected.
  {
    std::string csv = ReadText(run / "loops.csv");
    const size_t row = csv.find('\n') + 1;
    size_t field = row;
    for (int i = 0; i < 7; ++i) field = csv.find(',', field) + 1;  // column 8: accepted
    ASSERT_EQ(csv.substr(field, 2), "1,");
    csv[field] = '0';
    std::ofstream(run / "loops.csv") << csv;
  }
  r = RunCli({"report", run.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  page = ReadText(run / "report.html");
  EXPECT_NE(page.find(fmt::format("{} loops, {} accepted, 1 rejected", loops, accepted - 1)),
            std::string::npos);

  // Truncated mid-row: an error naming the file and line, not a caption that disagrees.
  {
    std::string csv = ReadText(run / "loops.csv");
    std::ofstream(run / "loops.csv") << csv.substr(0, csv.size() - 20);
  }
  r = RunCli({"report", run.string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("loops.csv:"), std::string::npos) << r.err;
  // Whole rows missing: the count disagrees with summary.json.
  {
    std::string csv = ReadText(run / "loops.csv");
    csv = csv.substr(0, csv.rfind('\n'));
    csv = csv.substr(0, csv.rfind('\n') + 1);
    std::ofstream(run / "loops.csv") << csv;
  }
  r = RunCli({"report", run.string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("(summary.json)"), std::string::npos) << r.err;
}

TEST(ReportCli, MissingFolderOrTrajectoryFails) {
  EXPECT_EQ(RunCli({"report", "/nonexistent/run"}).exit_code, 2);
  if (cli::FindPython().empty()) GTEST_SKIP() << "no python3 with matplotlib";
  const auto empty = OutDir("empty");
  WriteText(empty / "summary.json", "{}\n");
  const CliResult r = RunCli({"report", empty.string()});
  EXPECT_EQ(r.exit_code, 2);  // a folder without a trajectory is bad input
  EXPECT_NE(r.err.find("no trajectory"), std::string::npos) << r.err;
}

// A folder without summary.json (a dataset, not a run output) is refused before anything is
// written into it: report.html and its plots went into the dataset's folder.
TEST(ReportCli, AFolderWithoutSummaryJsonIsRefused) {
  if (cli::FindPython().empty()) {
    if (InCi()) FAIL() << "python3 with matplotlib required in CI";
    GTEST_SKIP() << "no python3 with matplotlib";
  }
  const auto run = OutDir("run");
  FabricateRun(run);
  const auto dataset = OutDir("dataset");
  fs::copy_file(run / "poses_gt.txt", dataset / "poses.txt");
  const CliResult r = RunCli({"report", dataset.string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("got a folder without summary.json"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dataset / "report.html"));
  EXPECT_FALSE(fs::exists(dataset / "report_topview.png"));
}

// The report reads the run's files as `eval` reads them: a BOM, CR-only or CRLF line ends, an
// image name that is not UTF-8. A truncated summary.json is one line naming the file and its line
// (it was a Python traceback).
TEST(ReportCli, ReadsWhatEvalReadsAndNamesABrokenSummary) {
  if (cli::FindPython().empty()) {
    if (InCi()) FAIL() << "python3 with matplotlib required in CI";
    GTEST_SKIP() << "no python3 with matplotlib";
  }
  const auto dir = OutDir("run");
  FabricateRun(dir);
  std::string loops = "\xEF\xBB\xBFquery,match,score,query_image\r";
  for (int i = 210; i < 390; i += 20)
    loops += fmt::format("{},{},0.8,\"\xff{}.png\"\r", i, i - 200, i);
  WriteText(dir / "loops.csv", loops);
  WriteText(dir / "summary.json",
            "\xEF\xBB\xBF{\r\n\"frames\": 400,\r\n\"loops\": 9,\r\n\"gt_loop_distance\": 20,"
            "\r\n\"dataset\": \"seq\xff\"\r\n}\r\n");
  CliResult r = RunCli({"report", dir.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(ReadText(dir / "report.html").find("9 loops, 9 accepted"), std::string::npos);

  WriteText(dir / "summary.json", "{\"frames\": 400,\n\"loops\": 9,\n\"gt_loo");
  r = RunCli({"report", dir.string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find((dir / "summary.json").string() + ":3: expected"), std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("Traceback"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace sparseloop::test

namespace sparseloop::test {
namespace {

// --out holding an earlier render is replaced whole: a 5-frame render into an 8-frame one left 8
// images beside 5 poses, a folder `run` refused. A folder with anything else (a copy of a real
// sequence with the user's notes) is refused before any work and kept as it was.
TEST(RenderCli, AnEarlierRenderIsReplacedWholeAndAForeignFolderIsRefused) {
  const auto dir = TempDir();
  const std::string out = (dir / "r").string();
  const auto render = [&](const std::string& frames) {
    return RunCli({"render", "--world", "aerial", "--frames", frames, "--out", out});
  };
  ASSERT_EQ(render("8").exit_code, 0);
  const CliResult again = render("5");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  size_t images = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir / "r" / "image_0"))
    images += e.is_regular_file();
  EXPECT_EQ(images, 5u);
  size_t mapped = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir / "r" / "mapped"))
    mapped += e.is_regular_file();
  EXPECT_EQ(mapped, 5u);
  WriteText(dir / "r" / "notes.txt", "mine\n");
  const CliResult refused = render("3");
  EXPECT_EQ(refused.exit_code, 2) << refused.err;
  EXPECT_NE(refused.err.find("got a folder holding 1 other entry (notes.txt)"), std::string::npos)
      << refused.err;
  EXPECT_EQ(ReadText(dir / "r" / "notes.txt"), "mine\n");
  EXPECT_TRUE(std::filesystem::exists(dir / "r" / "image_0" / "000004.png"));
  // A sequence folder without render.json (not ours) is refused too.
  std::filesystem::create_directories(dir / "kitti" / "image_0");
  WriteText(dir / "kitti" / "times.txt", "0\n");
  const CliResult foreign =
      RunCli({"render", "--world", "aerial", "--frames", "3", "--out", (dir / "kitti").string()});
  EXPECT_EQ(foreign.exit_code, 2) << foreign.err;
  EXPECT_NE(foreign.err.find("a folder without render.json"), std::string::npos) << foreign.err;
  EXPECT_EQ(ReadText(dir / "kitti" / "times.txt"), "0\n");
}

// Everything is read and checked before --out is touched: a positions-only --trajectory (the
// renderer needs each pose's rotation) is refused naming --trajectory and the file's line, and
// an earlier render in --out stays as it was (it was removed, then the render failed after
// creating its folders, naming no file).
TEST(RenderCli, ABadTrajectoryIsRefusedBeforeTheFolderIsTouched) {
  const auto dir = TempDir();
  const std::string positions =
      WriteText(dir / "positions.txt", "# frame x y z\n0 0 0 0\n1 1 0 0\n2 2 0 0\n").string();
  const std::string out = (dir / "r").string();
  CliResult r = RunCli(
      {"render", "--world", "street", "--trajectory", positions, "--frames", "2", "--out", out});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--trajectory " + positions + ":2: expected"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(out));
  ASSERT_EQ(RunCli({"render", "--world", "aerial", "--frames", "3", "--out", out}).exit_code, 0);
  const std::string before = ReadText(dir / "r" / "poses_gt.txt");
  for (const std::string world : {"street", "aerial"}) {
    r = RunCli(
        {"render", "--world", world, "--trajectory", positions, "--frames", "2", "--out", out});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("--trajectory " + positions + ":2: expected"), std::string::npos) << r.err;
    EXPECT_EQ(ReadText(dir / "r" / "poses_gt.txt"), before);
    EXPECT_TRUE(std::filesystem::exists(dir / "r" / "image_0" / "000002.png"));
  }
  // A --start past the trajectory, a missing file: refused the same way, the render kept.
  r = RunCli({"render", "--world", "aerial", "--trajectory", (dir / "r" / "poses_gt.txt").string(),
              "--start", "7", "--out", (dir / "s").string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--start"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "s"));
  r = RunCli(
      {"render", "--world", "street", "--trajectory", (dir / "none.txt").string(), "--out", out});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--trajectory"), std::string::npos) << r.err;
  EXPECT_EQ(ReadText(dir / "r" / "poses_gt.txt"), before);
}

// times.txt keeps distinct times distinct: a trajectory stamped in seconds since 1970 at 30 Hz
// was written "1.311868e+09" on every line, and `run` then refused the render's own times.txt.
TEST(RenderCli, TimesTxtKeepsEveryTimeOfTheTrajectory) {
  const auto dir = TempDir();
  ASSERT_EQ(RunCli({"render", "--world", "aerial", "--frames", "4", "--poses-only", "--out",
                    (dir / "p").string()})
                .exit_code,
            0);
  Trajectory path = ReadTrajectory(dir / "p" / "poses_gt.txt");
  path.has_timestamps = true;
  for (size_t i = 0; i < path.size(); ++i) path.poses[i].timestamp = 1311868229.576 + i / 30.0;
  const std::string trajectory = (dir / "tum.txt").string();
  WriteTrajectory(trajectory, path, TrajectoryFormat::kTum);
  const CliResult r = RunCli({"render", "--world", "aerial", "--trajectory", trajectory,
                              "--no-mapped", "--out", (dir / "r").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Dataset d = OpenDataset("kitti:" + (dir / "r").string());
  ASSERT_EQ(d.frames.size(), 4u);
  EXPECT_NEAR(d.frames[3].timestamp - d.frames[0].timestamp, 0.1, 1e-6);
}

// --seed takes a non-negative integer (-1 was stored as 18446744073709551615).
TEST(RenderCli, ANegativeSeedIsRefused) {
  const auto dir = TempDir();
  const CliResult r = RunCli({"render", "--world", "aerial", "--frames", "3", "--seed", "-1",
                              "--out", (dir / "r").string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--seed"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "r"));
}

}  // namespace
}  // namespace sparseloop::test
