#include "sparseloop/eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/statistics.h"
#include "sparseloop/core/trajectory.h"

namespace sparseloop {

ErrorStatistics ComputeStatistics(std::vector<double> errors) {
  ErrorStatistics stats;
  stats.count = errors.size();
  if (errors.empty()) return stats;
  const double n = static_cast<double>(errors.size());
  double sum = 0.0;
  double sum_sq = 0.0;
  for (double e : errors) {
    sum += e;
    sum_sq += e * e;
  }
  stats.mean = sum / n;
  stats.rmse = std::sqrt(sum_sq / n);
  double var = 0.0;
  for (double e : errors) var += (e - stats.mean) * (e - stats.mean);
  stats.std = std::sqrt(var / n);
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  stats.min = sorted.front();
  stats.max = sorted.back();
  stats.median = PercentileOfSorted(sorted, 0.5);
  stats.errors = std::move(errors);
  return stats;
}

AteResult ComputeAte(const std::vector<Eigen::Vector3d>& gt,
                     const std::vector<Eigen::Vector3d>& est, const Sim3d& gt_from_est) {
  SL_CHECK_MSG(gt.size() == est.size(), "ATE needs corresponding points, got {} gt and {} est",
               gt.size(), est.size());
  std::vector<double> errors(gt.size());
  for (size_t i = 0; i < gt.size(); ++i) errors[i] = (gt[i] - gt_from_est * est[i]).norm();
  return ComputeStatistics(std::move(errors));
}

Rigid3d ApplyAlignment(const Sim3d& gt_from_est, const Rigid3d& est_world_from_cam) {
  return Rigid3d(gt_from_est.rotation * est_world_from_cam.rotation,
                 gt_from_est * est_world_from_cam.translation);
}

std::string ToString(RpeUnit unit) { return unit == RpeUnit::kMeters ? "m" : "frames"; }

void RpeOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(delta) && delta > 0.0, "RPE delta must be > 0, got {}", delta);
  if (unit == RpeUnit::kFrames) {
    // Bounded before any pair is formed: 1e20 frames overflowed size_t (an endless loop, or
    // std::bad_alloc at 2^64).
    SL_CHECK_MSG(delta >= 1.0 && delta <= kMaxRpeDeltaFrames && std::floor(delta) == delta,
                 "RPE delta in frames must be an integer from 1 to {:g}, got {}",
                 kMaxRpeDeltaFrames, delta);
  } else {
    SL_CHECK_MSG(!all_pairs, "RPE all_pairs is only supported for a delta in frames");
  }
}

std::vector<std::pair<size_t, size_t>> RpePairs(const std::vector<Rigid3d>& gt,
                                                const RpeOptions& options) {
  options.Check();
  std::vector<std::pair<size_t, size_t>> pairs;
  const size_t n = gt.size();
  if (options.unit == RpeUnit::kFrames) {
    const size_t delta = static_cast<size_t>(options.delta);
    if (options.all_pairs) {
      for (size_t i = 0; delta < n && i < n - delta; ++i) pairs.emplace_back(i, i + delta);
    } else {
      for (size_t i = 0; delta < n && i < n - delta; i += delta) pairs.emplace_back(i, i + delta);
    }
    return pairs;
  }
  // evo filter_pairs_by_path (all_pairs false): accumulate the path, emit an id whenever it
  // reaches delta and restart; pairs are consecutive ids.
  std::vector<size_t> ids;
  double path = 0.0;
  for (size_t i = 0; i < n; ++i) {
    if (i > 0) path += (gt[i].translation - gt[i - 1].translation).norm();
    if (path >= options.delta) {
      ids.push_back(i);
      path = 0.0;
    }
  }
  for (size_t k = 1; k < ids.size(); ++k) pairs.emplace_back(ids[k - 1], ids[k]);
  return pairs;
}

