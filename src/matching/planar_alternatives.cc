// PlanarAlternatives: the other poses of a homography's decomposition, offered when the
// two-view pose disagrees with the pose prior (docs/DETECTOR.md, "Planar alternatives").
#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "matching/verification_internal.h"
#include "sparseloop/core/check.h"

namespace sparseloop {

using matching_internal::FinishTwoView;
using matching_internal::FromCv;
using matching_internal::InlierMask;
using matching_internal::MakeTwoViewData;
using matching_internal::TwoViewData;
using matching_internal::TwoViewModel;

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
