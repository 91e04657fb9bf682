#pragma once
// JSON serialisation of evaluation results (nlohmann::json). Values that are not computable are
// null. Key names are documented in docs/METRICS.md.
#include <nlohmann/json.hpp>

#include "sparseloop/eval/loops.h"
#include "sparseloop/eval/metrics.h"

namespace sparseloop {

nlohmann::json ToJson(const ErrorStatistics& stats, bool include_errors = false);
nlohmann::json ToJson(const AlignmentResult& alignment);
nlohmann::json ToJson(const KittiResult& kitti);
nlohmann::json ToJson(const RpeResult& rpe);
nlohmann::json ToJson(const LoopPrResult& loops);
// Full evaluation. Top-level flat keys: ate_rmse_m, ate_mean_m, ate_median_m, ate_max_m,
// rpe_trans_rmse, rpe_rot_rmse_deg, kitti_t_err_pct, kitti_r_err_deg_per_100m, plus nested
// "alignment", "ate", "rpe", "kitti" objects. Loop keys (loop_*) are added by the caller with
// AddLoopKeys.
nlohmann::json ToJson(const TrajectoryEvaluation& evaluation);
// What `sparseloop eval --json` writes for a trajectory (and Python's evaluate_trajectory):
// ToJson(evaluation) plus the evaluation pose by pose, for plots that show what was measured:
// "associated" {est_index, gt_index (rows of the files), est_time, gt_time, est_frame, gt_frame,
// ate_m}: one entry per associated pair, in estimate order; "aligned_positions": every estimate
// pose's position mapped by alignment.gt_from_est, in file order. `gt` and `est` are the
// trajectories `evaluation` was computed from (std::invalid_argument when their sizes differ).
nlohmann::json ToJson(const TrajectoryEvaluation& evaluation, const Trajectory& gt,
                      const Trajectory& est);
// Adds loop_precision, loop_recall, loop_recall_at_100p, loop_true_positives,
// loop_false_positives and a nested "loops" object (or nulls when `loops` is nullptr).
void AddLoopKeys(nlohmann::json& out, const LoopPrResult* loops);
// Loops scored by GT distance: AddLoopKeys over the correct and false detections, plus
// loop_false_accepted, loop_recall_at_100p_accepted, loop_trivial, loop_no_gt, loop_events,
// loop_events_detected, "loops_accepted" (as "loops", accepted detections only) and
// "loop_verdicts" (one of correct / false / trivial / no_gt per detection, input order).
void AddLoopKeys(nlohmann::json& out, const GtDistanceScore& score);

}  // namespace sparseloop
