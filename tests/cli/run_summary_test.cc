// What `run` / `detect` write about a run (docs/FORMATS.md): summary.json's loop checks, and
// the per-frame status.
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <utility>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

namespace fs = std::filesystem;

// Rows of a CSV as header-name -> value maps.
std::vector<std::map<std::string, std::string>> ReadCsv(const fs::path& p) {
  std::ifstream in(p);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::istringstream hs(line);
  for (std::string f; std::getline(hs, f, ',');) header.push_back(f);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    std::map<std::string, std::string> row;
    std::istringstream ls(line);
    size_t i = 0;
    for (std::string f; std::getline(ls, f, ','); ++i) row[i < header.size() ? header[i] : ""] = f;
    rows.push_back(row);
  }
  return rows;
}

// Ran once: the rendered loop sequence through `run` with its GT.
const fs::path& RunOnRenderedSequence() {
  static const fs::path out = [] {
    const fs::path& seq = RenderedLoopSequence();
    const fs::path dir = TempDir("_shared_run") / "out";
    const CliResult r = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                                (seq / "poses_raw.txt").string(), "--out", dir.string()});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return dir;
  }();
  return out;
}

TEST(CliRunSummary, LoopChecksListEveryAcceptedLoop) {
  const fs::path& out = RunOnRenderedSequence();
  const auto summary = ReadJson(out / "summary.json");
  ASSERT_TRUE(summary.contains("loop_checks")) << summary.dump(1);
  const auto& checks = summary["loop_checks"];
  ASSERT_TRUE(checks.is_array());
  std::set<std::pair<int, int>> accepted;
  for (const auto& row : ReadCsv(out / "loops.csv"))
    if (row.at("accepted") == "1")
      accepted.insert({std::stoi(row.at("query")), std::stoi(row.at("match"))});
  ASSERT_FALSE(accepted.empty());
  EXPECT_EQ(checks.size(), accepted.size());
  EXPECT_EQ(summary["accepted_loops"].get<size_t>(), accepted.size());
  size_t inconsistent = 0;
  for (const auto& c : checks) {
    EXPECT_TRUE(accepted.count({c["query"].get<int>(), c["match"].get<int>()})) << c.dump();
    EXPECT_GE(c["chi2"].get<double>(), 0.0);
    EXPECT_GT(c["dof"].get<int>(), 0);
    EXPECT_GT(c["threshold"].get<double>(), 0.0);
    EXPECT_EQ(c["consistent"].get<bool>(), c["chi2"].get<double>() <= c["threshold"].get<double>());
    for (const char* key : {"loop", "translation_error", "rotation_error_rad", "log_scale_error"})
      EXPECT_TRUE(c.contains(key)) << key;
    inconsistent += !c["consistent"].get<bool>();
  }
  EXPECT_EQ(summary["inconsistent_loops"].get<size_t>(), inconsistent);
}

