// The Sim(3) estimator of VerifyPair: depths on both sides (3-point RANSAC on the 3D points),
// with PnP of the match's points when that falls short.
#include <algorithm>
#include <cmath>
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
  // pairs ran all max_iterations, the K = 15 preset's verification tail on renders with
  // depths.
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
    if (options.scale_from_query_depths_min > 0)
      AddScaleFromQueryDepths(query, match, matches, options, options.scale_from_query_depths_min,
                              result);
  }
}

}  // namespace sparseloop::matching_internal

namespace sparseloop {

bool AddScaleFromQueryDepths(const KeyframeRecord& query, const KeyframeRecord& match,
                             const std::vector<DescriptorMatch>& matches,
                             const VerifyOptions& options, int min_pairs,
                             VerificationResult* result) {
  if (result->pose_kind != RelativePoseKind::kSE3Metric || !query.has_depths() ||
      !match.has_depths())
    return false;
  const Sim3d query_from_match = result->match_from_query.Inverse();
  std::vector<double> log_ratio;
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> observed;
  for (int i : result->inlier_matches) {
    const DescriptorMatch& m = matches[static_cast<size_t>(i)];
    const float zm = match.depths[static_cast<size_t>(m.train)];
    const float zq = query.depths[static_cast<size_t>(m.query)];
    const CompactKeypoint& kq = query.keypoints[static_cast<size_t>(m.query)];
    points.push_back(double(zm) * matching_internal::Bearing(match.keypoints[m.train]));
    observed.emplace_back(kq.x, kq.y);
    if (zq <= 0 || zm <= 0) continue;
    const double z = (query_from_match * points.back()).z();
    if (z > 0) log_ratio.push_back(std::log(z / zq));
  }
  if (static_cast<int>(log_ratio.size()) < std::max(1, min_pairs)) return false;
  std::vector<double> sorted = log_ratio;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median = sorted[sorted.size() / 2];
  // Robust spread: 1.4826 x the median absolute deviation, floored (a few identical ratios).
  std::vector<double> dev;
  for (double r : log_ratio) dev.push_back(std::abs(r - median));
  std::nth_element(dev.begin(), dev.begin() + dev.size() / 2, dev.end());
  const double sigma = std::max(1.4826 * dev[dev.size() / 2], 1e-3);
  result->match_from_query.scale = std::exp(median);
  // The PnP information again at the scaled pose (its translation columns scale with s).
  const float focal = std::max(1.0f, 0.5f * (query.focal_px + match.focal_px));
  result->information = PnpInformationPointsInMatch(points, observed, result->match_from_query,
                                                    options.InformationOptions(focal));
  result->information(6, 6) += static_cast<double>(log_ratio.size()) / (sigma * sigma);
  result->pose_kind = RelativePoseKind::kSim3;
  return true;
}

}  // namespace sparseloop
