#include "sparseloop/matching/geometric_verification.h"

#include <algorithm>
#include <cmath>
#include <limits>

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
  SL_CHECK_MSG(local_optimization_rounds >= 0 && local_optimization_rounds <= 100,
               "verify.local_optimization_rounds must be in [0, 100], got {}",
               local_optimization_rounds);
  SL_CHECK_MSG(std::isfinite(information_min_sigma_px) && information_min_sigma_px > 0,
               "verify.information_min_sigma_px must be > 0 pixels, got {}",
               information_min_sigma_px);
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

// Refines query_from_match (R, unit t) on the given correspondences by Levenberg-Marquardt with
// Huber weights on the Sampson distance (5 DoF: rotation increment and a 2D step tangent to the
// unit sphere of t). The RANSAC model comes from 5 points; this uses all inliers. Plain
// Gauss-Newton (the previous version) stopped at the first step that increased the cost, far from
// the optimum: on castle 29 -> 1 it left the translation direction 41 deg off where the optimum
// of the same inliers is 18 deg off (docs/DETECTOR.md).
void RefineEssential(const std::vector<Eigen::Vector3d>& xm, const std::vector<Eigen::Vector3d>& xq,
                     double huber, Eigen::Matrix3d* r, Eigen::Vector3d* t) {
  const int n = static_cast<int>(xm.size());
  if (n < 6) return;
  using Vec5 = Eigen::Matrix<double, 5, 1>;
  using Mat5 = Eigen::Matrix<double, 5, 5>;
  auto residuals = [&](const Eigen::Matrix3d& rr, const Eigen::Vector3d& tt) {
    const Eigen::Matrix3d e = Hat(tt) * rr;
    Eigen::VectorXd res(n);
    for (int i = 0; i < n; ++i) res(i) = Sampson(e, xm[i], xq[i]);
    return res;
  };
  auto apply = [](const Vec5& d, const Eigen::Matrix3d& r0, const Eigen::Vector3d& t0,
                  Eigen::Matrix3d* r1, Eigen::Vector3d* t1) {
    const Eigen::Vector3d a = t0.unitOrthogonal();
    const Eigen::Vector3d b = t0.cross(a).normalized();
    *r1 = ExpSO3(d.head<3>()).toRotationMatrix() * r0;
    *t1 = (t0 + d(3) * a + d(4) * b).normalized();
  };
  auto cost = [&](const Eigen::VectorXd& rr) {
    double c = 0;
    for (int i = 0; i < n; ++i) {
      const double a = std::abs(rr(i));
      c += a <= huber ? 0.5 * a * a : huber * (a - 0.5 * huber);
    }
    return c;
  };
  Eigen::VectorXd res = residuals(*r, *t);
  double c0 = cost(res);
  double lambda = 1e-3;
  Eigen::MatrixXd jac(n, 5);
  for (int iter = 0; iter < 50; ++iter) {
    const double h = 1e-7;
    for (int k = 0; k < 5; ++k) {
      Vec5 d = Vec5::Zero();
      d(k) = h;
      Eigen::Matrix3d r1;
      Eigen::Vector3d t1;
      apply(d, *r, *t, &r1, &t1);
      jac.col(k) = (residuals(r1, t1) - res) / h;
    }
    Eigen::VectorXd w(n);
    for (int i = 0; i < n; ++i) w(i) = std::abs(res(i)) <= huber ? 1.0 : huber / std::abs(res(i));
    const Mat5 jtj = jac.transpose() * w.asDiagonal() * jac;
    const Vec5 jtr = jac.transpose() * w.asDiagonal() * res;
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Mat5 a = jtj;
      a.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
      const Vec5 d = -a.ldlt().solve(jtr);
      if (!d.allFinite()) return;
      Eigen::Matrix3d r1;
      Eigen::Vector3d t1;
      apply(d, *r, *t, &r1, &t1);
      const Eigen::VectorXd res1 = residuals(r1, t1);
      const double c1 = cost(res1);
      if (c1 < c0) {
        const double decrease = (c0 - c1) / std::max(c0, 1e-300);
        *r = r1;
        *t = t1;
        res = res1;
        c0 = c1;
        lambda = std::max(lambda * 0.1, 1e-9);
        improved = true;
        if (d.norm() < 1e-10 || decrease < 1e-10) return;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) return;
  }
}

