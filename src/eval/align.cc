#include "sparseloop/eval/align.h"

#include <cmath>

#include <Eigen/SVD>

#include "sparseloop/core/check.h"

namespace sparseloop {

Alignment ParseAlignment(const std::string& name) {
  if (name == "none") return Alignment::kNone;
  if (name == "se3") return Alignment::kSE3;
  if (name == "sim3") return Alignment::kSim3;
  SL_CHECK_MSG(false, "unknown alignment '{}', expected none, se3 or sim3", name);
  return Alignment::kNone;
}

std::string ToString(Alignment alignment) {
  switch (alignment) {
    case Alignment::kNone:
      return "none";
    case Alignment::kSE3:
      return "se3";
    case Alignment::kSim3:
      return "sim3";
  }
  return "unknown";
}

std::string ToString(AlignmentStatus status) {
  switch (status) {
    case AlignmentStatus::kOk:
      return "ok";
    case AlignmentStatus::kTooFewPoints:
      return "too_few_points";
    case AlignmentStatus::kDegenerate:
      return "degenerate";
  }
  return "unknown";
}

namespace {

double RmsResidual(const std::vector<Eigen::Vector3d>& est, const std::vector<Eigen::Vector3d>& gt,
                   const Sim3d& gt_from_est) {
  if (est.empty()) return 0.0;
  double sum = 0.0;
  for (size_t i = 0; i < est.size(); ++i) sum += (gt[i] - gt_from_est * est[i]).squaredNorm();
  return std::sqrt(sum / static_cast<double>(est.size()));
}

}  // namespace

AlignmentResult Umeyama(const std::vector<Eigen::Vector3d>& est,
                        const std::vector<Eigen::Vector3d>& gt, Alignment type) {
  SL_CHECK_MSG(est.size() == gt.size(), "Umeyama needs corresponding points, got {} est and {} gt",
               est.size(), gt.size());
  AlignmentResult result;
  result.type = type;
  result.num_points = est.size();
  if (type == Alignment::kNone) {
    result.rms_residual = RmsResidual(est, gt, result.gt_from_est);
    return result;
  }
  if (est.size() < 3) {
    result.status = AlignmentStatus::kTooFewPoints;
    result.rms_residual = RmsResidual(est, gt, result.gt_from_est);
    return result;
  }
  const double n = static_cast<double>(est.size());
  Eigen::Vector3d mean_est = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_gt = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < est.size(); ++i) {
    mean_est += est[i];
    mean_gt += gt[i];
  }
  mean_est /= n;
  mean_gt /= n;
  double var_est = 0.0;
  double var_gt = 0.0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < est.size(); ++i) {
    const Eigen::Vector3d x = est[i] - mean_est;
    const Eigen::Vector3d y = gt[i] - mean_gt;
    var_est += x.squaredNorm();
    var_gt += y.squaredNorm();
    cov += y * x.transpose();
  }
  var_est /= n;
  var_gt /= n;
  cov /= n;

  // Each set's spread relative to the magnitude of its own coordinates: below this the points are
  // one point (the two sets may differ in scale by any factor: a monocular estimate's unit is
  // arbitrary, so an estimate at 1e14 x the GT's scale aligns exactly).
  const auto one_point = [](double var, const Eigen::Vector3d& mean) {
    return !(var > 1e-24 * mean.squaredNorm()) || !(var > 1e-280);
  };
  if (one_point(var_est, mean_est) || one_point(var_gt, mean_gt)) {
    result.status = AlignmentStatus::kDegenerate;
    result.gt_from_est = Sim3d(1.0, Eigen::Quaterniond::Identity(), mean_gt - mean_est);
    result.rms_residual = RmsResidual(est, gt, result.gt_from_est);
    return result;
  }

  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d& u = svd.matrixU();
  const Eigen::Matrix3d& v = svd.matrixV();
  const Eigen::Vector3d d = svd.singularValues();
  if (d(0) <= 1e-15 * std::sqrt(var_est * var_gt)) {
    // Uncorrelated point sets: no rotation is preferred; fall back to a pure translation.
    result.status = AlignmentStatus::kDegenerate;
    result.gt_from_est = Sim3d(1.0, Eigen::Quaterniond::Identity(), mean_gt - mean_est);
    result.rms_residual = RmsResidual(est, gt, result.gt_from_est);
    return result;
  }
  Eigen::Vector3d s = Eigen::Vector3d::Ones();
  if (u.determinant() * v.determinant() < 0.0) s(2) = -1.0;
  const Eigen::Matrix3d rotation = u * s.asDiagonal() * v.transpose();
  const double scale = type == Alignment::kSim3 ? d.dot(s) / var_est : 1.0;
  const Eigen::Vector3d translation = mean_gt - scale * rotation * mean_est;
  result.gt_from_est = Sim3d(scale, Eigen::Quaterniond(rotation), translation);
  if (d(1) <= 1e-9 * d(0)) result.status = AlignmentStatus::kDegenerate;
  result.rms_residual = RmsResidual(est, gt, result.gt_from_est);
  return result;
}

}  // namespace sparseloop
