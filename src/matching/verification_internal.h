#pragma once
// Internal to the matching module: the pieces the estimators of VerifyPair share
// (geometric_verification.cc dispatches; essential.cc, pnp.cc, sim3 / fundamental in
// geometric_verification.cc, planar_alternatives.cc). One estimator per file, as PoseLib does.
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "sparseloop/matching/geometric_verification.h"

namespace sparseloop::matching_internal {

// R (3x3) and t (3x1) from OpenCV as a Sim(3) with `scale`.
Sim3d FromCv(const cv::Mat& r_cv, const cv::Mat& t_cv, double scale = 1.0);

inline Eigen::Vector3d Bearing(const CompactKeypoint& k) { return {k.x, k.y, 1.0}; }

// PnP: 3D points (keypoint bearing x depth) of the side with depths, 2D observations on the
// other; EPnP inside RANSAC, then Levenberg-Marquardt on the inliers and one re-collection of
// the inliers with the refined pose (EPnP from a minimal set is noisy with stereo-grade depths).
// Sets method, inliers, inlier_matches, match_from_query and pose_kind (kNone on failure).
void VerifyPnp(const KeyframeRecord& query, const KeyframeRecord& match,
               const std::vector<DescriptorMatch>& matches, bool points_in_match,
               const VerifyOptions& options, double threshold, VerificationResult* result);

// The matches of a pair without depths as normalised image points, both as OpenCV points (for
// the RANSAC estimators) and as homogeneous vectors (for the refinement).
struct TwoViewData {
  std::vector<cv::Point2f> pts_match, pts_query;
  std::vector<Eigen::Vector3d> all_m, all_q;
  double threshold = 0;  // inlier threshold, normalised units
};

TwoViewData MakeTwoViewData(const KeyframeRecord& query, const KeyframeRecord& match,
                            const std::vector<DescriptorMatch>& matches, double threshold);

// query_from_match: x_query = R x_match + t, |t| = 1.
struct TwoViewModel {
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  // A prior on the refined pose (RefineFromPrior): residuals LogSO3(R prior_r^T) and
  // t - prior_t, each times prior_weight (normalised image units per radian), beside the
  // Sampson distances. 0 = no prior.
  double prior_weight = 0.0;
  Eigen::Matrix3d prior_r = Eigen::Matrix3d::Identity();
  Eigen::Vector3d prior_t = Eigen::Vector3d::Zero();
};

// Matches whose Sampson distance under the model is below the threshold.
std::vector<uint8_t> InlierMask(const TwoViewData& d, const TwoViewModel& mdl);
// Local optimisation (LO-RANSAC style): refine (R, t) on the inliers, re-select the inliers among
// ALL matches with the refined model, repeat until the set is stable. Returns the inlier mask.
std::vector<uint8_t> LocallyOptimise(const TwoViewData& d, int rounds, TwoViewModel* mdl);
// Local optimisation from a given model (a prior pose near the truth, not a RANSAC sample): the
// inlier threshold starts at `initial_threshold` (normalised units, wide enough for the prior's
// error) and halves down to d.threshold, with LocallyOptimise at each. Starting near the truth
// keeps it in the right basin where a RANSAC over a planar scene can pick a wrong decomposition.
// Returns the inlier mask at d.threshold.
std::vector<uint8_t> RefineFromPrior(const TwoViewData& d, double initial_threshold, int rounds,
                                     TwoViewModel* mdl);
// The decomposition of the refined essential matrix with most inliers in front of both cameras
// (recoverPose), then a cheirality check per inlier; fills inliers, inlier_matches, pose_kind and
// match_from_query (unit translation) of `result`.
void FinishTwoView(const TwoViewData& d, const TwoViewModel& mdl, std::vector<uint8_t> in,
                   VerificationResult* result);

// The essential-matrix estimator (no depths): RANSAC, local optimisation, decomposition; sets
// method, inliers, inlier_matches, match_from_query and pose_kind (kNone on failure).
void VerifyEssential(const TwoViewData& data, size_t num_matches, const VerifyOptions& options,
                     VerificationResult* result);

// RANSAC iterations after which a model with the fewest inliers a pair needs to pass
// (options.min_inliers, min_inlier_ratio) has been found with probability options.confidence, if
// one exists: the chance that a sample of `sample_size` of the `num_matches` points is all
// inliers of it is prod_i (m - i) / (n - i). A weaker model fails anyway, so searching longer
// for one only costs time (false pairs ran all max_iterations: the K = 15 preset's verification
// tail).
// At least 100 (noisy minimal samples at few matches) and at most options.max_iterations.
int IterationsToFindPassingModel(const VerifyOptions& options, size_t num_matches, int sample_size);

// VerifyOptions' acceptance of a pose with `inliers` of `num_matches` matches.
inline bool Accepted(const VerifyOptions& options, int inliers, size_t num_matches) {
  return inliers >= options.min_inliers &&
         inliers >= options.min_inlier_ratio * static_cast<double>(num_matches);
}

// Depths on both sides: 3-point Sim(3) RANSAC on the 3D points, and when that is not accepted,
// PnP of the match's 3D points against the query's observations. Fills *result (success too).
void VerifySim3(const KeyframeRecord& query, const KeyframeRecord& match,
                const std::vector<DescriptorMatch>& matches, const VerifyOptions& options,
                double threshold, float focal, VerificationResult* result);

}  // namespace sparseloop::matching_internal