// PnP: 3D points (keypoint bearing x depth) of the side with depths, 2D observations on the
// other; EPnP inside RANSAC, then Levenberg-Marquardt on the inliers and one re-collection of
// the inliers with the refined pose (EPnP from a minimal set is noisy with stereo-grade depths).
// Sets method, inliers, inlier_matches, match_from_query and pose_kind (kNone on failure).
void VerifyPnp(const KeyframeRecord& query, const KeyframeRecord& match,
               const std::vector<DescriptorMatch>& matches, bool points_in_match,
               const VerifyOptions& options, double threshold, VerificationResult* result) {
  result->method = VerificationMethod::kPnP;
  const bool m_depth = points_in_match;
  const KeyframeRecord& with = m_depth ? match : query;
  const KeyframeRecord& other = m_depth ? query : match;
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  std::vector<int> idx;
  for (size_t i = 0; i < matches.size(); ++i) {
    const int wi = m_depth ? matches[i].train : matches[i].query;
    const int oi = m_depth ? matches[i].query : matches[i].train;
    const float d = with.depths[wi];
    if (d <= 0) continue;
    const auto& kw = with.keypoints[wi];
    const auto& ko = other.keypoints[oi];
    object.emplace_back(d * kw.x, d * kw.y, d);
    image.emplace_back(ko.x, ko.y);
    idx.push_back(int(i));
  }
  if (static_cast<int>(object.size()) < std::max(6, options.min_inliers)) return;
  cv::Mat rvec, tvec, inl;
  const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
  const bool ok = cv::solvePnPRansac(object, image, eye, cv::noArray(), rvec, tvec, false,
                                     options.max_iterations, threshold, options.confidence, inl,
                                     cv::SOLVEPNP_EPNP);
  if (!ok || inl.rows < 4) return;
  std::vector<int> inliers(inl.rows);
  for (int r = 0; r < inl.rows; ++r) inliers[r] = inl.at<int>(r);
  const auto collect = [&](const cv::Mat& rv, const cv::Mat& tv) {
    std::vector<cv::Point2f> projected;
    cv::projectPoints(object, rv, tv, eye, cv::noArray(), projected);
    std::vector<int> in;
    for (size_t k = 0; k < projected.size(); ++k) {
      if (cv::norm(projected[k] - image[k]) <= threshold) in.push_back(static_cast<int>(k));
    }
    return in;
  };
  for (int round = 0; round < 2 && inliers.size() >= 6; ++round) {
    std::vector<cv::Point3f> obj_in;
    std::vector<cv::Point2f> img_in;
    for (int k : inliers) {
      obj_in.push_back(object[k]);
      img_in.push_back(image[k]);
    }
    cv::Mat rv = rvec.clone(), tv = tvec.clone();
    if (!cv::solvePnP(obj_in, img_in, eye, cv::noArray(), rv, tv, /*useExtrinsicGuess=*/true,
                      cv::SOLVEPNP_ITERATIVE)) {
      break;
    }
    std::vector<int> refined = collect(rv, tv);
    if (refined.size() < inliers.size()) break;
    rvec = rv;
    tvec = tv;
    inliers = std::move(refined);
  }
  for (int k : inliers) result->inlier_matches.push_back(idx[k]);
  result->inliers = static_cast<int>(inliers.size());
  cv::Mat r_cv;
  cv::Rodrigues(rvec, r_cv);
  // other_from_with maps the 3D side into the 2D side's camera.
  const Sim3d other_from_with = FromCv(r_cv, tvec);
  result->match_from_query = m_depth ? other_from_with.Inverse() : other_from_with;
  result->pose_kind = RelativePoseKind::kSE3Metric;
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> observed;
  for (int k : inliers) {
    points.emplace_back(object[k].x, object[k].y, object[k].z);
    observed.emplace_back(image[k].x, image[k].y);
  }
  const PoseInformationOptions info_options =
      options.InformationOptions(options.threshold_px / threshold);
  result->information =
      m_depth
          ? PnpInformationPointsInMatch(points, observed, result->match_from_query, info_options)
          : PnpInformationPointsInQuery(points, observed, result->match_from_query, info_options);
}

