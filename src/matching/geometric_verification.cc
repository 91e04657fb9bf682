#include "sparseloop/matching/geometric_verification.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "matching/verification_internal.h"
#include "sparseloop/core/check.h"
#include "sparseloop/matching/sim3_solver.h"

namespace sparseloop {

const char* ToString(VerificationMethod method) {
  switch (method) {
    case VerificationMethod::kEssential:
      return "essential";
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
  // An upper bound keeps a pair's cost bounded when the inlier ratio is low (no early stop).
  SL_CHECK_MSG(max_iterations >= 1 && max_iterations <= 100000,
               "verify.max_iterations must be in [1, 100000], got {}", max_iterations);
  SL_CHECK_MSG(local_optimization_rounds >= 0 && local_optimization_rounds <= 100,
               "verify.local_optimization_rounds must be in [0, 100], got {}",
               local_optimization_rounds);
  SL_CHECK_MSG(std::isfinite(information_min_sigma_px) && information_min_sigma_px > 0,
               "verify.information_min_sigma_px must be > 0 pixels, got {}",
               information_min_sigma_px);
  SL_CHECK_MSG(scale_from_query_depths_min == 0 || scale_from_query_depths_min >= 3,
               "verify.scale_from_query_depths_min must be 0 (off) or >= 3, got {}",
               scale_from_query_depths_min);
  SL_CHECK_MSG(min_inliers >= 5, "verify.min_inliers must be >= 5, got {}", min_inliers);
  SL_CHECK_MSG(min_inlier_ratio >= 0 && min_inlier_ratio <= 1,
               "verify.min_inlier_ratio must be in [0, 1], got {}", min_inlier_ratio);
}

using matching_internal::Accepted;
using matching_internal::MakeTwoViewData;
using matching_internal::TwoViewData;
using matching_internal::VerifyEssential;
using matching_internal::VerifyPnp;
using matching_internal::VerifySim3;

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
  auto accept = [&](int inliers) { return Accepted(options, inliers, matches.size()); };

  if (q_depth && m_depth) {
    VerifySim3(query, match, matches, options, threshold, focal, &result);
    return result;
  }

  if (q_depth || m_depth) {
    VerifyPnp(query, match, matches, /*points_in_match=*/m_depth, options, threshold, &result);
    result.success = result.pose_kind != RelativePoseKind::kNone && accept(result.inliers);
    return result;
  }

  const TwoViewData data = MakeTwoViewData(query, match, matches, threshold);
  VerifyEssential(data, matches.size(), options, &result);
  result.success = accept(result.inliers);
  return result;
}

}  // namespace sparseloop
