#pragma once
// Geometric verification of a descriptor-matched keyframe pair: essential matrix (5-point RANSAC
// on normalised coordinates), PnP (depths on one side) or 3D-3D Sim(3) (depths on both sides).
// All seeded, deterministic.
#include <cstdint>
#include <string>
#include <vector>

#include "sparseloop/core/sim3.h"
#include "sparseloop/features/informative_features.h"
#include "sparseloop/matching/descriptor_matching.h"
#include "sparseloop/matching/pose_information.h"

namespace sparseloop {

enum class VerificationMethod { kEssential, kPnP, kSim3 };
const char* ToString(VerificationMethod method);

// What the relative pose of a verified pair means.
enum class RelativePoseKind {
  kNone,                // no pose (the pair did not verify)
  kSE3UnitTranslation,  // rotation + translation direction (|t| = 1), monocular two-view
  kSE3Metric,           // rotation + translation in the depth units of one side (PnP)
  kSim3,                // rotation, translation and scale (3D-3D with depths on both sides)
};
const char* ToString(RelativePoseKind kind);

struct VerifyOptions {
  double threshold_px = 2.0;  // RANSAC inlier threshold, pixels (divided by the focal length)
  double confidence = 0.999;  // RANSAC confidence, probability in (0, 1)
  int max_iterations = 1000;  // RANSAC iterations, count
  // Essential matrix: rounds of local optimisation after RANSAC (refine R, t on the inliers by
  // Levenberg-Marquardt, re-select inliers among all matches), count >= 0 (0 = RANSAC model only).
  int local_optimization_rounds = 5;
  int min_inliers = 12;           // a pair with fewer geometric inliers fails, count
  double min_inlier_ratio = 0.0;  // inliers / matches below this fail, ratio in [0, 1]
  bool use_depths = true;         // use PnP / Sim(3) when depths exist
  // Depths on both sides and the Sim(3) RANSAC falls short: the PnP fallback's relative scale is
  // measured from the query's depths (AddScaleFromQueryDepths) when at least this many of its
  // inliers have one; 0 leaves the PnP pose at scale 1 (kSE3Metric), count.
  int scale_from_query_depths_min = 5;
  uint64_t seed = 42;  // RNG seed (cv::theRNG and the Sim(3) RANSAC)
  // Floor of the residual sigma behind VerificationResult::information, pixels: a handful of
  // near-perfect inliers must not claim a sub-pixel pose (ORB keypoints are localised to about
  // half a pixel at the finest level).
  double information_min_sigma_px = 0.5;
  // The PoseInformationOptions for a pair with this (mean) focal length, pixels.
  PoseInformationOptions InformationOptions(double focal_px) const {
    return PoseInformationOptions{information_min_sigma_px / focal_px, threshold_px / focal_px};
  }
  void Check() const;
};

struct VerificationResult {
  bool success = false;  // enough inliers and a valid model
  VerificationMethod method = VerificationMethod::kEssential;
  int inliers = 0;  // geometric inliers, count
  int matches = 0;  // descriptor matches tested, count
  RelativePoseKind pose_kind = RelativePoseKind::kNone;
  // Pose of the query camera in the match camera: p_in_match = match_from_query * p_in_query.
  Sim3d match_from_query;
  // PnP / Sim(3): the information of match_from_query from its inliers at the solution
  // (pose_information.h; tangent [upsilon, omega, sigma] of a right perturbation, normalised
  // image units). Zero for two-view (essential / fundamental) results.
  PoseInformation7 information = PoseInformation7::Zero();
  std::vector<int> inlier_matches;  // indices into the matches
};

VerificationResult VerifyPair(const KeyframeRecord& query, const KeyframeRecord& match,
                              const std::vector<DescriptorMatch>& matches,
                              const VerifyOptions& options);

// A PnP pose of the match's 3D points against the query's observations (kSE3Metric, scale 1)
// fixes the query camera in match units. Where the query has depths of its own (query units),
// the same inliers give the relative scale directly: s_i = z(query_from_match * P_i) / z_query,i,
// robustly the median; the pose becomes kSim3 with scale s and information: the PnP information
// at the scaled pose plus n / var(log s_i) on the scale (var from 1.4826 x the MAD, floored at
// 1e-3). A 3-point Sim(3) RANSAC between two noisy clouds rarely passes a 2 px check in both
// cameras; this needs no 3D-3D hypothesis. With scale 1 instead, a loop under scale drift carries
// the drift between its two places as an error (10-40 % at 4x the renders' drift) and PCM rejects
// it. Returns false and leaves *result unchanged when fewer than `min_pairs` inliers have both
// depths or *result is not a kSE3Metric pose.
bool AddScaleFromQueryDepths(const KeyframeRecord& query, const KeyframeRecord& match,
                             const std::vector<DescriptorMatch>& matches,
                             const VerifyOptions& options, int min_pairs,
                             VerificationResult* result);

// Other two-view poses the same matches support, for a pair VerifyPair verified by the essential
// matrix (no depths): a homography is fitted to the matches (RANSAC, seeded) and each of its
// decompositions is refined as an essential matrix on all matches, exactly as VerifyPair refines
// its RANSAC model. In a near-planar scene two-view geometry is ambiguous: the lowest-cost model
// and another one (the plane's twin) are both supported, and the lowest cost may be the wrong one
// (EuRoC pair (2,3): 21 deg off the GT, the homography's twin 1-2 deg; docs/DETECTOR.md). Returns
// the models that pass min_inliers / min_inlier_ratio and differ from `primary`'s rotation (and
// from each other) by >= 0.5 deg, most inliers first; empty for any other method. The caller
// decides with independent evidence (the loop detector: the pose prior) whether to use one.
std::vector<VerificationResult> PlanarAlternatives(const KeyframeRecord& query,
                                                   const KeyframeRecord& match,
                                                   const std::vector<DescriptorMatch>& matches,
                                                   const VerificationResult& primary,
                                                   const VerifyOptions& options);

}  // namespace sparseloop
