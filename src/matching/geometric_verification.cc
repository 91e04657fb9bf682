#include "sparseloop/matching/geometric_verification.h"

#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "sparseloop/core/check.h"
#include "sparseloop/matching/sim3_solver.h"

namespace sparseloop {

const char* ToString(VerificationMethod method) {
  switch (method) {
    case VerificationMethod::kEssential:
      return "essential";
    case VerificationMethod::kFundamental:
      return "fundamental";
    case VerificationMethod::kPnP:
      return "pnp";
    case VerificationMethod::kSim3:
      return "sim3";
  }
  return "unknown";
}

const char* ToString(RelativePoseKind kind) {
  switch (kind) {
    case RelativePoseKind::kNone:
      return "none";
    case RelativePoseKind::kSE3UnitTranslation:
      return "se3_unit_translation";
    case RelativePoseKind::kSE3Metric:
      return "se3_metric";
    case RelativePoseKind::kSim3:
      return "sim3";
  }
  return "unknown";
}

void VerifyOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(threshold_px) && threshold_px > 0,
               "verify.threshold_px must be > 0 pixels, got {}", threshold_px);
  SL_CHECK_MSG(confidence > 0 && confidence < 1, "verify.confidence must be in (0, 1), got {}",
               confidence);
  SL_CHECK_MSG(max_iterations >= 1, "verify.max_iterations must be >= 1, got {}", max_iterations);
  SL_CHECK_MSG(min_inliers >= 5, "verify.min_inliers must be >= 5, got {}", min_inliers);
  SL_CHECK_MSG(min_inlier_ratio >= 0 && min_inlier_ratio <= 1,
               "verify.min_inlier_ratio must be in [0, 1], got {}", min_inlier_ratio);
}

namespace {

Sim3d FromCv(const cv::Mat& r_cv, const cv::Mat& t_cv, double scale = 1.0) {
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(r_cv, r);
  cv::cv2eigen(t_cv, t);
  return Sim3d(scale, Eigen::Quaterniond(r).normalized(), t);
}

Eigen::Vector3d Bearing(const CompactKeypoint& k) { return {k.x, k.y, 1.0}; }

// Sampson distance of x_query^T E x_match with E = [t]x R (query_from_match), normalised units.
double Sampson(const Eigen::Matrix3d& e, const Eigen::Vector3d& xm, const Eigen::Vector3d& xq) {
  const Eigen::Vector3d ex = e * xm;
  const Eigen::Vector3d etx = e.transpose() * xq;
  const double num = xq.dot(ex);
  const double den = ex.head<2>().squaredNorm() + etx.head<2>().squaredNorm();
  return den > 0 ? num / std::sqrt(den) : 0.0;
}

// Refines query_from_match (R, unit t) on the inliers by Gauss-Newton with Huber weights on the
// Sampson distance (5 DoF: rotation increment and a 2D step tangent to the unit sphere of t).
// The RANSAC model comes from 5 points; this uses all inliers, which is what makes the relative
// pose accurate to about a degree.
void RefineEssential(const std::vector<Eigen::Vector3d>& xm, const std::vector<Eigen::Vector3d>& xq,
                     double huber, Eigen::Matrix3d* r, Eigen::Vector3d* t) {
  const int n = static_cast<int>(xm.size());
  if (n < 6) return;
  auto residuals = [&](const Eigen::Matrix3d& rr, const Eigen::Vector3d& tt) {
    const Eigen::Matrix3d e = Hat(tt) * rr;
    Eigen::VectorXd res(n);
    for (int i = 0; i < n; ++i) res(i) = Sampson(e, xm[i], xq[i]);
    return res;
  };
  auto apply = [&](const Eigen::Matrix<double, 5, 1>& d, const Eigen::Matrix3d& r0,
                   const Eigen::Vector3d& t0, Eigen::Matrix3d* r1, Eigen::Vector3d* t1) {
    Eigen::Vector3d a = t0.unitOrthogonal();
    Eigen::Vector3d b = t0.cross(a).normalized();
    *r1 = ExpSO3(d.head<3>()).toRotationMatrix() * r0;
    *t1 = (t0 + d(3) * a + d(4) * b).normalized();
  };
  for (int iter = 0; iter < 10; ++iter) {
    const Eigen::VectorXd res = residuals(*r, *t);
    Eigen::MatrixXd jac(n, 5);
    const double h = 1e-7;
    for (int k = 0; k < 5; ++k) {
      Eigen::Matrix<double, 5, 1> d = Eigen::Matrix<double, 5, 1>::Zero();
      d(k) = h;
      Eigen::Matrix3d r1;
      Eigen::Vector3d t1;
      apply(d, *r, *t, &r1, &t1);
      jac.col(k) = (residuals(r1, t1) - res) / h;
    }
    Eigen::VectorXd w(n);
    for (int i = 0; i < n; ++i) w(i) = std::abs(res(i)) <= huber ? 1.0 : huber / std::abs(res(i));
    const Eigen::Matrix<double, 5, 5> jtj =
        jac.transpose() * w.asDiagonal() * jac + 1e-9 * Eigen::Matrix<double, 5, 5>::Identity();
    const Eigen::Matrix<double, 5, 1> jtr = jac.transpose() * w.asDiagonal() * res;
    const Eigen::Matrix<double, 5, 1> d = -jtj.ldlt().solve(jtr);
    if (!d.allFinite()) return;
    Eigen::Matrix3d r1;
    Eigen::Vector3d t1;
    apply(d, *r, *t, &r1, &t1);
    const Eigen::VectorXd res1 = residuals(r1, t1);
    auto cost = [&](const Eigen::VectorXd& rr) {
      double c = 0;
      for (int i = 0; i < n; ++i) {
        const double a = std::abs(rr(i));
        c += a <= huber ? 0.5 * a * a : huber * (a - 0.5 * huber);
      }
      return c;
    };
    if (cost(res1) >= cost(res)) return;
    *r = r1;
    *t = t1;
    if (d.norm() < 1e-10) return;
  }
}

}  // namespace