namespace {

// The estimate pose used by the relative metrics: its own orientation, or the gt's.
Rigid3d EstPose(const Rigid3d& gt, const Rigid3d& est, bool use_est_rotation) {
  if (use_est_rotation) return est;
  Rigid3d out = gt;
  out.translation = est.translation;
  return out;
}

// The devkit's rotationError: acos(max(min(0.5 (trace - 1), 1), -1)).
double KittiRotationError(const Rigid3d& pose_error) {
  const Eigen::Matrix3d r = pose_error.RotationMatrix();
  const double d = 0.5 * (r(0, 0) + r(1, 1) + r(2, 2) - 1.0);
  return std::acos(std::max(std::min(d, 1.0), -1.0));
}

}  // namespace

RpeResult ComputeRpe(const std::vector<Rigid3d>& gt, const std::vector<Rigid3d>& est,
                     const RpeOptions& options, bool use_est_rotation) {
  SL_CHECK_MSG(gt.size() == est.size(), "RPE needs corresponding poses, got {} gt and {} est",
               gt.size(), est.size());
  RpeResult result;
  result.pairs = RpePairs(gt, options);
  std::vector<double> trans;
  std::vector<double> rot;
  trans.reserve(result.pairs.size());
  rot.reserve(result.pairs.size());
  for (const auto& [i, j] : result.pairs) {
    const Rigid3d gt_rel = gt[i].Inverse() * gt[j];
    const Rigid3d est_rel = EstPose(gt[i], est[i], use_est_rotation).Inverse() *
                            EstPose(gt[j], est[j], use_est_rotation);
    const Rigid3d error = gt_rel.Inverse() * est_rel;
    trans.push_back(error.translation.norm());
    rot.push_back(LogSO3(error.rotation).norm() * 180.0 / std::numbers::pi);
  }
  result.translation = ComputeStatistics(std::move(trans));
  if (use_est_rotation) result.rotation_deg = ComputeStatistics(std::move(rot));
  return result;
}

void KittiOptions::Check() const {
  SL_CHECK_MSG(!lengths.empty(), "KITTI lengths must not be empty");
  for (double len : lengths) {
    SL_CHECK_MSG(std::isfinite(len) && len > 0.0, "KITTI lengths must be > 0 m, got {}", len);
  }
  SL_CHECK_MSG(step_size >= 1, "KITTI step_size must be >= 1 frame, got {}", step_size);
  SL_CHECK_MSG(std::isfinite(frame_rate_hz) && frame_rate_hz > 0.0,
               "KITTI frame_rate_hz must be > 0, got {}", frame_rate_hz);
}

