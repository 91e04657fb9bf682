#include "sparseloop/eval/json.h"

#include "sparseloop/core/check.h"

namespace sparseloop {

namespace {

template <typename T>
nlohmann::json OrNull(const std::optional<T>& value) {
  return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

}  // namespace

nlohmann::json ToJson(const ErrorStatistics& stats, bool include_errors) {
  nlohmann::json j;
  j["count"] = stats.count;
  if (stats.count == 0) {
    for (const char* key : {"rmse", "mean", "median", "std", "min", "max"}) j[key] = nullptr;
  } else {
    j["rmse"] = stats.rmse;
    j["mean"] = stats.mean;
    j["median"] = stats.median;
    j["std"] = stats.std;
    j["min"] = stats.min;
    j["max"] = stats.max;
  }
  if (include_errors) j["errors"] = stats.errors;
  return j;
}

nlohmann::json ToJson(const AlignmentResult& alignment) {
  nlohmann::json j;
  j["type"] = ToString(alignment.type);
  j["status"] = ToString(alignment.status);
  j["num_points"] = alignment.num_points;
  j["rms_residual"] = alignment.rms_residual;
  const Sim3d& t = alignment.gt_from_est;
  j["scale"] = t.scale;
  j["rotation_xyzw"] = {t.rotation.x(), t.rotation.y(), t.rotation.z(), t.rotation.w()};
  j["translation"] = {t.translation.x(), t.translation.y(), t.translation.z()};
  return j;
}

nlohmann::json ToJson(const KittiResult& kitti) {
  nlohmann::json j;
  j["status"] = kitti.status == KittiStatus::kOk ? "ok" : "no_segments";
  j["num_segments"] = kitti.num_segments;
  j["t_err_pct"] = OrNull(kitti.t_err_pct);
  j["r_err_deg_per_100m"] = OrNull(kitti.r_err_deg_per_100m);
  nlohmann::json per = nlohmann::json::array();
  for (const auto& p : kitti.per_length) {
    per.push_back({{"length_m", p.length},
                   {"count", p.count},
                   {"t_err_pct", p.t_err_pct},
                   {"r_err_deg_per_100m", OrNull(p.r_err_deg_per_100m)}});
  }
  j["per_length"] = per;
  return j;
}

nlohmann::json ToJson(const RpeResult& rpe) {
  nlohmann::json j;
  j["translation"] = ToJson(rpe.translation);
  j["rotation_deg"] = rpe.rotation_deg ? ToJson(*rpe.rotation_deg) : nlohmann::json(nullptr);
  return j;
}

nlohmann::json ToJson(const LoopPrResult& loops) {
  nlohmann::json j;
  j["num_detections"] = loops.num_detections;
  j["true_positives"] = loops.true_positives;
  j["false_positives"] = loops.false_positives;
  j["num_gt_pairs"] = loops.num_gt_pairs;
  j["num_gt_queries"] = loops.num_gt_queries;
  j["recalled_queries"] = loops.recalled_queries;
  j["precision"] = OrNull(loops.precision);
  j["recall"] = OrNull(loops.recall);
  j["recall_at_100p"] = OrNull(loops.recall_at_100p);
  nlohmann::json curve = nlohmann::json::array();
  for (const auto& p : loops.curve) {
    curve.push_back({{"threshold", p.threshold},
                     {"detections", p.detections},
                     {"true_positives", p.true_positives},
                     {"precision", p.precision},
                     {"recall", p.recall}});
  }
  j["curve"] = curve;
  return j;
}

nlohmann::json ToJson(const TrajectoryEvaluation& e) {
  nlohmann::json j;
  const bool ok = e.status == EvaluationStatus::kOk;
  j["status"] = ToString(e.status);
  j["num_est_poses"] = e.num_est_poses;
  j["num_gt_poses"] = e.num_gt_poses;
  j["num_associated"] = e.association.pairs.size();
  j["rotation_evaluated"] = e.rotation_evaluated;
  j["alignment"] = ToJson(e.alignment);
  j["ate"] = ToJson(e.ate);
  j["ate_rmse_m"] = ok ? nlohmann::json(e.ate.rmse) : nlohmann::json(nullptr);
  j["ate_mean_m"] = ok ? nlohmann::json(e.ate.mean) : nlohmann::json(nullptr);
  j["ate_median_m"] = ok ? nlohmann::json(e.ate.median) : nlohmann::json(nullptr);
  j["ate_max_m"] = ok ? nlohmann::json(e.ate.max) : nlohmann::json(nullptr);
  j["rpe"] = e.rpe ? ToJson(*e.rpe) : nlohmann::json(nullptr);
  const bool rpe_ok = e.rpe && e.rpe->translation.count > 0;
  j["rpe_trans_rmse"] = rpe_ok ? nlohmann::json(e.rpe->translation.rmse) : nlohmann::json(nullptr);
  j["rpe_rot_rmse_deg"] = rpe_ok && e.rpe->rotation_deg ? nlohmann::json(e.rpe->rotation_deg->rmse)
                                                        : nlohmann::json(nullptr);
  j["kitti"] = e.kitti ? ToJson(*e.kitti) : nlohmann::json(nullptr);
  j["kitti_t_err_pct"] = e.kitti ? OrNull(e.kitti->t_err_pct) : nlohmann::json(nullptr);
  j["kitti_r_err_deg_per_100m"] =
      e.kitti ? OrNull(e.kitti->r_err_deg_per_100m) : nlohmann::json(nullptr);
  return j;
}

nlohmann::json ToJson(const TrajectoryEvaluation& e, const Trajectory& gt, const Trajectory& est) {
  SL_CHECK_MSG(gt.size() == e.num_gt_poses && est.size() == e.num_est_poses,
               "the trajectories ({} GT, {} estimate poses) are not the evaluated ones ({}, {})",
               gt.size(), est.size(), e.num_gt_poses, e.num_est_poses);
  nlohmann::json j = ToJson(e);
  nlohmann::json est_index = nlohmann::json::array(), gt_index = nlohmann::json::array();
  nlohmann::json est_time = nlohmann::json::array(), gt_time = nlohmann::json::array();
  nlohmann::json est_frame = nlohmann::json::array(), gt_frame = nlohmann::json::array();
  for (const auto& [i, g] : e.association.pairs) {
    est_index.push_back(i);
    gt_index.push_back(g);
    est_time.push_back(est.poses[i].timestamp);
    gt_time.push_back(gt.poses[g].timestamp);
    est_frame.push_back(est.poses[i].frame);
    gt_frame.push_back(gt.poses[g].frame);
  }
  j["associated"] = {{"est_index", est_index}, {"gt_index", gt_index},   {"est_time", est_time},
                     {"gt_time", gt_time},     {"est_frame", est_frame}, {"gt_frame", gt_frame},
                     {"ate_m", e.ate.errors}};
  nlohmann::json aligned = nlohmann::json::array();
  for (const StampedPose& p : est.poses) {
    const Eigen::Vector3d x = e.alignment.gt_from_est * p.world_from_cam.translation;
    aligned.push_back({x.x(), x.y(), x.z()});
  }
  j["aligned_positions"] = aligned;
  return j;
}

void AddLoopKeys(nlohmann::json& out, const LoopPrResult* loops) {
  if (loops == nullptr) {
    for (const char* key : {"loop_precision", "loop_recall", "loop_recall_at_100p",
                            "loop_true_positives", "loop_false_positives", "loops"}) {
      out[key] = nullptr;
    }
    return;
  }
  out["loop_precision"] = OrNull(loops->precision);
  out["loop_recall"] = OrNull(loops->recall);
  out["loop_recall_at_100p"] = OrNull(loops->recall_at_100p);
  out["loop_true_positives"] = loops->true_positives;
  out["loop_false_positives"] = loops->false_positives;
  out["loops"] = ToJson(*loops);
}

void AddLoopKeys(nlohmann::json& out, const GtDistanceScore& score) {
  AddLoopKeys(out, &score.all);
  out["loop_false_accepted"] = score.accepted.false_positives;
  out["loop_recall_at_100p_accepted"] = OrNull(score.accepted.recall_at_100p);
  out["loop_trivial"] = score.trivial;
  out["loop_no_gt"] = score.no_gt;
  out["loop_events"] = score.events;
  out["loop_events_detected"] = score.events_detected;
  out["loops_accepted"] = ToJson(score.accepted);
  nlohmann::json verdicts = nlohmann::json::array();
  for (LoopVerdict v : score.verdicts) verdicts.push_back(ToString(v));
  out["loop_verdicts"] = verdicts;
}

}  // namespace sparseloop
