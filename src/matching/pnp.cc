// The PnP estimator of VerifyPair: depths on one side only (or Sim(3) falling short).
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "matching/verification_internal.h"
#include "sparseloop/core/check.h"
#include "sparseloop/matching/pose_information.h"

namespace sparseloop::matching_internal {
namespace {

// Minimal-sample PnP RANSAC: 3 correspondences per sample (cv::solveP3P, AP3P: up to 4 poses),
// each pose scored by the points in front of the camera that reproject within `threshold`
// (normalised image units); the pose with the most inliers wins (the first on ties). Seeded.
// A 3-point sample needs far fewer iterations than EPnP's 5 at few matches (15 matches, floor 6:
// 154 against 1000): what makes a failing pair cheap (the K = 15 preset's verification tail).
bool RansacP3P(const std::vector<cv::Point3f>& object, const std::vector<cv::Point2f>& image,
               double threshold, int iterations, uint64_t seed, cv::Mat* rvec, cv::Mat* tvec,
               std::vector<int>* inliers) {
  const int n = static_cast<int>(object.size());
  if (n < 4) return false;
  std::vector<Eigen::Vector3d> p(object.size());
  for (size_t i = 0; i < object.size(); ++i) p[i] = {object[i].x, object[i].y, object[i].z};
  const double t2 = threshold * threshold;
  const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<int> in;
  inliers->clear();
  for (int it = 0; it < iterations; ++it) {
    const int a = pick(rng), b = pick(rng), c = pick(rng);
    if (a == b || b == c || a == c) continue;
    const std::vector<cv::Point3f> obj = {object[a], object[b], object[c]};
    const std::vector<cv::Point2f> img = {image[a], image[b], image[c]};
    std::vector<cv::Mat> rvecs, tvecs;
    if (cv::solveP3P(obj, img, eye, cv::noArray(), rvecs, tvecs, cv::SOLVEPNP_AP3P) <= 0) continue;
    for (size_t s = 0; s < rvecs.size(); ++s) {
      cv::Mat r_cv;
      cv::Rodrigues(rvecs[s], r_cv);
      Eigen::Matrix3d r;
      Eigen::Vector3d t;
      cv::cv2eigen(r_cv, r);
      cv::cv2eigen(tvecs[s], t);
      in.clear();
      for (int k = 0; k < n; ++k) {
        const Eigen::Vector3d q = r * p[k] + t;
        if (q.z() <= 0) continue;
        const double du = q.x() / q.z() - image[k].x, dv = q.y() / q.z() - image[k].y;
        if (du * du + dv * dv <= t2) in.push_back(k);
      }
      if (in.size() > inliers->size()) {
        *inliers = in;
        rvecs[s].convertTo(*rvec, CV_64F);
        tvecs[s].convertTo(*tvec, CV_64F);
      }
    }
    if (static_cast<int>(inliers->size()) == n) break;
  }
  return inliers->size() >= 4;
}

}  // namespace

// PnP: 3D points (keypoint bearing x depth) of the side with depths, 2D observations on the
// other; P3P inside RANSAC (RansacP3P), then Levenberg-Marquardt on the inliers and one
// re-collection of the inliers with the refined pose (a pose from a minimal set is noisy with
// stereo-grade depths). Sets method, inliers, inlier_matches, match_from_query and pose_kind (kNone
// on failure).
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
  cv::Mat rvec, tvec;
  const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
  constexpr int kP3PSample = 3;
  std::vector<int> inliers;
  if (!RansacP3P(object, image, threshold,
                 IterationsToFindPassingModel(options, object.size(), kP3PSample), options.seed,
                 &rvec, &tvec, &inliers)) {
    return;
  }
  if (inliers.size() >= 6) {  // EPnP on all the sample's inliers, as solvePnPRansac ends
    std::vector<cv::Point3f> obj_in;
    std::vector<cv::Point2f> img_in;
    for (int k : inliers) {
      obj_in.push_back(object[k]);
      img_in.push_back(image[k]);
    }
    cv::Mat rv, tv;
    if (cv::solvePnP(obj_in, img_in, eye, cv::noArray(), rv, tv, false, cv::SOLVEPNP_EPNP)) {
      rvec = rv;
      tvec = tv;
    }
  }
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