KittiResult ComputeKittiMetric(const std::vector<Rigid3d>& gt, const std::vector<Rigid3d>& est,
                               const KittiOptions& options, bool use_est_rotation) {
  options.Check();
  SL_CHECK_MSG(gt.size() == est.size(),
               "KITTI metric needs corresponding poses, got {} gt and {} est", gt.size(),
               est.size());
  KittiResult result;
  const size_t n = gt.size();
  // trajectoryDistances: cumulative gt path length.
  const std::vector<double> dist =
      CumulativePathLength(gt, [](const Rigid3d& p) { return p.translation; });

  for (size_t first = 0; first < n; first += static_cast<size_t>(options.step_size)) {
    for (double len : options.lengths) {
      // lastFrameFromSegmentLength
      size_t last = n;
      for (size_t i = first; i < n; ++i) {
        if (dist[i] > dist[first] + len) {
          last = i;
          break;
        }
      }
      if (last == n) continue;
      const Rigid3d delta_gt = gt[first].Inverse() * gt[last];
      const Rigid3d delta_est = EstPose(gt[first], est[first], use_est_rotation).Inverse() *
                                EstPose(gt[last], est[last], use_est_rotation);
      const Rigid3d pose_error = delta_est.Inverse() * delta_gt;
      KittiSegmentError seg;
      seg.first_frame = first;
      seg.last_frame = last;
      seg.length = len;
      seg.t_err = pose_error.translation.norm() / len;
      if (use_est_rotation) seg.r_err = KittiRotationError(pose_error) / len;
      const double num_frames = static_cast<double>(last - first + 1);
      seg.speed = len / (num_frames / options.frame_rate_hz);
      result.segments.push_back(seg);
    }
  }
  result.num_segments = result.segments.size();
  if (result.segments.empty()) return result;
  result.status = KittiStatus::kOk;
  constexpr double kRadToDegPer100m = 180.0 / std::numbers::pi * 100.0;
  double t_sum = 0.0;
  double r_sum = 0.0;
  for (const auto& seg : result.segments) {
    t_sum += seg.t_err;
    if (seg.r_err) r_sum += *seg.r_err;
  }
  const double count = static_cast<double>(result.segments.size());
  result.t_err_pct = t_sum / count * 100.0;
  if (use_est_rotation) result.r_err_deg_per_100m = r_sum / count * kRadToDegPer100m;
  for (double len : options.lengths) {
    KittiLengthError per;
    per.length = len;
    double t = 0.0;
    double r = 0.0;
    for (const auto& seg : result.segments) {
      if (seg.length != len) continue;
      ++per.count;
      t += seg.t_err;
      if (seg.r_err) r += *seg.r_err;
    }
    if (per.count == 0) continue;
    per.t_err_pct = t / static_cast<double>(per.count) * 100.0;
    if (use_est_rotation) {
      per.r_err_deg_per_100m = r / static_cast<double>(per.count) * kRadToDegPer100m;
    }
    result.per_length.push_back(per);
  }
  return result;
}

void EvaluationOptions::Check() const {
  association.Check();
  if (compute_rpe) rpe.Check();
  if (compute_kitti) kitti.Check();
}

std::string ToString(EvaluationStatus status) {
  return status == EvaluationStatus::kOk ? "ok" : "no_association";
}

TrajectoryEvaluation EvaluateTrajectory(const Trajectory& gt, const Trajectory& est,
                                        const EvaluationOptions& options) {
  options.Check();
  TrajectoryEvaluation out;
  out.num_est_poses = est.size();
  out.num_gt_poses = gt.size();
  out.association = Associate(est, gt, options.association);
  out.rotation_evaluated = est.has_rotation && gt.has_rotation;
  out.alignment.type = options.alignment;
  if (out.association.pairs.empty()) {
    Logger().warn("evaluation: no estimate pose could be associated with the ground truth");
    return out;
  }
  out.status = EvaluationStatus::kOk;
  const size_t n = out.association.pairs.size();
  std::vector<Eigen::Vector3d> gt_points(n);
  std::vector<Eigen::Vector3d> est_points(n);
  std::vector<Rigid3d> gt_poses(n);
  std::vector<Rigid3d> est_poses(n);
  for (size_t k = 0; k < n; ++k) {
    const auto [i, j] = out.association.pairs[k];
    gt_poses[k] = gt.poses[j].world_from_cam;
    est_poses[k] = est.poses[i].world_from_cam;
    gt_points[k] = gt_poses[k].translation;
    est_points[k] = est_poses[k].translation;
  }
  out.alignment = Umeyama(est_points, gt_points, options.alignment);
  if (out.alignment.status != AlignmentStatus::kOk) {
    Logger().warn("evaluation: {} alignment is {} ({} associated poses)",
                  ToString(options.alignment), ToString(out.alignment.status), n);
  }
  out.ate = ComputeAte(gt_points, est_points, out.alignment.gt_from_est);
  for (auto& pose : est_poses) pose = ApplyAlignment(out.alignment.gt_from_est, pose);
  if (options.compute_rpe) {
    out.rpe = ComputeRpe(gt_poses, est_poses, options.rpe, out.rotation_evaluated);
  }
  if (options.compute_kitti) {
    out.kitti = ComputeKittiMetric(gt_poses, est_poses, options.kitti, out.rotation_evaluated);
  }
  return out;
}

}  // namespace sparseloop
