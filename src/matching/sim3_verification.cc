// The Sim(3) estimator of VerifyPair: depths on both sides (3-point RANSAC on the 3D points),
// with PnP of the match's points when that falls short.
#include <utility>
#include <vector>

#include "matching/verification_internal.h"
#include "sparseloop/matching/pose_information.h"
#include "sparseloop/matching/sim3_solver.h"

namespace sparseloop::matching_internal {

void VerifySim3(const KeyframeRecord& query, const KeyframeRecord& match,
                const std::vector<DescriptorMatch>& matches, const VerifyOptions& options,
                double threshold, float focal, VerificationResult* result) {
  result->method = VerificationMethod::kSim3;
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
  constexpr int kSim3Sample = 3;  // RansacSim3's minimal sample
  so.max_error = threshold;
  // Stop once a passing model would have been found (as essential and PnP RANSAC do): failing
  // pairs ran all max_iterations, the verification tail of #19 on renders with depths.
  so.max_iterations = IterationsToFindPassingModel(options, src.size(), kSim3Sample);
  so.min_inliers = options.min_inliers;
  so.seed = options.seed;
  auto r = RansacSim3(src, dst, so);
  if (r.success) {
    for (int i : r.inliers) result->inlier_matches.push_back(idx[i]);
    result->inliers = static_cast<int>(r.inliers.size());
    result->match_from_query = r.target_from_source;
    result->pose_kind = RelativePoseKind::kSim3;
    std::vector<Eigen::Vector3d> q_in, m_in;
    for (int i : r.inliers) {
      q_in.push_back(src[static_cast<size_t>(i)]);
      m_in.push_back(dst[static_cast<size_t>(i)]);
    }
    result->information =
        Sim3Information(q_in, m_in, result->match_from_query, options.InformationOptions(focal));
    result->success = Accepted(options, result->inliers, matches.size());
  }
  if (result->success) return;
  // 3-point Sim(3) hypotheses from noisy depths (sparse stereo: ~10 % at 4 m) rarely pass a
  // 2 px reprojection check in both cameras: try the match's 3D points against the query's
  // 2D observations (PnP, the paper's image-to-map step), which needs depth on one side only.
  VerificationResult pnp;
  pnp.matches = result->matches;
  VerifyPnp(query, match, matches, /*points_in_match=*/true, options, threshold, &pnp);
  if (pnp.pose_kind != RelativePoseKind::kNone && pnp.inliers > result->inliers) {
    *result = std::move(pnp);
    result->success = Accepted(options, result->inliers, matches.size());
  }
}

}  // namespace sparseloop::matching_internal