// The matches of a pair without depths as normalised image points, both as OpenCV points (for
// the RANSAC estimators) and as homogeneous vectors (for the refinement).
struct TwoViewData {
  std::vector<cv::Point2f> pts_match, pts_query;
  std::vector<Eigen::Vector3d> all_m, all_q;
  double threshold = 0;  // inlier threshold, normalised units
};

TwoViewData MakeTwoViewData(const KeyframeRecord& query, const KeyframeRecord& match,
                            const std::vector<DescriptorMatch>& matches, double threshold) {
  TwoViewData d;
  d.threshold = threshold;
  for (const auto& m : matches) {
    const CompactKeypoint& km = match.keypoints[m.train];
    const CompactKeypoint& kq = query.keypoints[m.query];
    d.pts_match.emplace_back(km.x, km.y);
    d.pts_query.emplace_back(kq.x, kq.y);
    d.all_m.emplace_back(km.x, km.y, 1.0);
    d.all_q.emplace_back(kq.x, kq.y, 1.0);
  }
  return d;
}

// query_from_match: x_query = R x_match + t, |t| = 1.
struct TwoViewModel {
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
};

std::vector<uint8_t> InlierMask(const TwoViewData& d, const TwoViewModel& mdl) {
  const Eigen::Matrix3d e = Hat(mdl.t) * mdl.r;
  std::vector<uint8_t> in(d.all_m.size());
  for (size_t i = 0; i < in.size(); ++i)
    in[i] = std::abs(Sampson(e, d.all_m[i], d.all_q[i])) < d.threshold ? 1 : 0;
  return in;
}

// Local optimisation (LO-RANSAC style): refine (R, t) on the inliers, re-select the inliers among
// ALL matches with the refined model, repeat until the set is stable. Returns the inlier mask.
std::vector<uint8_t> LocallyOptimise(const TwoViewData& d, int rounds, TwoViewModel* mdl) {
  std::vector<uint8_t> cur = InlierMask(d, *mdl);
  for (int round = 0; round < rounds; ++round) {
    std::vector<Eigen::Vector3d> xm, xq;
    for (size_t i = 0; i < cur.size(); ++i) {
      if (!cur[i]) continue;
      xm.push_back(d.all_m[i]);
      xq.push_back(d.all_q[i]);
    }
    RefineEssential(xm, xq, d.threshold, &mdl->r, &mdl->t);
    const std::vector<uint8_t> now = InlierMask(d, *mdl);
    const bool changed = now != cur;
    cur = now;
    if (!changed) break;
  }
  return cur;
}

