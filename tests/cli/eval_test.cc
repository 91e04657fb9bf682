// End-to-end tests of `sparseloop eval`.
#include <cmath>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "sparseloop/eval/metrics.h"
#include "sparseloop/io/trajectory_io.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

// RunCli() itself calls TempDir(), which empties the test's temp folder, so input fixtures live in
// a sibling folder that RunCli does not touch.
std::filesystem::path FixtureDir() {
  auto dir = TempDir();
  dir += "_fixtures";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

double Rel(double a, double b) { return std::abs(a - b) / std::max(std::abs(b), 1e-300); }

TEST(CliEval, KittiSequence00SiftAgreesWithLibrary) {
  SL_REQUIRE_DATA("kitti_gt_poses/00.txt");
  SL_REQUIRE_DATA("vslam_trajectories/kitti00/kitti_sift_flannmatch.txt");
  const auto gt = DataDir() / "kitti_gt_poses/00.txt";
  const auto est = DataDir() / "vslam_trajectories/kitti00/kitti_sift_flannmatch.txt";
  const auto json_path = TempDir() / "eval.json";
  const auto r = RunCli({"eval", "--gt", gt.string(), "--est", est.string(), "--align", "se3",
                         "--json", json_path.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("ATE"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("KITTI"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("positions only"), std::string::npos) << r.out;

  // The library on the same inputs (index association: neither file has timestamps).
  EvaluationOptions options;
  options.association.method = AssociationMethod::kIndex;
  options.alignment = Alignment::kSE3;
  const auto e = EvaluateTrajectory(ReadTrajectory(gt), ReadTrajectory(est), options);
  ASSERT_EQ(e.status, EvaluationStatus::kOk);
  ASSERT_TRUE(e.kitti && e.kitti->t_err_pct);

  // Printed per-segment table: one row per length with the library's numbers (6 decimals).
  for (const auto& p : e.kitti->per_length) {
    const std::string row =
        fmt::format("{:>8.0f}  {:>8}  {:>12.6f}", p.length, p.count, p.t_err_pct);
    EXPECT_NE(r.out.find(row), std::string::npos) << "missing row '" << row << "' in\n" << r.out;
  }
  EXPECT_NE(r.out.find(fmt::format("rmse {:.6f}", e.ate.rmse)), std::string::npos) << r.out;

  const auto j = ReadJson(json_path);
  for (const char* key :
       {"ate_rmse_m", "kitti_t_err_pct", "kitti_r_err_deg_per_100m", "loop_precision",
        "loop_recall", "loop_recall_at_100p", "ate", "rpe", "kitti", "alignment"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_LT(Rel(j["ate_rmse_m"].get<double>(), e.ate.rmse), 1e-12);
  EXPECT_LT(Rel(j["kitti_t_err_pct"].get<double>(), *e.kitti->t_err_pct), 1e-12);
  EXPECT_TRUE(j["kitti_r_err_deg_per_100m"].is_null());  // positions-only estimate
  EXPECT_TRUE(j["loop_precision"].is_null());
  EXPECT_EQ(j["num_associated"].get<size_t>(), 4541u);
  ASSERT_EQ(j["kitti"]["per_length"].size(), e.kitti->per_length.size());
  for (size_t k = 0; k < e.kitti->per_length.size(); ++k) {
    EXPECT_LT(Rel(j["kitti"]["per_length"][k]["t_err_pct"].get<double>(),
                  e.kitti->per_length[k].t_err_pct),
              1e-12);
  }
}

// 8 frames along x; frame 6 returns next to frame 0 and frame 7 next to frame 2.
void WriteHandMadePositions(const std::filesystem::path& path) {
  std::ofstream out(path);
  const double xs[] = {0, 10, 20, 30, 40, 50, 0.5, 20.2};
  for (int i = 0; i < 8; ++i) out << i << " " << xs[i] << " 0 0\n";
}

TEST(CliEval, LoopPrecisionRecall) {
  const auto dir = FixtureDir();
  WriteHandMadePositions(dir / "gt.txt");
  {
    std::ofstream out(dir / "loops.csv");
    out << "query,match,score,inliers\n"
        << "6,0,0.9,50\n"   // correct
        << "5,1,0.8,20\n";  // wrong
  }
  const auto json_path = dir / "out.json";
  // --derive-loops 1,3: GT pairs (6,0) and (7,2) -> precision 1/2, recall 1/2, R@100P 1/2.
  const auto r = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--est",
                         (dir / "gt.txt").string(), "--align", "none", "--derive-loops", "1,3",
                         "--loops", (dir / "loops.csv").string(), "--json", json_path.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("GT loops     2 pairs"), std::string::npos) << r.out;
  const auto j = ReadJson(json_path);
  EXPECT_DOUBLE_EQ(j["loop_precision"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(j["loop_recall"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(j["loop_recall_at_100p"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(j["ate_rmse_m"].get<double>(), 0.0);
  // Path 50 + 49.5 + 19.7 = 119.2 m: a single 100 m segment (frames 0 -> 7), error-free.
  EXPECT_EQ(j["kitti"]["num_segments"].get<size_t>(), 1u);
  EXPECT_DOUBLE_EQ(j["kitti_t_err_pct"].get<double>(), 0.0);
}

// --correct-distance: verdicts by GT distance (the benchmark's rule), as the library scores them.
TEST(CliEval, LoopsByGtDistanceWithTrivialAndAcceptedColumns) {
  const auto dir = FixtureDir();
  WriteHandMadePositions(dir / "gt.txt");
  {
    std::ofstream out(dir / "loops.csv");
    out << "query,match,score,accepted\n"
        << "6,0,0.9,1\n"   // 0.5 apart, 99.5 of path between: correct
        << "2,1,0.95,1\n"  // 10 apart (< 12), 10 of path between (< 20): trivial
        << "7,2,0.5,0\n"   // 0.2 apart: correct, not accepted
        << "5,1,0.8,1\n";  // 40 apart: false
  }
  const auto json_path = dir / "out.json";
  const auto r = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--derive-loops", "1,3",
                         "--min-path", "20", "--correct-distance", "12", "--loops",
                         (dir / "loops.csv").string(), "--json", json_path.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("1 trivial"), std::string::npos) << r.out;
  const auto j = ReadJson(json_path);
  EXPECT_EQ(j["loop_verdicts"],
            nlohmann::json::parse(R"(["correct", "trivial", "correct", "false"])"));
  EXPECT_EQ(j["loop_trivial"].get<int>(), 1);
  EXPECT_EQ(j["loop_true_positives"].get<int>(), 2);
  EXPECT_EQ(j["loop_false_positives"].get<int>(), 1);
  EXPECT_EQ(j["loop_false_accepted"].get<int>(), 1);
  // GT queries 6 and 7: 0.9 (6, correct), 0.8 (false): 1/2; accepted only the same.
  EXPECT_DOUBLE_EQ(j["loop_recall_at_100p"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(j["loop_recall_at_100p_accepted"].get<double>(), 0.5);
  EXPECT_EQ(j["loop_events"].get<int>(), 1);
  EXPECT_EQ(j["loop_events_detected"].get<int>(), 1);

  // Without GT loops: verdicts only; recall is not computable.
  const auto r2 = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--correct-distance", "12",
                          "--loops", (dir / "loops.csv").string(), "--json", json_path.string()});
  ASSERT_EQ(r2.exit_code, 0) << r2.err;
  EXPECT_TRUE(ReadJson(json_path)["loop_recall"].is_null());
  // Bad values name their flag.
  const auto bad = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--correct-distance", "-1",
                           "--loops", (dir / "loops.csv").string()});
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--correct-distance"), std::string::npos) << bad.err;
  const auto no_gt =
      RunCli({"eval", "--correct-distance", "5", "--loops", (dir / "loops.csv").string()});
  EXPECT_EQ(no_gt.exit_code, 2);
  EXPECT_NE(no_gt.err.find("--gt"), std::string::npos) << no_gt.err;
}

TEST(CliEval, MalformedInputExits2WithFileAndLine) {
  const auto dir = FixtureDir();
  WriteHandMadePositions(dir / "gt.txt");
  {
    std::ofstream out(dir / "bad.txt");
    out << "0 0 0 0\n1 1 0 0\n2 oops 0 0\n";
  }
  auto r = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--est", (dir / "bad.txt").string(),
                   "--est-format", "positions"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("bad.txt:3"), std::string::npos) << r.err;

  {
    std::ofstream out(dir / "loops.csv");
    out << "query,match,score\n6,0,0.9\n5,1\n";
  }
  r = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--est", (dir / "gt.txt").string(),
              "--align", "none", "--derive-loops", "1,3", "--loops", (dir / "loops.csv").string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("loops.csv:3"), std::string::npos) << r.err;

  r = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--est", (dir / "gt.txt").string(),
              "--derive-loops", "five"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--derive-loops"), std::string::npos) << r.err;

  r = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--est", (dir / "gt.txt").string(),
              "--align", "affine"});
  EXPECT_EQ(r.exit_code, 2);
}

TEST(CliEval, MissingFileExits2) {
  const auto dir = FixtureDir();
  WriteHandMadePositions(dir / "gt.txt");
  const auto r = RunCli(
      {"eval", "--gt", (dir / "gt.txt").string(), "--est", (dir / "does_not_exist.txt").string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("does_not_exist.txt"), std::string::npos) << r.err;
  EXPECT_EQ(RunCli({"eval", "--gt", (dir / "gt.txt").string()}).exit_code, 2);  // --est missing
}

// A file name that is not UTF-8 (byte 0xE9 of Latin-1) is written into the JSON as U+FFFD: the
// metrics were printed, then a JSON encoding error ended the command with exit 1 and no file.
TEST(CliEval, ANonUtf8FileNameStillGivesTheJson) {
  const auto dir = FixtureDir();
  const auto gt = dir / "gt\xe9.txt";
  WriteHandMadePositions(gt);
  const auto json = dir / "m.json";
  const auto r =
      RunCli({"eval", "--gt", gt.string(), "--est", gt.string(), "--json", json.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = ReadJson(json);
  EXPECT_NE(j.dump().find("gt\xEF\xBF\xBD.txt"), std::string::npos) << j.dump();
}

// The JSON carries the evaluation pose by pose: the associated pairs (rows, stamps, frames, ATE)
// and every estimate position as the alignment maps it into the GT frame, associated or not, so a
// plot needs no alignment or association of its own (scripts/report.py draws these).
TEST(CliEval, JsonCarriesTheAssociatedPairsAndTheAlignedEstimate) {
  const auto dir = FixtureDir();
  {
    // GT: a curve at 10 Hz. Estimate: the same positions at half the scale, shifted by (1, 2, 3)
    // and stamped 5 ms later, then one pose 50 ms after the last (no GT within --max-dt 0.02).
    std::ofstream gt(dir / "gt.txt"), est(dir / "est.txt");
    for (int i = 0; i < 12; ++i) {
      const double x = i, y = std::sin(i), z = 0.1 * i * i;
      gt << fmt::format("{} {} {} {} 0 0 0 1\n", 0.1 * i, x, y, z);
      est << fmt::format("{} {} {} {} 0 0 0 1\n", 0.1 * i + 0.005, 0.5 * x + 1, 0.5 * y + 2,
                         0.5 * z + 3);
    }
    est << fmt::format("{} 7 7 7 0 0 0 1\n", 1.1 + 0.05);
  }
  const auto json = dir / "m.json";
  const auto r = RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--est",
                         (dir / "est.txt").string(), "--json", json.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = ReadJson(json);
  EXPECT_NEAR(j["alignment"]["scale"].get<double>(), 2.0, 1e-9);
  const nlohmann::json& a = j["associated"];
  ASSERT_EQ(a["est_index"].size(), 12u) << a.dump();
  const nlohmann::json& aligned = j["aligned_positions"];
  ASSERT_EQ(aligned.size(), 13u);
  for (size_t k = 0; k < 12; ++k) {
    EXPECT_EQ(a["est_index"][k].get<size_t>(), k);
    EXPECT_EQ(a["gt_index"][k].get<size_t>(), k);
    EXPECT_EQ(a["gt_frame"][k].get<int64_t>(), static_cast<int64_t>(k));
    EXPECT_NEAR(a["gt_time"][k].get<double>(), 0.1 * k, 1e-12);
    EXPECT_NEAR(a["est_time"][k].get<double>(), 0.1 * k + 0.005, 1e-12);
    EXPECT_NEAR(a["ate_m"][k].get<double>(), 0.0, 1e-9);
    const double i = static_cast<double>(k);
    const double gt_position[3] = {i, std::sin(i), 0.1 * i * i};
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(aligned[k][c].get<double>(), gt_position[c], 1e-9);
  }
  // The unassociated pose, mapped too: gt = 2 (est - (1, 2, 3)).
  EXPECT_NEAR(aligned[12][0].get<double>(), 12.0, 1e-9);
  EXPECT_NEAR(aligned[12][1].get<double>(), 10.0, 1e-9);
  EXPECT_NEAR(aligned[12][2].get<double>(), 8.0, 1e-9);
}

// No estimate pose pairs with a ground-truth pose: exit 2 naming both files, not an empty table.
TEST(CliEval, NoAssociatedPairsExits2NamingBothFiles) {
  const auto dir = FixtureDir();
  {
    std::ofstream gt(dir / "gt_tum.txt");
    std::ofstream est(dir / "est_tum.txt");
    for (int i = 0; i < 8; ++i) {
      gt << i << " " << i << " 0 0 0 0 0 1\n";
      est << 1000 + i << " " << i << " 0 0 0 0 0 1\n";  // another time base
    }
  }
  const auto r = RunCli({"eval", "--gt", (dir / "gt_tum.txt").string(), "--est",
                         (dir / "est_tum.txt").string(), "--json", (dir / "m.json").string()});
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("--est " + (dir / "est_tum.txt").string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--gt " + (dir / "gt_tum.txt").string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--max-dt"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(".cc:"), std::string::npos) << r.err;  // no source path
  EXPECT_FALSE(std::filesystem::exists(dir / "m.json"));
}

// GT loop pairs naming frames past the end of --gt (another sequence, 1-based ids) are an error
// with the file and line; pairs written (earlier, later) score exactly as (later, earlier).
TEST(CliEval, GtLoopsOutOfRangeExit2AndReversedPairsScoreTheSame) {
  const auto dir = FixtureDir();
  WriteHandMadePositions(dir / "gt.txt");  // frames 0..7
  {
    std::ofstream out(dir / "loops.csv");
    out << "query,match,score\n6,0,0.9\n7,2,0.8\n5,1,0.7\n";
  }
  std::ofstream(dir / "later_first.txt") << "6 0\n7 2\n";
  std::ofstream(dir / "earlier_first.txt") << "# match query\n0 6\n2 7\n";
  std::ofstream(dir / "one_based.txt") << "7 1\n8 3\n";
  auto eval = [&](const char* gt_loops) {
    return RunCli({"eval", "--gt", (dir / "gt.txt").string(), "--est", (dir / "gt.txt").string(),
                   "--align", "none", "--gt-loops", (dir / gt_loops).string(), "--loops",
                   (dir / "loops.csv").string()});
  };
  const auto later_first = eval("later_first.txt");
  const auto earlier_first = eval("earlier_first.txt");
  ASSERT_EQ(later_first.exit_code, 0) << later_first.err;
  ASSERT_EQ(earlier_first.exit_code, 0) << earlier_first.err;
  EXPECT_NE(later_first.out.find("3 detections, 2 correct"), std::string::npos) << later_first.out;
  EXPECT_NE(earlier_first.out.find("3 detections, 2 correct"), std::string::npos)
      << earlier_first.out;
  const auto out_of_range = eval("one_based.txt");
  EXPECT_EQ(out_of_range.exit_code, 2);
  EXPECT_NE(out_of_range.err.find((dir / "one_based.txt").string() + ":2:"), std::string::npos)
      << out_of_range.err;
  EXPECT_NE(out_of_range.err.find("0..7"), std::string::npos) << out_of_range.err;
}

}  // namespace
}  // namespace sparseloop::test
