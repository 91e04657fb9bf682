// The PnP estimator of VerifyPair: depths on one side only (or Sim(3) falling short).
#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "matching/verification_internal.h"
#include "sparseloop/core/check.h"
#include "sparseloop/matching/pose_information.h"

namespace sparseloop::matching_internal {

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
  constexpr int kEpnpSample = 5;  // solvePnPRansac's sample for EPnP
  const int iterations = IterationsToFindPassingModel(options, object.size(), kEpnpSample);
  const bool ok =
      cv::solvePnPRansac(object, image, eye, cv::noArray(), rvec, tvec, false, iterations,
                         threshold, options.confidence, inl, cv::SOLVEPNP_EPNP);
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

}  // namespace sparseloop::matching_internal
