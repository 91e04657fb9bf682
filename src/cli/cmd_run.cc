// sparseloop run: detect loops on a dataset with raw vSLAM poses, optimise the pose graph, write
// the corrected trajectory; with --gt, evaluate raw and corrected side by side.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <unordered_map>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "cli/run_output.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/eval/json.h"
#include "sparseloop/eval/loop_nees.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/raw_scale.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/pipeline/pipeline.h"

namespace sparseloop::cli {
namespace {

// Every file `run` writes into --out.
const std::vector<std::string> kRunOutputFiles = {
    "trajectory.txt", "trajectory_kitti.txt", "poses_raw.txt", "poses_gt.txt", "loops.csv",
    "timings.csv",    "pr_curve.csv",         "gt_loops.txt",  "summary.json", "frames.csv"};

// The flags of `run` beyond the shared detector flags.
struct RunFlags {
  DetectorFlags detector;
  std::string gt_path, vertex, map_path, covariance_path, raw_scale_path;
  double gt_loop_distance = -1.0;  // -1: not given (the default)
  std::optional<int64_t> gt_min_gap;
  std::optional<double> gt_min_path;
};

void AddRunFlags(CLI::App& app, RunFlags* f) {
  AddDetectorFlags(app, &f->detector);
  app.add_option("--gt", f->gt_path, "Ground-truth trajectory (TUM/KITTI/EuRoC) for evaluation");
  app.add_option("--vertex", f->vertex,
                 "Pose-graph vertices: sim3 (monocular, default) | se3 (metric poses)")
      ->check(CLI::IsMember({"sim3", "se3"}));
  app.add_option("--odometry-covariance", f->covariance_path,
                 "The vSLAM's covariance of each keyframe step: 'key' + 21 (upper triangle) or 36 "
                 "numbers per line, key = timestamp (frame index for KITTI / images:); steps "
                 "without a line keep the odometry model (docs/FORMATS.md)");
  app.add_option("--map", f->map_path,
                 "Persistent map database (SQLite): earlier sessions in it are loaded for "
                 "multi-session loop closure, and this run is stored as a new session");
  app.add_option("--raw-scale", f->raw_scale_path,
                 "With --gt: the raw trajectory's scale per frame (raw units per GT unit; "
                 "raw_scale.txt of `sparseloop render`, read by default from a kitti: render "
                 "folder): each metric loop's pose is checked against the exact one, NEES in "
                 "summary.json loop_nees");
  app.add_option("--gt-loop-distance", f->gt_loop_distance,
                 "A detected loop is 'correct' when the GT positions of its frames are closer "
                 "than this (GT units; default: 5% of the GT path length, at most 10)");
  app.add_option("--gt-min-gap", f->gt_min_gap,
                 "GT revisits (loop recall): at least this many frames between the two frames "
                 "(default: the detector's search.exclude_recent, at least 1)")
      ->check(IntegerAtLeast(1));
  app.add_option("--gt-min-path", f->gt_min_path,
                 "GT revisits (loop recall): at least this much GT path between the two frames, "
                 "so that driving on is not a revisit (GT units; default: 4 x the GT loop "
                 "distance; 0: off)");
}

// Checked now, not after the run.
void CheckRunFlags(const RunFlags& f) {
  // No input written over first (the more important message), then the output folder itself.
  std::vector<NamedPath> inputs = {{"--config", f.detector.config},
                                   {"--poses", f.detector.poses},
                                   {"--gt", f.gt_path},
                                   {"--odometry-covariance", f.covariance_path},
                                   {"--raw-scale", f.raw_scale_path}};
  for (const NamedPath& map : MapFiles("--map", f.map_path)) inputs.push_back(map);
  CheckOutputsAreNotInputs(FilesIn("--out", f.detector.out, kRunOutputFiles), inputs);
  CheckOutputDirFlag("--out", f.detector.out, kRunOutputFiles);
  if (f.gt_min_path && !(std::isfinite(*f.gt_min_path) && *f.gt_min_path >= 0.0)) {
    throw std::invalid_argument(
        fmt::format("--gt-min-path must be a path length >= 0, got {}", *f.gt_min_path));
  }
  // At most 1e12 GT units: the GT revisits' default minimum path is 4 x this distance, which
  // must stay finite (1e308 failed after every frame was processed).
  if (f.gt_loop_distance != -1.0 && !(f.gt_loop_distance > 0.0 && f.gt_loop_distance <= 1e12)) {
    throw std::invalid_argument(fmt::format(
        "--gt-loop-distance must be a distance in (0, 1e12], got {}", f.gt_loop_distance));
  }
  // Raw poses: --poses, else the rosbag: dataset's pose topic (checked before anything is read).
  if (f.detector.poses.empty() && !DatasetHasPoseTopic(f.detector.dataset)) {
    throw std::invalid_argument(fmt::format(
        "--poses is required for '{}' (raw vSLAM poses; a rosbag: dataset may name a pose=TOPIC "
        "instead)",
        f.detector.dataset));
  }
}

using StepCovariances = std::vector<std::optional<Eigen::Matrix<double, 6, 6>>>;

// --odometry-covariance matched to the frames (empty without the flag).
StepCovariances ReadCovarianceFlag(const std::string& path, const Dataset& dataset, double max_dt) {
  if (path.empty()) return {};
  const auto rows = ReadStepCovariances(path);
  StepCovariances covariances;
  try {
    covariances = MatchStepCovariancesToFrames(dataset, rows, max_dt);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(fmt::format("--odometry-covariance {}: {}", path, e.what()));
  }
  const auto with = std::count_if(covariances.begin(), covariances.end(),
                                  [](const auto& c) { return c.has_value(); });
  Logger().info("run: the caller's odometry covariance for {} of {} frames ({})", with,
                covariances.size(), path);
  return covariances;
}

// The ground truth evaluated against: --gt, else the dataset's own (`gt_file` names it). An
// index-only GT (KITTI) gets each pose's frame timestamp, so that every file written shares one
// time base (TUM files, report, evo).
std::optional<Trajectory> GroundTruthFor(const std::string& gt_path, const Dataset& dataset,
                                         std::string* gt_file) {
  std::optional<Trajectory> gt;
  if (!gt_path.empty()) {
    gt = ReadTrajectory(gt_path);
    RequireOrientations("--gt", gt_path, *gt);
    *gt_file = gt_path;
    Logger().info("run: evaluating against --gt {} ({} poses){}", gt_path, gt->size(),
                  dataset.has_gt() ? fmt::format("; the dataset's ground truth {} is not used",
                                                 dataset.gt_path.string())
                                   : "");
  } else if (dataset.has_gt()) {
    gt = dataset.GtTrajectory();
    *gt_file = dataset.gt_path.string();
    Logger().info("run: evaluating against the dataset's ground truth {} ({} poses)", *gt_file,
                  gt->size());
  }
  return gt;
}

void GiveFrameTimestamps(const Dataset& dataset, Trajectory* gt) {
  if (gt->has_timestamps) return;
  std::unordered_map<int64_t, double> time_of_frame;
  for (const auto& f : dataset.frames) time_of_frame[f.index] = f.timestamp;
  bool all = true;
  for (const auto& p : gt->poses) all &= time_of_frame.count(p.frame) > 0;
  if (!all) return;
  for (auto& p : gt->poses) p.timestamp = time_of_frame.at(p.frame);
  gt->has_timestamps = true;
}

// summary.json: the solve, PCM's rejected loops, and each accepted loop against its own
// covariance after the solve (LoopResidualCheck).
void AddOptimizerJson(const PipelineResult& result, nlohmann::json& summary) {
  const PoseGraphSummary& o = result.optimizer;
  summary["optimizer"] = {{"status", ToString(o.status)},
                          {"initial_cost", o.initial_cost},
                          {"final_cost", o.final_cost},
                          {"iterations", o.iterations},
                          {"solves", o.solves},
                          {"loop_weight_scale", o.loop_weight_scale},
                          {"solve_seconds", o.solve_seconds},
                          {"rejection_seconds", o.rejection_seconds},
                          {"vertices", o.num_vertices},
                          {"solved_vertices", o.num_solved_vertices},
                          {"edges", o.num_edges}};
  nlohmann::json rejected = nlohmann::json::array();
  for (const auto& r : o.rejected_loop_ids) rejected.push_back({r.query, r.match});
  summary["rejected_loops"] = rejected;
  summary["accepted_loops"] =
      std::count(result.loop_accepted.begin(), result.loop_accepted.end(), true);
  nlohmann::json loop_checks = nlohmann::json::array();
  size_t inconsistent = 0;
  for (const LoopResidualCheck& c : o.loop_checks) {
    loop_checks.push_back({{"loop", c.loop},
                           {"query", c.query_id},
                           {"match", c.match_id},
                           {"chi2", c.chi2},
                           {"dof", c.dof},
                           {"threshold", c.threshold},
                           {"consistent", c.consistent},
                           {"translation_error", c.translation_error},
                           {"rotation_error_rad", c.rotation_error_rad},
                           {"log_scale_error", c.log_scale_error}});
    inconsistent += !c.consistent;
  }
  summary["loop_checks"] = loop_checks;
  summary["inconsistent_loops"] = inconsistent;
}

// The raw scale per frame for the loop NEES: --raw-scale, else raw_scale.txt of a kitti: render
// folder; none without --gt or without either.
std::optional<std::vector<double>> RawScaleFor(const RunFlags& flags, const Dataset& dataset,
                                               bool have_gt) {
  if (!have_gt) {
    if (!flags.raw_scale_path.empty())
      throw std::invalid_argument("--raw-scale: expected --gt as well (the exact loop poses)");
    return std::nullopt;
  }
  std::filesystem::path path = flags.raw_scale_path;
  if (path.empty()) {
    if (dataset.kind != "kitti") return std::nullopt;
    path = dataset.root / "raw_scale.txt";
    if (!std::filesystem::is_regular_file(path)) return std::nullopt;
  }
  std::vector<double> scale = ReadRawScale(path);
  if (scale.size() < dataset.frames.size()) {
    throw FileError(path.string(), 0,
                    fmt::format("a raw scale for each of the {} frames", dataset.frames.size()),
                    fmt::format("{} lines", scale.size()));
  }
  return scale;
}

// summary.json loop_nees: each accepted metric (PnP / Sim(3)) loop's pose against the exact one
// (GT poses, raw scales), with the information the graph gave it (eval/loop_nees.h).
nlohmann::json LoopNeesJson(const PipelineResult& result, const Trajectory& gt,
                            const std::vector<double>& raw_scale) {
  std::unordered_map<int64_t, size_t> gt_row;
  for (size_t i = 0; i < gt.poses.size(); ++i) gt_row[gt.poses[i].frame] = i;
  std::vector<LoopNees> checks;
  nlohmann::json rows = nlohmann::json::array();
  for (size_t k = 0; k < result.loops.size(); ++k) {
    const LoopResult& l = result.loops[k];
    const bool metric =
        l.pose_kind == RelativePoseKind::kSE3Metric || l.pose_kind == RelativePoseKind::kSim3;
    if (!result.loop_accepted[k] || !metric || !gt_row.count(l.query_id) ||
        !gt_row.count(l.match_id) || static_cast<size_t>(l.query_id) >= raw_scale.size() ||
        static_cast<size_t>(l.match_id) >= raw_scale.size())
      continue;
    const Sim3d exact = ExactLoopPose(
        gt.poses[gt_row[l.match_id]].world_from_cam, gt.poses[gt_row[l.query_id]].world_from_cam,
        raw_scale[static_cast<size_t>(l.match_id)], raw_scale[static_cast<size_t>(l.query_id)]);
    LoopNees c = ComputeLoopNees(l.match_from_query, result.loop_information[k], exact);
    c.query = l.query_id;
    c.match = l.match_id;
    checks.push_back(c);
    rows.push_back({c.query, c.match, ToString(l.pose_kind), c.dof, c.nees});
  }
  const LoopNeesSummary s = SummarizeLoopNees(checks);
  return {{"loops", s.loops},
          {"mean_nees_per_dof", s.mean_ratio},
          {"band_95", {s.band_low, s.band_high}},
          {"median_nees_per_dof", s.median_ratio},
          {"p95_nees_per_dof", s.p95_ratio},
          {"above_95", s.above_95},
          {"beyond_3_sigma", s.beyond_3_sigma},
          {"per_loop", rows},
          {"per_loop_columns", {"query", "match", "pose_kind", "dof", "nees"}}};
}

// Loop precision / recall against GT revisits derived from the GT poses (the loop-truth
// distance), over every query frame that has a GT partner: summary keys, pr_curve.csv and
// gt_loops.txt.
void AddGtLoopEvaluation(const RunFlags& flags, const PipelineOptions& options,
                         const PipelineResult& result, const Trajectory& gt, const LoopTruth& truth,
                         const std::filesystem::path& out, nlohmann::json& summary) {
  AddLoopTruthJson(summary, truth, result.loop_accepted);
  GtLoopOptions gl;
  gl.distance = truth.threshold;
  gl.min_gap = flags.gt_min_gap.value_or(std::max(1, options.detector.search.exclude_recent));
  gl.min_path = flags.gt_min_path.value_or(4.0 * gl.distance);
  const std::vector<LoopPair> gt_pairs = DeriveGtLoops(gt, gl);
  std::vector<Detection> detections;
  for (const LoopResult& l : result.loops) detections.push_back({l.query_id, l.match_id, l.score});
  const LoopPrResult pr = EvaluateLoops(detections, gt_pairs);
  // AddLoopKeys writes flat loop_* keys plus a nested "loops" object; "loops" is our count,
  // so the object goes under "loop_eval".
  nlohmann::json loop_eval;
  AddLoopKeys(loop_eval, &pr);
  for (auto& [key, value] : loop_eval.items()) {
    summary[key == "loops" ? "loop_eval" : key] = value;
  }
  summary["gt_revisits"] = {{"distance", gl.distance},
                            {"min_gap", gl.min_gap},
                            {"min_path", gl.min_path},
                            {"pairs", gt_pairs.size()}};
  WritePrCurveCsv(out / "pr_curve.csv", pr);
  WriteFileAtomically(out / "gt_loops.txt", [&](std::ostream& os) {
    os << "# query match: GT revisits (distance < " << gl.distance << ", gap >= " << gl.min_gap
       << " frames, GT path between >= " << gl.min_path << ")\n";
    for (const LoopPair& p : gt_pairs) os << p.query << ' ' << p.match << '\n';
  });
}

int RunRun(int argc, char** argv) {
  CLI::App app{"Detect loops, optimise the pose graph and write the corrected trajectory"};
  RunFlags run_flags;
  AddRunFlags(app, &run_flags);
  Parse(app, argc, argv);
  CheckRunFlags(run_flags);
  const DetectorFlags& flags = run_flags.detector;

  PipelineOptions options = PipelineOptionsFromFlags(flags);
  if (!run_flags.vertex.empty())
    options.vertex_type = run_flags.vertex == "sim3" ? VertexType::kSim3 : VertexType::kSe3;
  options.map_path = run_flags.map_path;
  options.Check();

  const Dataset dataset = OpenDatasetFromFlags(flags);
  const Trajectory raw = *RawPosesForFrames(flags.poses, dataset, options.raw_association_max_dt);
  const std::string raw_source = flags.poses.empty() ? dataset.raw_poses_source : flags.poses;
  const StepCovariances step_covariances =
      ReadCovarianceFlag(run_flags.covariance_path, dataset, options.raw_association_max_dt);
  std::string gt_file;  // the file evaluated against
  std::optional<Trajectory> gt = GroundTruthFor(run_flags.gt_path, dataset, &gt_file);
  const std::optional<std::vector<double>> raw_scale =
      RawScaleFor(run_flags, dataset, gt.has_value());
  // Every input is read: the folder now holds this run only.
  PrepareRunFolder(flags.out, "run", flags.dataset, kRunOutputFiles,
                   {flags.config, flags.poses, run_flags.gt_path, run_flags.map_path,
                    run_flags.covariance_path, run_flags.raw_scale_path});
  if (gt) GiveFrameTimestamps(dataset, &*gt);

  ProgressLine progress("run", flags.quiet);
  const PipelineResult result = RunPipeline(
      dataset, raw, step_covariances, options,
      [&](const PipelineProgress& p) { progress.Update(p.frames_done, p.frames_total, p.loops); });
  progress.Finish();

  const std::filesystem::path out = ResolvedPath(flags.out);  // DIR/missing/.. is DIR
  std::filesystem::create_directories(out);
  WriteTrajectory(out / "trajectory.txt", result.corrected, TrajectoryFormat::kTum);
  WriteTrajectory(out / "trajectory_kitti.txt", result.corrected, TrajectoryFormat::kKitti);
  // Named as `sparseloop render` names them, so `sparseloop report` finds all three.
  WriteTrajectory(out / "poses_raw.txt", result.raw, TrajectoryFormat::kTum);
  if (gt) WriteTrajectory(out / "poses_gt.txt", *gt, TrajectoryFormat::kTum);

  std::optional<LoopTruth> truth;
  if (gt) {
    std::vector<LoopPair> pairs;
    for (const LoopResult& l : result.loops) pairs.push_back({l.query_id, l.match_id});
    truth = ClassifyLoopsByGtDistance(pairs, *gt, run_flags.gt_loop_distance,
                                      {&raw, options.raw_association_max_dt});
  }
  {
    // In-session loops first (accepted / correct known), then loops into earlier map sessions.
    std::vector<LoopResult> rows = result.loops;
    rows.insert(rows.end(), result.cross_session_loops.begin(), result.cross_session_loops.end());
    WriteLoopsCsv(out / "loops.csv", rows, &result.loop_accepted, truth ? &*truth : nullptr,
                  ImageNamesByFrame(dataset));
  }
  WriteTimingsCsv(out / "timings.csv", result.frame_results);
  WriteFramesCsv(out / "frames.csv", result.frame_results);

  nlohmann::json summary = DetectionSummaryJson(result, result.loops.size());
  summary["command"] = "run";
  summary["dataset"] = flags.dataset;
  summary["poses_file"] = raw_source;  // --poses, or the rosbag: pose topic
  if (gt) summary["gt_file"] = gt_file;
  summary["skipped_frames"] = result.skipped_frames;
  if (!run_flags.covariance_path.empty()) {
    summary["odometry_covariance"] = {{"file", run_flags.covariance_path},
                                      {"steps", result.caller_covariance_steps}};
  }
  summary["cross_session_loops"] = result.cross_session_loops.size();
  if (!run_flags.map_path.empty()) {
    summary["map"] = {{"path", run_flags.map_path},
                      {"session", result.map_session},
                      {"prior_keyframes", result.prior_keyframes}};
  }
  AddOptimizerJson(result, summary);
  if (truth) AddGtLoopEvaluation(run_flags, options, result, *gt, *truth, out, summary);
  if (gt && raw_scale) summary["loop_nees"] = LoopNeesJson(result, *gt, *raw_scale);
  summary["config"] = ConfigToJson(options);

  std::optional<TrajectoryEvaluation> eval_raw, eval_corrected;
  if (gt) {
    EvaluationOptions eo;
    eo.alignment = options.vertex_type == VertexType::kSim3 ? Alignment::kSim3 : Alignment::kSE3;
    eo.association.method = gt->has_timestamps && raw.has_timestamps ? AssociationMethod::kTimestamp
                                                                     : AssociationMethod::kIndex;
    eval_raw = EvaluateTrajectory(*gt, result.raw, eo);
    eval_corrected = EvaluateTrajectory(*gt, result.corrected, eo);
    summary["eval"] = {{"raw", ToJson(*eval_raw)}, {"corrected", ToJson(*eval_corrected)}};
  }
  WriteFileAtomically(out / "summary.json", [&](std::ostream& os) { os << JsonText(summary); });

  PrintRunSummary(std::cout, summary, eval_raw ? &*eval_raw : nullptr,
                  eval_corrected ? &*eval_corrected : nullptr);
  std::cout << "wrote " << (std::filesystem::path(flags.out) / "trajectory.txt").string()
            << ", trajectory_kitti.txt, loops.csv, summary.json\n";
  return 0;
}

}  // namespace

SPARSELOOP_REGISTER_COMMAND("run", "detect loops, optimise, write the corrected trajectory",
                            RunRun);

}  // namespace sparseloop::cli
