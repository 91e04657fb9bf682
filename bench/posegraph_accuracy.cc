// Pose-graph accuracy numbers for docs/BENCHMARKS.md, as ONE JSON object on stdout.
//
//   posegraph_accuracy [--data DIR]
//   posegraph_accuracy --oracle RAW GT [--revisit M] [--min-gap KEYFRAMES] [--scales FILE]
//                      [--loop-sigma F] [--odometry-sigma F]
//
// DIR is the shared real-data folder (default: $SPARSELOOP_DATA, else the configured
// SPARSELOOP_DATA_DIR, i.e. ../shared/data next to the repository). Exit code 2 with a message on
// stderr when the data is absent or an argument is wrong.
//
// Reports, for each real-drift case of tests/support/loop_harness.h (KITTI 09 monocular VO,
// four EuRoC monocular VIO runs; loops from GT as a monocular vSLAM would measure them):
// raw ATE, corrected ATE with true loops, with 20 % false loops (default robust solve) and the
// same with plain least squares, loop counts and solve time; the true loops also on SE(3) and
// 4-DoF vertices. For the standard graphs in
// pose_graphs/: costs, iterations, time and status; for sphere2500 also the ATE against its GT.
//
// --oracle: the limit of loop correction on one raw trajectory (KITTI files associated by row,
// e.g. a render's poses_raw.txt / poses_gt.txt): EXACT loops from the GT at every revisit (GT
// closer than --revisit metres, default 10, at least --min-gap keyframes apart, default 100, one
// per query keyframe), one solve with all of them (no outlier rejection: they are exact) and, the
// `pcm_*` figures, one with the default options; prints raw and corrected ATE and KITTI t_err.
// What real loops cannot beat: the drift they do not observe. The loops' relative scale comes from
// --scales (one number per row: a render's raw_scale.txt, the simulated drift's exact scale) or,
// without it, from LocalScales (a windowed alignment, wrong where the scale drifts fast).
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string>
#include <utility>

#include <fmt/format.h>

#include "data_dir.h"
#include "loop_harness.h"
#include "program_main.h"
#include "sparseloop/core/timer.h"
#include "sparseloop/eval/metrics.h"
#include "sparseloop/posegraph/g2o.h"

