#pragma once
// The loop-closure detector of the paper (Algorithm 1): informative features per keyframe, a
// geometric search area on the raw trajectory, Hamming matching of the K stored descriptors and
// geometric verification, plus a consistency check against the raw pose prior.
// Synchronous and deterministic: the same inputs and options give the same results.
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "sparseloop/core/camera.h"
#include "sparseloop/core/sim3.h"
#include "sparseloop/features/informative_features.h"
#include "sparseloop/matching/descriptor_matching.h"
#include "sparseloop/matching/geometric_verification.h"
#include "sparseloop/search/search_area.h"

namespace sparseloop {

struct KeyframeInput {
  int64_t id = 0;          // unique keyframe id, increasing in time
  double timestamp = 0.0;  // seconds
  cv::Mat image;           // CV_8UC1 grayscale
  CameraIntrinsics intrinsics;
  // Raw vSLAM pose (any scale; SE(3) poses convert with Sim3d(rigid)). Absent: no geometric search
  // area and no pose-prior check (only SearchStrategy::kGlobal is allowed).
  std::optional<Sim3d> world_from_cam;
  // Optional informative area: pixels the vSLAM mapped (feature-based SLAM) with optional depths
  // (same length, <= 0 unknown, in the pose's units), or a mask of its high-gradient pixels.
  std::vector<cv::Point2f> mapped_pixels;
  std::vector<float> mapped_depths;
  cv::Mat high_gradient_mask;  // CV_8UC1, non-zero = mapped
};

enum class LoopStatus {
  kDetected,               // a verified, consistent loop
  kSkipped,                // not a check keyframe (every-N rule); features were stored
  kNoFeatures,             // fewer than 5 features extracted
  kNoCandidates,           // the search area is empty
  kTooFewMatches,          // no candidate has enough descriptor matches
  kTooFewInliers,          // no candidate passed geometric verification
  kRejectedByConsistency,  // verified, but the rotation disagrees with the raw pose prior
  kRejectedByTemporal,     // verified, but not confirmed by the previous check keyframe
};
const char* ToString(LoopStatus status);

struct StageTimings {
  double extract_ms = 0.0;  // feature extraction, ms
  double search_ms = 0.0;   // search area, ms
  double match_ms = 0.0;    // descriptor matching against all candidates, ms
  double verify_ms = 0.0;   // geometric verification, ms
  double total_ms = 0.0;    // whole Process() call, ms
};

struct LoopResult {
  LoopStatus status = LoopStatus::kNoCandidates;
  int64_t query_id = 0;   // the processed keyframe
  int64_t match_id = -1;  // best candidate (-1 when none was matched)
  int candidates = 0;     // keyframes in the search area after filtering, count
  int matches = 0;        // descriptor matches with match_id, count
  int inliers = 0;        // geometric inliers with match_id, count
  double score = 0.0;     // inliers / K (K = options.features.max_features), in [0, 1]
  VerificationMethod method = VerificationMethod::kEssential;
  RelativePoseKind pose_kind = RelativePoseKind::kNone;
  // p_in_match = match_from_query * p_in_query; see pose_kind for what is meaningful.
  Sim3d match_from_query;
  double rotation_error_vs_prior_deg = -1.0;  // -1 when no prior was available
  StageTimings timings;
  bool detected() const { return status == LoopStatus::kDetected; }
};

class LoopDetector {
 public:
  struct Options {
    FeatureOptions features;                     // informative ORB (K = features.max_features)
    SearchAreaOptions search = DefaultSearch();  // search area on the raw trajectory
    MatchOptions match;                          // Hamming matching
    VerifyOptions verify;                        // geometric verification (seed inside)
    int check_every = 1;   // run the loop check every N keyframes (paper's N), keyframes >= 1
    int min_matches = 12;  // candidates with fewer descriptor matches are not verified, count
    int max_verify = 3;    // best-ranked candidates verified geometrically, count
    // The inlier threshold grows with K: a pair needs max(verify.min_inliers,
    // ceil(min_inlier_fraction_of_k * K)) inliers (more features = more chance inliers between
    // unrelated but similar-looking places). Fraction in [0, 1].
    double min_inlier_fraction_of_k = 0.08;
    // A candidate must be "far along the path": path length between it and the query >=
    // min_path_ratio * straight-line distance (scale-free; rejects the recent, still-overlapping
    // stretch of a forward motion). Needs poses; 0 disables. ratio >= 0.
    double min_path_ratio = 3.0;
    // Pose-prior consistency: |angle(R_verified, R_prior)| <= min(max, base + per_keyframe * n),
    // n = keyframes since the last accepted loop (or since the start). Degrees.
    bool check_consistency = true;
    double consistency_base_deg = 10.0;
    double consistency_per_keyframe_deg = 0.1;
    double consistency_max_deg = 45.0;
    // Temporal consistency: accept only when the previous check keyframe also verified a match
    // within temporal_window keyframes (by index) of this match.
    bool temporal_check = false;
    int temporal_window = 3;  // keyframes
    uint64_t seed = 42;       // copied into verify.seed
    void Check() const;
    // The inlier threshold actually applied: max(verify.min_inliers, ceil(fraction * K)).
    int EffectiveMinInliers() const;
    static SearchAreaOptions DefaultSearch() {
      SearchAreaOptions s;
      s.exclude_recent = 10;
      return s;
    }
  };

  explicit LoopDetector(Options options);

  // Extracts and stores the keyframe's features, then (every N keyframes) searches for a loop.
  LoopResult Process(const KeyframeInput& input);

  const Options& options() const { return options_; }
  size_t num_keyframes() const { return records_.size(); }
  const KeyframeRecord& record(int64_t id) const;
  // Sum of KeyframeRecord::Bytes() over the stored keyframes.
  size_t StoredBytes() const;

  // Query/match against stored records only (no extraction), for benchmarks and tests: matches
  // `query` against the given candidate ids and verifies the best.
  LoopResult MatchAgainst(const KeyframeRecord& query, const std::vector<int64_t>& candidate_ids);

 private:
  void SearchAndVerify(const KeyframeRecord& query, std::vector<int64_t> candidates,
                       LoopResult* result);

  Options options_;
  VerifyOptions verify_;  // options_.verify with the effective min_inliers and seed
  SearchArea search_;
  std::vector<KeyframeRecord> records_;
  std::vector<double> path_length_;  // cumulative path length at each keyframe (pose units)
  std::unordered_map<int64_t, size_t> index_of_;
  int64_t last_loop_index_ = 0;  // keyframe index of the last accepted loop (or 0)
  std::optional<std::pair<size_t, size_t>> last_verified_;  // (query index, match index)
  bool any_pose_ = false;
  bool any_missing_pose_ = false;
};

}  // namespace sparseloop