// `run --odometry-covariance`: one line per frame (KITTI: keyed by frame index), 21 numbers. Every
// step takes the caller's covariance (summary.json says how many) and the solve changes with it;
// a malformed line is refused before anything is written, naming the file and the line.
TEST(CliRunSummary, OdometryCovarianceFileWeightsEveryStep) {
  const fs::path& seq = RenderedLoopSequence();
  const auto dir = TempDir();
  size_t frames = 0;
  for (const auto& e : fs::directory_iterator(seq / "image_0")) frames += e.is_regular_file();
  ASSERT_GT(frames, 20u);
  const fs::path cov = dir / "cov.txt";
  {
    std::ofstream f(cov);
    f << "# frame, upper triangle of the step covariance [t, r]\n";
    for (size_t i = 0; i < frames; ++i) {
      f << i;
      for (int r = 0; r < 6; ++r) {
        for (int c = r; c < 6; ++c) f << " " << (r != c ? 0.0 : r < 3 ? 0.25 : 0.0025);
      }
      f << "\n";
    }
  }
  const fs::path out = dir / "out";
  const CliResult r = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                              (seq / "poses_raw.txt").string(), "--odometry-covariance",
                              cov.string(), "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = ReadJson(out / "summary.json");
  ASSERT_TRUE(summary.contains("odometry_covariance")) << summary.dump(1);
  EXPECT_EQ(summary["odometry_covariance"]["steps"].get<size_t>(), frames - 1);
  const auto plain = ReadJson(RunOnRenderedSequence() / "summary.json");
  EXPECT_FALSE(plain.contains("odometry_covariance"));
  EXPECT_NE(ReadText(out / "trajectory.txt"), ReadText(RunOnRenderedSequence() / "trajectory.txt"));

  const fs::path bad = dir / "bad.txt";
  {
    std::ofstream f(bad);
    f << "0 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n1 1 0 0\n";
  }
  const fs::path out2 = dir / "out2";
  const CliResult b = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                              (seq / "poses_raw.txt").string(), "--odometry-covariance",
                              bad.string(), "--out", out2.string()});
  EXPECT_NE(b.exit_code, 0);
  EXPECT_NE(b.err.find(bad.string() + ":2:"), std::string::npos) << b.err;
  EXPECT_FALSE(fs::exists(out2));
  // Keys of another sequence: no frame matches.
  const fs::path other = dir / "other.txt";
  {
    std::ofstream f(other);
    f << "99999 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
  }
  const CliResult o = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                              (seq / "poses_raw.txt").string(), "--odometry-covariance",
                              other.string(), "--out", out2.string()});
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_NE(o.err.find("--odometry-covariance"), std::string::npos) << o.err;
  EXPECT_NE(o.err.find("frame indices"), std::string::npos) << o.err;
  EXPECT_FALSE(fs::exists(out2));
}

// The first `frames` frames of the rendered sequence, without GT (no poses: global search).
fs::path ShortSequence(const fs::path& dir, int frames) {
  const fs::path& seq = RenderedLoopSequence();
  const fs::path copy = dir / "short";
  fs::create_directories(copy / "image_0");
  for (int i = 0; i < frames; ++i) {
    const std::string name = fmt::format("{:06d}.png", i);
    fs::create_symlink(seq / "image_0" / name, copy / "image_0" / name);
  }
  fs::copy_file(seq / "times.txt", copy / "times.txt");
  fs::copy_file(seq / "calib.txt", copy / "calib.txt");
  return copy;
}