VerificationResult VerifyPair(const KeyframeRecord& query, const KeyframeRecord& match,
                              const std::vector<DescriptorMatch>& matches,
                              const VerifyOptions& options) {
  options.Check();
  VerificationResult result;
  result.matches = static_cast<int>(matches.size());
  const float focal = std::max(1.0f, 0.5f * (query.focal_px + match.focal_px));
  const double threshold = options.threshold_px / focal;
  cv::theRNG().state = options.seed;

  const bool q_depth = options.use_depths && query.has_depths();
  const bool m_depth = options.use_depths && match.has_depths();
  auto accept = [&](int inliers) {
    return inliers >= options.min_inliers &&
           inliers >= options.min_inlier_ratio * static_cast<double>(matches.size());
  };

  if (q_depth && m_depth) {
    result.method = VerificationMethod::kSim3;
    std::vector<Eigen::Vector3d> src, dst;
    std::vector<int> idx;
    for (size_t i = 0; i < matches.size(); ++i) {
      const float dq = query.depths[matches[i].query];
      const float dm = match.depths[matches[i].train];
      if (dq <= 0 || dm <= 0) continue;
      src.push_back(dq * Bearing(query.keypoints[matches[i].query]));
      dst.push_back(dm * Bearing(match.keypoints[matches[i].train]));
      idx.push_back(int(i));
    }
    Sim3RansacOptions so;
    so.max_error = threshold;
    so.max_iterations = options.max_iterations;
    so.min_inliers = options.min_inliers;
    so.seed = options.seed;
    auto r = RansacSim3(src, dst, so);
    if (r.success) {
      for (int i : r.inliers) result.inlier_matches.push_back(idx[i]);
      result.inliers = static_cast<int>(r.inliers.size());
      result.match_from_query = r.target_from_source;
      result.pose_kind = RelativePoseKind::kSim3;
      result.success = accept(result.inliers);
    }
    return result;
  }

  if (q_depth || m_depth) {
    // PnP: 3D points on the side with depths, 2D observations on the other.
    result.method = VerificationMethod::kPnP;
    const KeyframeRecord& with = m_depth ? match : query;
    std::vector<cv::Point3f> object;
    std::vector<cv::Point2f> image;
    std::vector<int> idx;
    for (size_t i = 0; i < matches.size(); ++i) {
      const int wi = m_depth ? matches[i].train : matches[i].query;
      const int oi = m_depth ? matches[i].query : matches[i].train;
      const float d = with.depths[wi];
      if (d <= 0) continue;
      const auto& kw = with.keypoints[wi];
      const auto& ko = (m_depth ? query : match).keypoints[oi];
      object.emplace_back(d * kw.x, d * kw.y, d);
      image.emplace_back(ko.x, ko.y);
      idx.push_back(int(i));
    }
    if (static_cast<int>(object.size()) < std::max(6, options.min_inliers)) return result;
    cv::Mat rvec, tvec, inl;
    const bool ok = cv::solvePnPRansac(object, image, cv::Mat::eye(3, 3, CV_64F), cv::noArray(),
                                       rvec, tvec, false, options.max_iterations, threshold,
                                       options.confidence, inl, cv::SOLVEPNP_EPNP);
    if (!ok) return result;
    for (int r = 0; r < inl.rows; ++r) result.inlier_matches.push_back(idx[inl.at<int>(r)]);
    result.inliers = inl.rows;
    cv::Mat r_cv;
    cv::Rodrigues(rvec, r_cv);
    // other_from_with maps the 3D side into the 2D side's camera.
    const Sim3d other_from_with = FromCv(r_cv, tvec);
    result.match_from_query = m_depth ? other_from_with.Inverse() : other_from_with;
    result.pose_kind = RelativePoseKind::kSE3Metric;
    result.success = accept(result.inliers);
    return result;
  }

  std::vector<cv::Point2f> pts_match, pts_query;
  for (const auto& m : matches) {
    pts_match.emplace_back(match.keypoints[m.train].x, match.keypoints[m.train].y);
    pts_query.emplace_back(query.keypoints[m.query].x, query.keypoints[m.query].y);
  }
  if (options.use_fundamental) {
    result.method = VerificationMethod::kFundamental;
    if (matches.size() < 8) return result;
    cv::Mat mask;
    cv::Mat f = cv::findFundamentalMat(pts_match, pts_query, cv::FM_RANSAC, threshold,
                                       options.confidence, options.max_iterations, mask);
    if (f.empty() || mask.empty()) return result;
    for (int i = 0; i < mask.rows; ++i)
      if (mask.at<uint8_t>(i)) result.inlier_matches.push_back(i);
    result.inliers = static_cast<int>(result.inlier_matches.size());
    result.success = accept(result.inliers);
    return result;
  }

  result.method = VerificationMethod::kEssential;
  if (matches.size() < 5) return result;
  cv::Mat mask;
  const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
  cv::Mat e = cv::findEssentialMat(pts_match, pts_query, eye, cv::RANSAC, options.confidence,
                                   threshold, options.max_iterations, mask);
  if (e.empty() || e.rows < 3 || mask.empty()) return result;
  cv::Mat r_cv, t_cv;
  // recoverPose keeps the inliers in front of both cameras; x_query = R x_match + t.
  const int good = cv::recoverPose(e.rowRange(0, 3), pts_match, pts_query, eye, r_cv, t_cv, mask);
  for (int i = 0; i < mask.rows; ++i)
    if (mask.at<uint8_t>(i)) result.inlier_matches.push_back(i);
  result.inliers = good;
  Sim3d query_from_match = FromCv(r_cv, t_cv);
  {
    std::vector<Eigen::Vector3d> xm, xq;
    for (int i = 0; i < mask.rows; ++i) {
      if (!mask.at<uint8_t>(i)) continue;
      xm.emplace_back(pts_match[i].x, pts_match[i].y, 1.0);
      xq.emplace_back(pts_query[i].x, pts_query[i].y, 1.0);
    }
    Eigen::Matrix3d r = query_from_match.rotation.toRotationMatrix();
    Eigen::Vector3d t = query_from_match.translation.normalized();
    RefineEssential(xm, xq, threshold, &r, &t);
    query_from_match = Sim3d(1.0, Eigen::Quaterniond(r).normalized(), t);
  }
  Sim3d match_from_query = query_from_match.Inverse();
  const double n = match_from_query.translation.norm();
  if (n > 0) match_from_query.translation /= n;
  result.match_from_query = match_from_query;
  result.pose_kind = RelativePoseKind::kSE3UnitTranslation;
  result.success = accept(result.inliers);
  return result;
}

}  // namespace sparseloop