namespace sparseloop {
namespace {

std::string Json(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : "null"; }

std::string SummaryJson(const PoseGraphSummary& s) {
  return fmt::format(
      "\"initial_cost\": {}, \"final_cost\": {}, \"iterations\": {}, \"solve_seconds\": {}, "
      "\"status\": \"{}\", \"converged\": {}",
      Json(s.initial_cost), Json(s.final_cost), s.iterations, Json(s.solve_seconds),
      ToString(s.status), s.status == PoseGraphStatus::kConverged ? "true" : "false");
}

std::string DriftCaseJson(const test::DriftCase& c, uint64_t seed) {
  std::mt19937_64 rng(seed);
  const test::HarnessLoops clean = test::MakeHarnessLoops(c.raw, c.gt, c.harness, rng);
  test::LoopHarnessOptions with_false = c.harness;
  with_false.outlier_fraction = 0.2;
  const test::HarnessLoops dirty = test::MakeHarnessLoops(c.raw, c.gt, with_false, rng);
  PoseGraphOptions plain;
  plain.rejection = OutlierRejection::kNone;
  const double raw_ate = test::AlignedAte(c.raw, c.gt);
  const auto r_clean =
      test::CorrectAndScore(c.raw, c.gt, clean.loops, PoseGraphOptions{}, c.odometry);
  const auto r_dirty =
      test::CorrectAndScore(c.raw, c.gt, dirty.loops, PoseGraphOptions{}, c.odometry);
  const auto r_plain = test::CorrectAndScore(c.raw, c.gt, dirty.loops, plain, c.odometry);
  // The same true loops on the metric vertex types (SE(3) for metric input, 4-DoF for
  // gravity-aligned VIO): the EuRoC VIO is metric, but its scale is off by a few per cent.
  const auto r_se3 = test::CorrectAndScore(c.raw, c.gt, clean.loops, PoseGraphOptions{}, c.odometry,
                                           VertexType::kSe3);
  const auto r_4dof = test::CorrectAndScore(c.raw, c.gt, clean.loops, PoseGraphOptions{},
                                            c.odometry, VertexType::kFourDof);
  std::vector<bool> rejected(dirty.loops.size(), false);
  for (size_t k : r_dirty.summary.rejected_loops) rejected[k] = true;
  size_t num_false = 0, accepted_true = 0, accepted_false = 0;
  for (size_t k = 0; k < dirty.loops.size(); ++k) {
    num_false += dirty.is_false[k];
    if (!rejected[k]) (dirty.is_false[k] ? accepted_false : accepted_true)++;
  }
  return fmt::format(
      "\"{}\": {{\"keyframes\": {}, \"raw_ate_m\": {}, \"clean\": {{\"loops\": {}, \"ate_m\": {}, "
      "\"ratio\": {}, \"solve_seconds\": {}}}, \"false_20pct\": {{\"loops_true\": {}, "
      "\"loops_false\": {}, \"accepted_true\": {}, \"accepted_false\": {}, \"ate_m\": {}, "
      "\"ratio\": {}, \"solve_seconds\": {}, \"pcm_seconds\": {}}}, \"false_20pct_plain_ls\": "
      "{{\"ate_m\": {}, \"ratio\": {}, \"solve_seconds\": {}}}, \"clean_se3\": {{\"ate_m\": {}, "
      "\"ratio\": {}}}, \"clean_four_dof\": {{\"ate_m\": {}, \"ratio\": {}}}}}",
      c.name, c.raw.size(), Json(raw_ate), clean.loops.size(), Json(r_clean.ate),
      Json(r_clean.ate / raw_ate), Json(r_clean.summary.solve_seconds),
      dirty.loops.size() - num_false, num_false, accepted_true, accepted_false, Json(r_dirty.ate),
      Json(r_dirty.ate / raw_ate), Json(r_dirty.summary.solve_seconds),
      Json(r_dirty.summary.rejection_seconds), Json(r_plain.ate), Json(r_plain.ate / raw_ate),
      Json(r_plain.summary.solve_seconds), Json(r_se3.ate), Json(r_se3.ate / raw_ate),
      Json(r_4dof.ate), Json(r_4dof.ate / raw_ate));
}

PoseGraphOptions PlainOptions(int max_iterations) {
  PoseGraphOptions options;
  options.rejection = OutlierRejection::kNone;
  options.max_iterations = max_iterations;
  return options;
}

double SphereAte(const PoseGraph& g, const PoseGraph& gt) {
  std::vector<Eigen::Vector3d> est, ref;
  for (int64_t id : g.VertexIds()) {
    est.push_back(g.Pose(id).translation);
    ref.push_back(gt.Pose(id).translation);
  }
  return Umeyama(est, ref, Alignment::kSE3).rms_residual;
}

double TErr(const TrajectoryEvaluation& e) {
  return e.kitti && e.kitti->t_err_pct ? *e.kitti->t_err_pct : NAN;
}

// One number per line; nullopt (with a message naming the file and line) on anything else.
std::optional<std::vector<double>> ReadScales(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) {
    std::cerr << "posegraph_accuracy: --scales " << path << ": cannot open\n";
    return std::nullopt;
  }
  std::vector<double> out;
  std::string line;
  for (int line_no = 1; std::getline(in, line); ++line_no) {
    char* end = nullptr;
    const double v = std::strtod(line.c_str(), &end);
    if (end == line.c_str() || !std::isfinite(v) || v <= 0) {
      std::cerr << "posegraph_accuracy: --scales " << path << " line " << line_no
                << ": expected one positive number, got '" << line << "'\n";
      return std::nullopt;
    }
    out.push_back(v);
  }
  return out;
}

int Oracle(const std::filesystem::path& raw_path, const std::filesystem::path& gt_path,
           double revisit_m, int64_t min_gap, const std::filesystem::path& scales_path,
           double sigma_factor, double odometry_factor) {
  const Trajectory raw = ReadTrajectory(raw_path);
  const Trajectory gt = ReadTrajectory(gt_path);
  if (raw.size() != gt.size() || raw.size() < 2) {
    std::cerr << "posegraph_accuracy --oracle: " << raw_path << " has " << raw.size() << " poses, "
              << gt_path << " " << gt.size() << " (need the same number, >= 2)\n";
    return 2;
  }
  std::optional<std::vector<double>> scales;
  if (!scales_path.empty()) {
    scales = ReadScales(scales_path);
    if (!scales) return 2;
    if (scales->size() != raw.size()) {
      std::cerr << "posegraph_accuracy: --scales " << scales_path << " has " << scales->size()
                << " lines, " << raw_path << " " << raw.size() << " poses (need one per pose)\n";
      return 2;
    }
  }
  std::vector<Sim3d> raw_kf, gt_kf;
  for (size_t i = 0; i < raw.size(); ++i) {
    raw_kf.emplace_back(raw.poses[i].world_from_cam);
    gt_kf.emplace_back(gt.poses[i].world_from_cam);
  }
  test::LoopHarnessOptions o;
  o.distance = revisit_m;
  o.min_gap = min_gap;
  o.query_stride = 1;
  o.scale_min_extent = 10.0;
  o.add_noise = false;
  o.translation_noise *= sigma_factor;  // the loops' information only (they are exact)
  o.rotation_noise_rad *= sigma_factor;
  o.scale_noise *= sigma_factor;
  std::mt19937_64 rng(1);
  const test::HarnessLoops loops =
      test::MakeHarnessLoops(raw_kf, gt_kf, o, rng, scales ? &*scales : nullptr);
  std::vector<int64_t> ids(raw_kf.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int64_t>(i);
  auto evaluate = [&](const PoseGraph& graph) {
    Trajectory corrected = raw;
    for (size_t i = 0; i < ids.size(); ++i)
      corrected.poses[i].world_from_cam = graph.Pose(ids[i]).ToRigid();
    return EvaluateTrajectory(gt, corrected);
  };
  // Exact loops need no outlier rejection: the limit is the solve with all of them. Beside it the
  // default options (PCM), which under strong drift reject exact loops too.
  OdometryWeighting odometry;
  odometry.translation_fraction *= odometry_factor;
  odometry.rotation_sigma_rad *= odometry_factor;
  odometry.scale_sigma *= odometry_factor;
  // (evaluation, loops rejected)
  auto solve = [&](OutlierRejection rejection) {
    PoseGraph graph = BuildOdometryGraph(ids, raw_kf, VertexType::kSim3, odometry);
    for (const auto& l : loops.loops) graph.AddLoop(l);
    PoseGraphOptions options;
    options.rejection = rejection;
    const PoseGraphSummary summary = graph.Optimize(options);
    return std::make_pair(evaluate(graph), summary.rejected_loops.size());
  };
  const TrajectoryEvaluation e_raw = EvaluateTrajectory(gt, raw);
  const TrajectoryEvaluation e_cor = solve(OutlierRejection::kNone).first;
  const auto [e_pcm, pcm_rejected] = solve(OutlierRejection::kPcm);
  std::cout << fmt::format(
      "{{\"keyframes\": {}, \"oracle_loops\": {}, \"exact_scales\": {}, \"raw_ate_m\": {}, "
      "\"corrected_ate_m\": {}, \"raw_t_err_pct\": {}, \"corrected_t_err_pct\": {}, "
      "\"pcm_corrected_ate_m\": {}, \"pcm_corrected_t_err_pct\": {}, \"pcm_rejected_loops\": "
      "{}}}\n",
      raw_kf.size(), loops.loops.size(), scales ? "true" : "false", Json(e_raw.ate.rmse),
      Json(e_cor.ate.rmse), Json(TErr(e_raw)), Json(TErr(e_cor)), Json(e_pcm.ate.rmse),
      Json(TErr(e_pcm)), pcm_rejected);
  return 0;
}

int Main(int argc, char** argv) {
  if (argc >= 4 && std::string(argv[1]) == "--oracle") {
    double revisit = 10.0;
    int64_t gap = 100;
    std::filesystem::path scales;
    double sigma = 1.0, odometry_sigma = 1.0;
    for (int i = 4; i + 1 < argc; i += 2) {
      const std::string a = argv[i];
      if (a == "--revisit") {
        revisit = std::atof(argv[i + 1]);
      } else if (a == "--min-gap") {
        gap = std::atoll(argv[i + 1]);
      } else if (a == "--scales") {
        scales = argv[i + 1];
      } else if (a == "--loop-sigma") {
        sigma = std::atof(argv[i + 1]);
      } else if (a == "--odometry-sigma") {
        odometry_sigma = std::atof(argv[i + 1]);
      } else {
        std::cerr << "posegraph_accuracy: unknown argument '" << a << "'\n";
        return 2;
      }
    }
    if (!(sigma > 0) || !(odometry_sigma > 0)) {
      std::cerr << "posegraph_accuracy: --loop-sigma and --odometry-sigma must be > 0\n";
      return 2;
    }
    return Oracle(argv[2], argv[3], revisit, gap, scales, sigma, odometry_sigma);
  }
  std::filesystem::path data = test::DataDir();
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--data" && i + 1 < argc) {
      data = argv[++i];
    } else if (arg == "--help" || arg == "-h") {
      std::cerr << "usage: posegraph_accuracy [--data DIR]   (prints one JSON object)\n";
      return 0;
    } else {
      std::cerr << "posegraph_accuracy: unknown argument '" << arg
                << "' (usage: posegraph_accuracy [--data DIR])\n";
      return 2;
    }
  }
  for (const char* needed :
       {"vslam_trajectories/kitti09_10/example_0/09.txt",
        "vslam_trajectories/euroc/MH_01/vio_mono_estimate.txt", "kitti_gt_poses/09.txt",
        "pose_graphs/parking-garage.g2o", "pose_graphs/sphere_bignoise_vertex3.g2o",
        "pose_graphs/sphere2500.txt", "pose_graphs/sphere2500_groundtruth.txt"}) {
    if (!std::filesystem::exists(data / needed)) {
      std::cerr << "posegraph_accuracy: real data not found: " << (data / needed)
                << "\n  pass --data DIR or set SPARSELOOP_DATA to the shared data folder\n";
      return 2;
    }
  }
  std::string out = "{\"drift\": {";
  uint64_t seed = 20261122 + 100;  // the seeds of tests/posegraph/drift_data_test.cc
  bool first = true;
  for (const test::DriftCase& c : test::LoadDriftCases(data)) {
    out += (first ? "" : ", ") + DriftCaseJson(c, seed++);
    first = false;
  }
  out += "}, \"graphs\": {";
  {
    PoseGraph g = ReadG2o(data / "pose_graphs/parking-garage.g2o");
    out += "\"parking-garage.g2o\": {" + SummaryJson(g.Optimize(PlainOptions(100))) + "}";
  }
  {
    PoseGraph g = ReadG2o(data / "pose_graphs/sphere_bignoise_vertex3.g2o");
    out +=
        ", \"sphere_bignoise_vertex3.g2o\": {" + SummaryJson(g.Optimize(PlainOptions(300))) + "}";
  }
  {
    PoseGraph g = ReadG2o(data / "pose_graphs/sphere2500.txt");
    const PoseGraph gt = ReadG2o(data / "pose_graphs/sphere2500_groundtruth.txt");
    const double before = SphereAte(g, gt);
    const PoseGraphSummary s = g.Optimize(PlainOptions(100));
    out += fmt::format(", \"sphere2500.txt\": {{{}, \"ate_before_m\": {}, \"ate_after_m\": {}}}",
                       SummaryJson(s), Json(before), Json(SphereAte(g, gt)));
  }
  out += "}}";
  std::cout << out << "\n";
  return 0;
}

}  // namespace
}  // namespace sparseloop

int main(int argc, char** argv) {
  return sparseloop::test::RunProgram("posegraph_accuracy", 2,
                                      [&] { return sparseloop::Main(argc, argv); });
}