// Mapped-pixel files whose depths are all unknown (<= 0) are reported: a warning naming the files
// and the count in summary.json (mapped_pixels.keyframes_without_depth); such a run found no loop
// and said nothing.
TEST(CliRunSummary, MappedPixelsWithoutAnyDepthAreReported) {
  const auto dir = TempDir();
  const fs::path seq = ShortSequence(dir, 12);
  for (int i = 0; i < 12; ++i) {
    std::string text = "# u v depth\n";
    for (int k = 0; k < 20; ++k)
      text += fmt::format("{} {} {}\n", 10 + 5 * k, 20 + 3 * k, i == 0 ? 5.0 : -(k % 2));
    WriteText(seq / "mapped" / fmt::format("{:06d}.txt", i), text);
  }
  const CliResult r =
      RunCli({"detect", "--dataset", "kitti:" + seq.string(), "--out", (dir / "a").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = ReadJson(dir / "a" / "summary.json");
  ASSERT_TRUE(summary.contains("mapped_pixels")) << summary.dump(1);
  EXPECT_EQ(summary["mapped_pixels"]["keyframes"].get<int>(), 12);
  EXPECT_EQ(summary["mapped_pixels"]["keyframes_without_depth"].get<int>(), 11);
  EXPECT_NE(r.err.find((seq / "mapped" / "000001.txt").string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("11 of 12 keyframes"), std::string::npos) << r.err;
}

// --set KEY=VALUE reaches any configuration key from the command line, after --config and the
// shorthand flags; a bad key or value is refused before the run, naming the --set argument.
TEST(CliRunSummary, SetOverridesAnyConfigurationKey) {
  const auto dir = TempDir();
  const fs::path seq = ShortSequence(dir, 6);
  const fs::path config = dir / "config.json";
  {
    std::ofstream f(config);
    f << R"({"detector": {"features": {"max_features": 40}}})";
  }
  const CliResult r =
      RunCli({"detect", "--dataset", "kitti:" + seq.string(), "--config", config.string(), "-K",
              "30", "--set", "detector.features.max_features=15", "--set",
              "detector.features.ranking=response", "--out", (dir / "a").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = ReadJson(dir / "a" / "summary.json");
  EXPECT_EQ(summary["features_per_keyframe"].get<int>(), 15);
  EXPECT_EQ(summary["config"]["features"]["max_features"].get<int>(), 15);
  EXPECT_EQ(summary["config"]["features"]["ranking"].get<std::string>(), "response");
  struct Case {
    std::string arg, message;
  };
  const Case cases[] = {
      {"detector.features.max_features=0", "--set detector.features.max_features=0:"},
      {"detector.features.max_features=many", "expected an integer"},
      {"detector.feature.max_features=15", "such as detector.features.max_features"},
      {"max_features", "expected KEY=VALUE"},
  };
  for (const Case& c : cases) {
    const CliResult b = RunCli({"detect", "--dataset", "kitti:" + seq.string(), "--set", c.arg,
                                "--out", (dir / "b").string()});
    EXPECT_EQ(b.exit_code, 2) << c.arg;
    EXPECT_NE(b.err.find(c.message), std::string::npos) << b.err;
    EXPECT_FALSE(fs::exists(dir / "b")) << c.arg;
  }
}

// A short sequence finds nothing with the default exclude_recent (10): detect says why, per frame
// (frames.csv) and counted (summary.json status_counts, stdout), and --exclude-recent fixes it.
TEST(CliRunSummary, DetectSaysWhyNothingWasFound) {
  const auto dir = TempDir();
  const fs::path seq = ShortSequence(dir, 10);
  const CliResult r =
      RunCli({"detect", "--dataset", "kitti:" + seq.string(), "--out", (dir / "a").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rows = ReadCsv(dir / "a" / "frames.csv");
  ASSERT_EQ(rows.size(), 10u);
  for (const auto& row : rows) {
    EXPECT_EQ(row.at("status"), "no_candidates");
    EXPECT_EQ(row.at("candidates"), "0");
    EXPECT_EQ(row.at("match"), "-1");
    for (const char* column : {"frame", "matches", "inliers"}) EXPECT_TRUE(row.count(column));
  }
  const auto summary = ReadJson(dir / "a" / "summary.json");
  EXPECT_EQ(summary["status_counts"]["no_candidates"].get<int>(), 10);
  EXPECT_EQ(summary["status_counts"]["detected"].get<int>(), 0);
  EXPECT_NE(r.out.find("no_candidates 10"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--exclude-recent 10"), std::string::npos) << r.out;

  // The overlap walk (detector.overlap_gap) would exclude these frames too: one continuous
  // 10-frame stretch shares its scene throughout; switched off to see --exclude-recent alone.
  const fs::path config = dir / "no_overlap.json";
  std::ofstream(config) << R"({"detector": {"overlap_gap": 0}})";
  const CliResult fixed =
      RunCli({"detect", "--dataset", "kitti:" + seq.string(), "--exclude-recent", "2",
              "--min-path-ratio", "0", "--config", config.string(), "--out", (dir / "b").string()});
  ASSERT_EQ(fixed.exit_code, 0) << fixed.err;
  const auto fixed_summary = ReadJson(dir / "b" / "summary.json");
  EXPECT_EQ(fixed_summary["config"]["search"]["exclude_recent"].get<int>(), 2);
  EXPECT_EQ(fixed_summary["config"]["min_path_ratio"].get<double>(), 0.0);
  EXPECT_LT(fixed_summary["status_counts"]["no_candidates"].get<int>(), 10);
  int with_candidates = 0;
  for (const auto& row : ReadCsv(dir / "b" / "frames.csv"))
    with_candidates += std::stoi(row.at("candidates")) > 0;
  EXPECT_EQ(with_candidates, 10 - fixed_summary["status_counts"]["no_candidates"].get<int>());
}

// loops.csv carries the images' file names in two columns appended at the end; `run` writes
// frames.csv too, and its status counts are summary.json's.
TEST(CliRunSummary, LoopsCsvEndsWithImageNamesAndRunWritesFramesCsv) {
  const fs::path& out = RunOnRenderedSequence();
  std::ifstream in(out / "loops.csv");
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header,
            "query,match,score,inliers,status,pose_kind,planar_alternative,accepted,correct,qx,qy,"
            "qz,qw,tx,ty,tz,scale,match_session,query_image,match_image,method,"
            "local_poses_from_images,local_poses_raw");
  const auto loops = ReadCsv(out / "loops.csv");
  ASSERT_FALSE(loops.empty());
  for (const auto& row : loops) {
    EXPECT_EQ(row.at("query_image"), fmt::format("{:06d}.png", std::stoi(row.at("query"))));
    EXPECT_EQ(row.at("match_image"), fmt::format("{:06d}.png", std::stoi(row.at("match"))));
  }
  const auto summary = ReadJson(out / "summary.json");
  const auto frames = ReadCsv(out / "frames.csv");
  EXPECT_EQ(frames.size(), summary["keyframes"].get<size_t>());
  std::map<std::string, int> counts;
  for (const auto& row : frames) counts[row.at("status")]++;
  for (const auto& [status, count] : summary["status_counts"].items())
    EXPECT_EQ(counts[status], count.get<int>()) << status;
}

// `eval` scores loops without trajectories, and agrees with `run`'s own numbers.
TEST(CliRunSummary, EvalScoresLoopsWithoutTrajectories) {
  const fs::path& out = RunOnRenderedSequence();
  const auto dir = TempDir();
  const CliResult r =
      RunCli({"eval", "--loops", (out / "loops.csv").string(), "--gt-loops",
              (out / "gt_loops.txt").string(), "--json", (dir / "m.json").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto metrics = ReadJson(dir / "m.json");
  const auto summary = ReadJson(out / "summary.json");
  EXPECT_EQ(metrics["loop_precision"], summary["loop_precision"]);
  EXPECT_EQ(metrics["loop_recall"], summary["loop_recall"]);
  EXPECT_TRUE(!metrics.contains("ate_rmse_m") || metrics["ate_rmse_m"].is_null());
  const CliResult nothing = RunCli({"eval", "--gt-loops", (out / "gt_loops.txt").string()});
  EXPECT_EQ(nothing.exit_code, 2);
  EXPECT_NE(nothing.err.find("nothing to evaluate"), std::string::npos) << nothing.err;
  EXPECT_EQ(RunCli({"eval", "--est", (out / "trajectory.txt").string()}).exit_code, 2);
}

// eval --frames: the search area's coverage of the GT loops from run's frames.csv (its `area`
// column); bad input names the flag or the file and line.
TEST(CliRunSummary, EvalMeasuresSearchAreaCoverageFromFramesCsv) {
  const fs::path& out = RunOnRenderedSequence();
  const auto dir = TempDir();
  const CliResult r = RunCli({"eval", "--gt-loops", (out / "gt_loops.txt").string(), "--frames",
                              (out / "frames.csv").string(), "--json", (dir / "m.json").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("Search area"), std::string::npos) << r.out;
  const auto area = ReadJson(dir / "m.json")["search_area"];
  ASSERT_TRUE(area.is_object());
  const auto queries = area["gt_queries"].get<int>();
  EXPECT_GT(queries, 0);
  EXPECT_LE(area["covered"].get<int>(), queries);
  EXPECT_GT(area["covered"].get<int>(), 0);  // the rendered loop's revisits are in the area
  EXPECT_GT(area["mean_candidates"].get<double>(), 0.0);
  // No GT loops to cover: the flag is named.
  const CliResult no_gt = RunCli({"eval", "--frames", (out / "frames.csv").string()});
  EXPECT_EQ(no_gt.exit_code, 2);
  EXPECT_NE(no_gt.err.find("--frames"), std::string::npos) << no_gt.err;
  // A frames.csv without the area column (an older run): file and line.
  const fs::path old = dir / "old_frames.csv";
  std::ofstream(old) << "frame,status\n0,no_candidates\n";
  const CliResult bad =
      RunCli({"eval", "--gt-loops", (out / "gt_loops.txt").string(), "--frames", old.string()});
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("old_frames.csv:1"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("area"), std::string::npos) << bad.err;
}

// run's loop recall counts revisits, not driving on: GT pairs need GT path between the frames
// (default 4 x the GT loop distance); --gt-min-path 0 --gt-min-gap 1 counts consecutive frames.
TEST(CliRunSummary, GtRevisitsNeedPathBetweenTheFrames) {
  const fs::path& seq = RenderedLoopSequence();
  const auto dir = TempDir();
  // 40 m: the sequence's frames are ~18 m apart, so neighbours are within the GT loop distance.
  const auto run = [&](const std::string& name, std::vector<std::string> extra) {
    std::vector<std::string> args = {"run",
                                     "--dataset",
                                     "kitti:" + seq.string(),
                                     "--poses",
                                     (seq / "poses_raw.txt").string(),
                                     "--gt-loop-distance",
                                     "40",
                                     "--out",
                                     (dir / name).string()};
    args.insert(args.end(), extra.begin(), extra.end());
    const CliResult r = RunCli(args);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return ReadJson(dir / name / "summary.json");
  };
  const auto strict = run("default", {});
  EXPECT_DOUBLE_EQ(strict["gt_revisits"]["min_path"].get<double>(), 160.0);
  const auto loose = run("loose", {"--gt-min-path", "0", "--gt-min-gap", "1"});
  EXPECT_EQ(loose["gt_revisits"]["min_gap"].get<int>(), 1);
  EXPECT_GT(loose["gt_revisits"]["pairs"].get<size_t>(),
            strict["gt_revisits"]["pairs"].get<size_t>() + 30);  // every neighbouring pair
  EXPECT_LT(loose["loop_recall"].get<double>(), strict["loop_recall"].get<double>());
  EXPECT_EQ(RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                    (seq / "poses_raw.txt").string(), "--gt-min-path", "-1", "--out",
                    (dir / "bad").string()})
                .exit_code,
            2);
}

// bench/configs/sparse_k15.json (docs/DETECTOR.md "Sparse K = 15"): K = 15 records
// (about 1/16 of the default's bytes), and on the rendered circuit at least the correct loops the
// paper's symmetric K = 15 finds, no false one; summary.json counts the loops per source. Correct
// = GT distance < 35 m, the aerial rule of docs/BENCHMARKS.md: the nadir views of neighbouring
// frames (17 m apart here) overlap, so a match one frame off is a true loop.
TEST(CliRunSummary, SparsePresetKeepsK15AndFindsMoreThanSymmetricK15) {
  const fs::path& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty());
  const auto dir = TempDir();
  std::ofstream(dir / "sym.json") << R"({"detector": {"features": {"max_features": 15}}})";
  const auto run = [&](const std::string& name, const fs::path& config) {
    const CliResult r = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                                (seq / "poses_raw.txt").string(), "--config", config.string(),
                                "--gt-loop-distance", "35", "--out", (dir / name).string()});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return ReadJson(dir / name / "summary.json");
  };
  const auto sparse = run("sparse", SourceDir() / "bench" / "configs" / "sparse_k15.json");
  const auto sym = run("sym", dir / "sym.json");
  EXPECT_LT(sparse["bytes_per_keyframe"].get<double>(), 1000.0);
  EXPECT_EQ(sparse["loop_false_positives"].get<int>(), 0);
  EXPECT_GE(sparse["loop_true_positives"].get<int>(), sym["loop_true_positives"].get<int>());
  EXPECT_GT(sparse["loop_true_positives"].get<int>(), 0);
  const auto& sources = sparse["loop_sources"];
  EXPECT_EQ(sources["area"].get<int>() + sources["appearance"].get<int>(),
            sparse["status_counts"]["detected"].get<int>());
}

}  // namespace
}  // namespace sparseloop::test

namespace sparseloop::test {
namespace {

// `run --gt` on a render folder (it holds raw_scale.txt): summary.json loop_nees checks each
// accepted metric loop against the exact relative pose with the information the graph gave it.
// On this fixture the graph's covariance is far wider than the error (measured: 32 loops, mean
// NEES per dof 0.015, none above its 95 % quantile; docs/POSEGRAPH.md "Loop covariance against the
// exact pose"). --raw-scale without --gt, or a file shorter than the dataset, is refused first.
TEST(CliRunSummary, LoopNeesAgainstTheExactPoseOfARender) {
  const fs::path& seq = RenderedLoopSequence();
  const fs::path dir = TempDir();
  fs::create_directories(dir / "images");
  const CliResult r = RunCli(
      {"run", "--dataset", "kitti:" + seq.string(), "--poses", (seq / "poses_raw.txt").string(),
       "--gt", (seq / "poses_gt.txt").string(), "--out", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = ReadJson(dir / "out" / "summary.json");
  ASSERT_TRUE(summary.contains("loop_nees")) << summary.dump(1);
  const auto& nees = summary["loop_nees"];
  std::set<std::pair<int, int>> metric_accepted, checked;
  for (const auto& row : ReadCsv(dir / "out" / "loops.csv")) {
    if (row.at("accepted") == "1" &&
        (row.at("pose_kind") == "sim3" || row.at("pose_kind") == "se3_metric"))
      metric_accepted.insert({std::stoi(row.at("query")), std::stoi(row.at("match"))});
  }
  for (const auto& row : nees["per_loop"]) {
    checked.insert({row[0].get<int>(), row[1].get<int>()});
    EXPECT_GE(row[3].get<int>(), 6) << row.dump();
    EXPECT_TRUE(std::isfinite(row[4].get<double>()) && row[4].get<double>() >= 0) << row.dump();
  }
  EXPECT_EQ(checked, metric_accepted);
  EXPECT_GE(nees["loops"].get<int>(), 20);
  EXPECT_EQ(nees["beyond_3_sigma"].get<int>(), 0);
  EXPECT_LT(nees["band_95"][0].get<double>(), 1.0);
  EXPECT_GT(nees["band_95"][1].get<double>(), 1.0);

  // An images: folder has no ground truth of its own.
  for (const char* name : {"000000.png", "000001.png", "000002.png"})
    fs::copy_file(seq / "image_0" / name, dir / "images" / name);
  std::ifstream raw_in(seq / "poses_raw.txt");
  std::string three, line;
  for (int i = 0; i < 3 && std::getline(raw_in, line); ++i) three += line + "\n";
  WriteText(dir / "three_poses.txt", three);
  const CliResult no_gt =
      RunCli({"run", "--dataset", "images:" + (dir / "images").string(), "--intrinsics",
              "500,500,319.5,239.5", "--poses", (dir / "three_poses.txt").string(), "--raw-scale",
              (seq / "raw_scale.txt").string(), "--out", (dir / "a").string(), "--quiet"});
  EXPECT_EQ(no_gt.exit_code, 2) << no_gt.err;
  EXPECT_NE(no_gt.err.find("--raw-scale: expected --gt"), std::string::npos) << no_gt.err;
  WriteText(dir / "short_scale.txt", "1.0\n1.0\n");
  const CliResult short_file = RunCli(
      {"run", "--dataset", "kitti:" + seq.string(), "--poses", (seq / "poses_raw.txt").string(),
       "--gt", (seq / "poses_gt.txt").string(), "--raw-scale", (dir / "short_scale.txt").string(),
       "--out", (dir / "b").string(), "--quiet"});
  EXPECT_EQ(short_file.exit_code, 2) << short_file.err;
  EXPECT_NE(short_file.err.find("short_scale.txt: expected a raw scale for each of the"),
            std::string::npos)
      << short_file.err;
  EXPECT_FALSE(fs::exists(dir / "a"));
  EXPECT_FALSE(fs::exists(dir / "b"));
}

}  // namespace
}  // namespace sparseloop::test