// The decomposition of the refined essential matrix with most inliers in front of both cameras
// (recoverPose), then a cheirality check per inlier; fills inliers, inlier_matches, pose_kind and
// match_from_query (unit translation) of `result`.
void FinishTwoView(const TwoViewData& d, const TwoViewModel& mdl, std::vector<uint8_t> in,
                   VerificationResult* result) {
  const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
  cv::Mat r_cv, t_cv;
  cv::Mat e_cv(3, 3, CV_64F);
  const Eigen::Matrix3d e_ref = Hat(mdl.t) * mdl.r;
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 3; ++x) e_cv.at<double>(y, x) = e_ref(y, x);
  cv::Mat in_mask(static_cast<int>(in.size()), 1, CV_8U);
  for (size_t i = 0; i < in.size(); ++i) in_mask.at<uint8_t>(int(i)) = in[i] ? 255 : 0;
  cv::recoverPose(e_cv, d.pts_match, d.pts_query, eye, r_cv, t_cv, in_mask);
  const Sim3d query_from_match = FromCv(r_cv, t_cv);
  // Cheirality of each inlier under the chosen decomposition: d_q x_q = d_m R x_m + t. A point
  // seen with parallax clearly above the noise must lie in front of both cameras; points with
  // less parallax (far away, or a near-pure rotation) carry no depth sign and stay inliers
  // (recoverPose's own count drops every point farther than 50 baselines).
  const Eigen::Matrix3d rr = query_from_match.rotation.toRotationMatrix();
  const Eigen::Vector3d tt = query_from_match.translation.normalized();
  for (size_t i = 0; i < in.size(); ++i) {
    if (!in[i]) continue;
    const Eigen::Vector3d a = (rr * d.all_m[i]).normalized();
    const Eigen::Vector3d b = d.all_q[i].normalized();
    if (a.cross(b).norm() < 4.0 * d.threshold) continue;  // parallax below ~4 thresholds
    Eigen::Matrix<double, 3, 2> m;
    m.col(0) = a;
    m.col(1) = -b;
    const Eigen::Vector2d depth = m.colPivHouseholderQr().solve(-tt);
    if (depth(0) <= 0 || depth(1) <= 0) in[i] = 0;
  }
  result->inlier_matches.clear();
  for (size_t i = 0; i < in.size(); ++i)
    if (in[i]) result->inlier_matches.push_back(static_cast<int>(i));
  result->inliers = static_cast<int>(result->inlier_matches.size());
  Sim3d match_from_query = query_from_match.Inverse();
  const double n = match_from_query.translation.norm();
  if (n > 0) match_from_query.translation /= n;
  result->match_from_query = match_from_query;
  result->pose_kind = RelativePoseKind::kSE3UnitTranslation;
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
      std::vector<Eigen::Vector3d> q_in, m_in;
      for (int i : r.inliers) {
        q_in.push_back(src[static_cast<size_t>(i)]);
        m_in.push_back(dst[static_cast<size_t>(i)]);
      }
      result.information =
          Sim3Information(q_in, m_in, result.match_from_query, options.InformationOptions(focal));
      result.success = accept(result.inliers);
    }
    if (result.success) return result;
    // 3-point Sim(3) hypotheses from noisy depths (sparse stereo: ~10 % at 4 m) rarely pass a
    // 2 px reprojection check in both cameras: try the match's 3D points against the query's
    // 2D observations (PnP, the paper's image-to-map step), which needs depth on one side only.
    VerificationResult pnp;
    pnp.matches = result.matches;
    VerifyPnp(query, match, matches, /*points_in_match=*/true, options, threshold, &pnp);
    if (pnp.pose_kind != RelativePoseKind::kNone && pnp.inliers > result.inliers) {
      result = std::move(pnp);
      result.success = accept(result.inliers);
    }
    return result;
  }

  if (q_depth || m_depth) {
    VerifyPnp(query, match, matches, /*points_in_match=*/m_depth, options, threshold, &result);
    result.success = result.pose_kind != RelativePoseKind::kNone && accept(result.inliers);
    return result;
  }

  const TwoViewData data = MakeTwoViewData(query, match, matches, threshold);
  if (options.use_fundamental) {
    result.method = VerificationMethod::kFundamental;
    if (matches.size() < 8) return result;
    cv::Mat mask;
    cv::Mat f = cv::findFundamentalMat(data.pts_match, data.pts_query, cv::FM_RANSAC, threshold,
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
  cv::Mat e = cv::findEssentialMat(data.pts_match, data.pts_query, eye, cv::RANSAC,
                                   options.confidence, threshold, options.max_iterations, mask);
  if (e.empty() || e.rows < 3 || mask.empty()) return result;
  cv::Mat r_cv, t_cv;
  // recoverPose keeps the inliers in front of both cameras; x_query = R x_match + t.
  cv::recoverPose(e.rowRange(0, 3), data.pts_match, data.pts_query, eye, r_cv, t_cv, mask);
  const Sim3d q_from_m = FromCv(r_cv, t_cv);
  TwoViewModel model{q_from_m.rotation.toRotationMatrix(), q_from_m.translation.normalized()};
  // Local optimisation of the RANSAC model. Other starts (homography decompositions) are not
  // mixed in here: on castle 29 -> 02 the wrong one of two equally supported planar models has
  // the lower MSAC cost (docs/DETECTOR.md); PlanarAlternatives offers them separately.
  std::vector<uint8_t> in = LocallyOptimise(data, options.local_optimization_rounds, &model);
  FinishTwoView(data, model, in, &result);
  result.success = accept(result.inliers);
  return result;
}

std::vector<VerificationResult> PlanarAlternatives(const KeyframeRecord& query,
                                                   const KeyframeRecord& match,
                                                   const std::vector<DescriptorMatch>& matches,
                                                   const VerificationResult& primary,
                                                   const VerifyOptions& options) {
  options.Check();
  std::vector<VerificationResult> out;
  if (primary.method != VerificationMethod::kEssential ||
      primary.pose_kind != RelativePoseKind::kSE3UnitTranslation || matches.size() < 8) {
    return out;
  }
  const float focal = std::max(1.0f, 0.5f * (query.focal_px + match.focal_px));
  const double threshold = options.threshold_px / focal;
  cv::theRNG().state = options.seed;
  const TwoViewData data = MakeTwoViewData(query, match, matches, threshold);
  cv::Mat h_mask;
  const cv::Mat h = cv::findHomography(data.pts_match, data.pts_query, cv::RANSAC, threshold,
                                       h_mask, options.max_iterations, options.confidence);
  if (h.empty() || h_mask.empty() || cv::countNonZero(h_mask) < options.min_inliers) return out;
  std::vector<cv::Mat> rotations, translations, normals;
  // Normalised coordinates: the camera matrix is the identity. x_query ~ (R + t n^T / d) x_match.
  cv::decomposeHomographyMat(h, cv::Mat::eye(3, 3, CV_64F), rotations, translations, normals);
  std::vector<Eigen::Matrix3d> seen = {primary.match_from_query.rotation.toRotationMatrix()};
  for (size_t k = 0; k < rotations.size(); ++k) {
    Eigen::Vector3d t;
    cv::cv2eigen(translations[k], t);
    if (t.norm() < 1e-9) continue;  // a pure rotation has no essential matrix
    const Sim3d q_from_m = FromCv(rotations[k], translations[k]);
    TwoViewModel model{q_from_m.rotation.toRotationMatrix(), t.normalized()};
    // The decomposition as it is, not refined as an essential matrix: on near-planar inliers
    // the essential matrix is ill-conditioned and the refinement slides along the plane's
    // ambiguity (EuRoC pair (2,3): 2.37 deg from the GT unrefined, 3.06 deg refined).
    const std::vector<uint8_t> in = InlierMask(data, model);
    VerificationResult alt;
    alt.method = VerificationMethod::kEssential;
    alt.matches = static_cast<int>(matches.size());
    FinishTwoView(data, model, in, &alt);
    if (alt.inliers < options.min_inliers ||
        alt.inliers < options.min_inlier_ratio * static_cast<double>(matches.size())) {
      continue;
    }
    // Distinct from the primary and from each other (the decompositions come in +-t pairs and
    // several starts converge to one optimum).
    const Eigen::Matrix3d r = alt.match_from_query.rotation.toRotationMatrix();
    bool duplicate = false;
    for (const Eigen::Matrix3d& s : seen)
      duplicate |= RotationAngle(Eigen::Quaterniond(s), Eigen::Quaterniond(r)) < 0.5 * M_PI / 180;
    if (duplicate) continue;
    seen.push_back(r);
    alt.success = true;
    out.push_back(std::move(alt));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const VerificationResult& a, const VerificationResult& b) {
                     return a.inliers > b.inliers;
                   });
  return out;
}

}  // namespace sparseloop
