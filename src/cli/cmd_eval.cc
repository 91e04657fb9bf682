// sparseloop eval: trajectory metrics (ATE, RPE, KITTI devkit) and loop precision/recall.
// Parses arguments, calls the eval library, prints a table and optionally writes JSON.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "sparseloop/core/check.h"
#include "sparseloop/eval/json.h"
#include "sparseloop/eval/loops.h"
#include "sparseloop/eval/metrics.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/loop_pairs.h"
#include "sparseloop/io/trajectory_io.h"

namespace sparseloop::cli {

namespace {

// "DIST,GAP" -> GtLoopOptions (std::invalid_argument, i.e. exit 2, when malformed).
GtLoopOptions ParseDeriveLoops(const std::string& spec) {
  const auto comma = spec.find(',');
  const std::string dist = spec.substr(0, comma);
  const std::string gap = comma == std::string::npos ? std::string() : spec.substr(comma + 1);
  GtLoopOptions options;
  bool ok = comma != std::string::npos && !dist.empty() && !gap.empty();
  if (ok) {
    try {
      size_t used_dist = 0;
      size_t used_gap = 0;
      options.distance = std::stod(dist, &used_dist);
      options.min_gap = std::stoll(gap, &used_gap);
      ok = used_dist == dist.size() && used_gap == gap.size();
    } catch (const std::exception&) {
      ok = false;
    }
  }
  SL_CHECK_MSG(ok, "--derive-loops expects DIST,GAP (metres,frames, e.g. 5,100), got '{}'", spec);
  return options;
}

std::string Num(double v) { return fmt::format("{:.6f}", v); }
std::string Num(const std::optional<double>& v) { return v ? Num(*v) : std::string("n/a"); }

void PrintStats(const std::string& name, const ErrorStatistics& s, const std::string& unit) {
  if (s.count == 0) {
    std::cout << fmt::format("{:<14} n/a (no pairs)\n", name);
    return;
  }
  std::cout << fmt::format(
      "{:<14} rmse {}  mean {}  median {}  std {}  min {}  max {}  {} (n={})\n", name, Num(s.rmse),
      Num(s.mean), Num(s.median), Num(s.std), Num(s.min), Num(s.max), unit, s.count);
}

void PrintTrajectoryTable(const TrajectoryEvaluation& e, const EvaluationOptions& options,
                          const std::string& est_path, const Trajectory& est,
                          const std::string& gt_path, const Trajectory& gt);

}  // namespace

namespace {

struct EvalFlags {
  std::string gt_path, est_path, gt_format = "auto", est_format = "auto", align = "sim3";
  std::string associate = "auto", gt_loops_path, derive_loops, loops_path, json_path;
  std::string frames_path;  // frames.csv of run / detect: search-area coverage of the GT loops
  std::string rpe_unit = "frames";
  EvaluationOptions options;
  GtLoopOptions gt_loop_options;
  LoopEvalOptions loop_options;
  double correct_distance = 0.0;  // > 0: loops scored by GT distance (ScoreLoopsByGtDistance)
  bool trajectories() const { return !est_path.empty(); }
  bool by_distance() const { return correct_distance != 0.0; }
};

void AddEvalFlags(CLI::App& app, EvalFlags* f) {
  app.add_option("--gt", f->gt_path,
                 "ground-truth trajectory file (with --est: trajectory metrics)");
  app.add_option("--est", f->est_path, "estimated trajectory file (needs --gt)");
  app.add_option("--gt-format", f->gt_format, "auto|tum|kitti|euroc|positions")
      ->capture_default_str();
  app.add_option("--est-format", f->est_format, "auto|tum|kitti|euroc|positions")
      ->capture_default_str();
  app.add_option("--align", f->align, "alignment of est to gt: sim3|se3|none (monocular: sim3)")
      ->capture_default_str();
  app.add_option("--associate", f->associate,
                 "time|index|auto (auto: time when both files carry timestamps, else index)")
      ->capture_default_str();
  app.add_option("--max-dt", f->options.association.max_dt,
                 "largest timestamp difference for time association, seconds")
      ->capture_default_str();
  app.add_option("--rpe-delta", f->options.rpe.delta, "RPE pair distance (frames or metres)")
      ->capture_default_str();
  app.add_option("--rpe-unit", f->rpe_unit, "frames|m")->capture_default_str();
  auto* gt_loops_opt = app.add_option("--gt-loops", f->gt_loops_path,
                                      "ground-truth loop pairs file ('i j' per line)");
  auto* derive_opt = app.add_option("--derive-loops", f->derive_loops,
                                    "derive GT loops from gt poses: DIST,GAP (metres, frames)");
  gt_loops_opt->excludes(derive_opt);
  app.add_option("--view-angle", f->gt_loop_options.max_view_angle_deg,
                 "with --derive-loops: max angle between viewing directions, degrees")
      ->capture_default_str();
  app.add_option("--min-path", f->gt_loop_options.min_path,
                 "with --derive-loops: least GT path between the two frames of a GT loop (GT "
                 "units); with --correct-distance also the path below which a correct loop is "
                 "trivial (left out)")
      ->capture_default_str();
  app.add_option("--correct-distance", f->correct_distance,
                 "score loops by GT distance (needs --gt): a loop is correct when the GT "
                 "positions of its frames are closer than this (GT units), instead of matching "
                 "GT pairs");
  app.add_option("--loops", f->loops_path, "detector loops.csv (columns query,match,score,...)");
  app.add_option("--frame-tolerance", f->loop_options.frame_tolerance,
                 "allowed |match - gt match| in frames for a correct loop")
      ->capture_default_str();
  app.add_option("--frames", f->frames_path,
                 "frames.csv of run / detect: fraction of GT loop queries whose GT match was in "
                 "the search area (its area column; needs GT loops)");
  app.add_option("--json", f->json_path, "write all results as JSON to this file (atomically)");
}

// Everything checked that can be before a file is read; an invalid value names its flag.
void CheckEvalFlags(EvalFlags* f) {
  CheckOutputsAreNotInputs({{"--json", f->json_path}}, {{"--gt", f->gt_path},
                                                        {"--est", f->est_path},
                                                        {"--gt-loops", f->gt_loops_path},
                                                        {"--loops", f->loops_path},
                                                        {"--frames", f->frames_path}});
  if (!f->json_path.empty()) CheckOutputFileFlag("--json", f->json_path);
  f->options.alignment = ParseAlignment(f->align);
  SL_CHECK_MSG(f->rpe_unit == "frames" || f->rpe_unit == "m",
               "--rpe-unit must be frames or m, got '{}'", f->rpe_unit);
  f->options.rpe.unit = f->rpe_unit == "m" ? RpeUnit::kMeters : RpeUnit::kFrames;
  if (!f->derive_loops.empty()) {
    const GtLoopOptions from_flags = f->gt_loop_options;
    f->gt_loop_options = ParseDeriveLoops(f->derive_loops);
    f->gt_loop_options.max_view_angle_deg = from_flags.max_view_angle_deg;
    f->gt_loop_options.min_path = from_flags.min_path;
  }
  SL_CHECK_MSG(!f->by_distance() || (std::isfinite(f->correct_distance) && f->correct_distance > 0),
               "--correct-distance must be a distance > 0, got {}", f->correct_distance);
  SL_CHECK_MSG(!f->by_distance() || (!f->gt_path.empty() && !f->loops_path.empty()),
               "--correct-distance needs --gt (the GT positions) and --loops (what to score)");
  SL_CHECK_MSG(f->loops_path.empty() || !f->gt_loops_path.empty() || !f->derive_loops.empty() ||
                   f->by_distance(),
               "--loops needs ground-truth loops (--gt-loops FILE or --derive-loops DIST,GAP) "
               "or --correct-distance D with --gt (verdicts by GT distance)");
  // Trajectory metrics need --gt and --est; loops alone need --loops and --gt-loops.
  SL_CHECK_MSG(!f->trajectories() || !f->gt_path.empty(),
               "--est needs --gt (the ground truth to compare with)");
  SL_CHECK_MSG(f->trajectories() || !f->loops_path.empty() || !f->frames_path.empty(),
               "nothing to evaluate: give --gt and --est (trajectory metrics), and/or --loops with "
               "--gt-loops (loop precision/recall; without trajectories)");
  SL_CHECK_MSG(f->frames_path.empty() || !f->gt_loops_path.empty() || !f->derive_loops.empty(),
               "--frames needs ground-truth loops (--gt-loops FILE or --derive-loops DIST,GAP "
               "with --gt)");
  SL_CHECK_MSG(f->derive_loops.empty() || !f->gt_path.empty(),
               "--derive-loops needs --gt (GT loops are derived from its poses)");
}

// The association rule (auto: by time when both files carry timestamps) and the option checks.
void CheckEvalOptions(const Trajectory& gt, const Trajectory& est, EvalFlags* f) {
  if (f->associate == "auto") {
    f->options.association.method = gt.has_timestamps && est.has_timestamps
                                        ? AssociationMethod::kTimestamp
                                        : AssociationMethod::kIndex;
  } else {
    f->options.association.method = ParseAssociationMethod(f->associate);
  }
  CheckNamingFlags({{"max_dt", "--max-dt"},
                    {"RPE delta", "--rpe-delta"},
                    {"max_view_angle_deg", "--view-angle"},
                    {"frame_tolerance", "--frame-tolerance"},
                    {"GT loop distance", "--derive-loops DIST"},
                    {"GT loop min_gap", "--derive-loops GAP"},
                    {"GT loop min_path", "--min-path"}},
                   [&] {
                     f->options.Check();
                     f->loop_options.Check();
                     if (!f->derive_loops.empty()) f->gt_loop_options.Check();
                   });
}

// --gt-loops (pairs must name frames of --gt: ids past its last frame are an error with the
// line) or --derive-loops; nothing without either.
std::optional<std::vector<LoopPair>> GtLoopsFor(const EvalFlags& f, const Trajectory& gt) {
  if (!f.gt_loops_path.empty()) {
    LoopPairReadOptions read_options;  // without --gt: no range to check
    for (const StampedPose& p : gt.poses)
      read_options.num_frames = std::max(read_options.num_frames.value_or(0), p.frame + 1);
    return ReadLoopPairs(f.gt_loops_path, read_options);
  }
  if (!f.derive_loops.empty()) return DeriveGtLoops(gt, f.gt_loop_options);
  return std::nullopt;
}

// The loops scored as the flags ask: against GT pairs, or by GT distance (--correct-distance).
struct LoopScores {
  std::optional<LoopPrResult> by_pairs;
  std::optional<GtDistanceScore> by_distance;
  const LoopPrResult* all() const { return by_pairs ? &*by_pairs : &by_distance->all; }
};

std::optional<LoopScores> ScoreLoops(const EvalFlags& f, const Trajectory& gt,
                                     const std::vector<LoopPair>& gt_loops) {
  if (f.loops_path.empty()) return std::nullopt;
  const std::vector<Detection> detections = ReadDetections(f.loops_path);
  LoopScores scores;
  if (!f.by_distance()) {
    scores.by_pairs = EvaluateLoops(detections, gt_loops, f.loop_options);
    return scores;
  }
  GtDistanceScoringOptions options;
  options.correct_distance = f.correct_distance;
  options.trivial_path = f.gt_loop_options.min_path;
  scores.by_distance = ScoreLoopsByGtDistance(detections, gt_loops, gt, options);
  return scores;
}

void WriteEvalJson(const EvalFlags& f, const Trajectory& gt, const Trajectory& est,
                   const TrajectoryEvaluation& e,
                   const std::optional<std::vector<LoopPair>>& gt_loops,
                   const std::optional<LoopScores>& loops,
                   const std::optional<AreaCoverage>& coverage) {
  const auto path_or_null = [](const std::string& p) {
    return p.empty() ? nlohmann::json(nullptr) : nlohmann::json(p);
  };
  nlohmann::json j = f.trajectories() ? ToJson(e, gt, est) : nlohmann::json::object();
  j["gt_file"] = path_or_null(f.gt_path);
  j["est_file"] = path_or_null(f.est_path);
  if (f.trajectories()) j["association"] = ToString(f.options.association.method);
  j["loops_file"] = path_or_null(f.loops_path);
  j["gt_loops_file"] = path_or_null(f.gt_loops_path);
  j["gt_loop_pairs"] = gt_loops ? nlohmann::json(gt_loops->size()) : nlohmann::json(nullptr);
  if (loops && loops->by_distance) {
    j["correct_distance"] = f.correct_distance;
    AddLoopKeys(j, *loops->by_distance);
  } else {
    AddLoopKeys(j, loops ? loops->all() : nullptr);
  }
  if (coverage) {
    j["search_area"] = {{"frames_file", f.frames_path},
                        {"gt_queries", coverage->queries},
                        {"covered", coverage->covered},
                        {"coverage", coverage->fraction ? nlohmann::json(*coverage->fraction)
                                                        : nlohmann::json(nullptr)},
                        {"mean_candidates", coverage->mean_candidates}};
  }
  WriteFileAtomically(f.json_path, [&](std::ostream& out) { out << JsonText(j); });
  std::cout << "wrote " << f.json_path << "\n";
}

}  // namespace

int RunEval(int argc, char** argv) {
  CLI::App app{
      "Evaluate an estimated trajectory against ground truth (ATE, RPE, KITTI) and "
      "loop detections against ground-truth loops (precision/recall)"};
  EvalFlags f;
  AddEvalFlags(app, &f);
  Parse(app, argc, argv);
  CheckEvalFlags(&f);

  const Trajectory gt = f.gt_path.empty()
                            ? Trajectory()
                            : ReadTrajectory(f.gt_path, ParseTrajectoryFormat(f.gt_format));
  const Trajectory est = f.trajectories()
                             ? ReadTrajectory(f.est_path, ParseTrajectoryFormat(f.est_format))
                             : Trajectory();
  CheckEvalOptions(gt, est, &f);
  const EvaluationOptions& options = f.options;
  const TrajectoryEvaluation e =
      f.trajectories() ? EvaluateTrajectory(gt, est, options) : TrajectoryEvaluation();
  if (f.trajectories() && e.status == EvaluationStatus::kNoAssociation) {
    const std::string how =
        options.association.method == AssociationMethod::kTimestamp
            ? fmt::format("by timestamp within --max-dt {} s", options.association.max_dt)
            : "by frame index";
    throw std::invalid_argument(fmt::format(
        "no pose of --est {} ({} poses) could be associated with a pose of --gt {} ({} poses) "
        "{}: nothing to evaluate",
        f.est_path, est.size(), f.gt_path, gt.size(), how));
  }

  const std::optional<std::vector<LoopPair>> gt_loops = GtLoopsFor(f, gt);
  const std::optional<LoopScores> loops =
      ScoreLoops(f, gt, gt_loops.value_or(std::vector<LoopPair>()));

  // ---- table ----
  if (f.trajectories()) PrintTrajectoryTable(e, options, f.est_path, est, f.gt_path, gt);
  if (gt_loops) std::cout << fmt::format("GT loops     {} pairs\n", gt_loops->size());
  if (loops) {
    const LoopPrResult& all = *loops->all();
    std::cout << fmt::format(
        "Loops        {} detections, {} correct, precision {}  recall {}  recall@100%P {}\n",
        all.num_detections, all.true_positives, Num(all.precision), Num(all.recall),
        Num(all.recall_at_100p));
    if (loops->by_distance) {
      const GtDistanceScore& s = *loops->by_distance;
      std::cout << fmt::format(
          "  by GT distance < {}: {} trivial, {} without GT; accepted {} ({} false), "
          "recall@100%P {}; GT events {} ({} detected)\n",
          f.correct_distance, s.trivial, s.no_gt, s.accepted.num_detections,
          s.accepted.false_positives, Num(s.accepted.recall_at_100p), s.events, s.events_detected);
    }
  }
  std::optional<AreaCoverage> coverage;
  if (!f.frames_path.empty() && gt_loops) {
    coverage = SearchAreaCoverage(*gt_loops, ReadSearchAreas(f.frames_path));
    std::cout << fmt::format(
        "Search area  GT match in the area for {} of {} GT loop queries ({}), mean {:.1f} "
        "candidates\n",
        coverage->covered, coverage->queries, Num(coverage->fraction), coverage->mean_candidates);
  }
  if (!f.json_path.empty()) WriteEvalJson(f, gt, est, e, gt_loops, loops, coverage);
  return 0;
}

namespace {

void PrintTrajectoryTable(const TrajectoryEvaluation& e, const EvaluationOptions& options,
                          const std::string& est_path, const Trajectory& est,
                          const std::string& gt_path, const Trajectory& gt) {
  std::cout << fmt::format("estimate     {} ({} poses{})\n", est_path, est.size(),
                           est.has_rotation ? "" : ", positions only");
  std::cout << fmt::format("ground truth {} ({} poses)\n", gt_path, gt.size());
  std::cout << fmt::format("associated   {} pairs by {}\n", e.association.pairs.size(),
                           ToString(options.association.method));
  std::cout << fmt::format("alignment    {} ({}), scale {:.6f}, rms residual {} m\n",
                           ToString(e.alignment.type), ToString(e.alignment.status),
                           e.alignment.gt_from_est.scale, Num(e.alignment.rms_residual));
  PrintStats("ATE [m]", e.ate, "m");
  if (e.rpe) {
    std::cout << fmt::format("RPE over {} {}:\n", options.rpe.delta, ToString(options.rpe.unit));
    PrintStats("  translation", e.rpe->translation, "m");
    if (e.rpe->rotation_deg) {
      PrintStats("  rotation", *e.rpe->rotation_deg, "deg");
    } else {
      std::cout << "  rotation      n/a (positions-only trajectory)\n";
    }
  }
  if (e.kitti) {
    std::cout << fmt::format("KITTI        t_err {} %  r_err {} deg/100m  ({} segments)\n",
                             Num(e.kitti->t_err_pct), Num(e.kitti->r_err_deg_per_100m),
                             e.kitti->num_segments);
    if (!e.kitti->per_length.empty()) {
      std::cout << fmt::format("  {:>8}  {:>8}  {:>12}  {:>18}\n", "length_m", "segments",
                               "t_err_pct", "r_err_deg_per_100m");
      for (const auto& p : e.kitti->per_length) {
        std::cout << fmt::format("  {:>8.0f}  {:>8}  {:>12}  {:>18}\n", p.length, p.count,
                                 Num(p.t_err_pct), Num(p.r_err_deg_per_100m));
      }
    }
  }
}

}  // namespace

SPARSELOOP_REGISTER_COMMAND("eval",
                            "trajectory metrics (ATE/RPE/KITTI) and loop P/R vs ground truth",
                            RunEval);

}  // namespace sparseloop::cli
