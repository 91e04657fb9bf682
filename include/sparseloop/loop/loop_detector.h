#pragma once
// The loop-closure detector of the paper (Algorithm 1): informative features per keyframe, a
// geometric search area on the raw trajectory, Hamming matching of the K stored descriptors and
// geometric verification, plus a consistency check against the raw pose prior.
// Synchronous and deterministic: the same inputs and options give the same results.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "sparseloop/core/camera.h"
#include "sparseloop/core/sim3.h"
#include "sparseloop/loop/loop_detector_options.h"
#include "sparseloop/matching/geometric_verification.h"

namespace sparseloop {

struct KeyframeInput {
  int64_t id = 0;          // unique keyframe id, increasing in time
  double timestamp = 0.0;  // seconds
  cv::Mat image;           // CV_8UC1 grayscale
  CameraIntrinsics intrinsics;
  // Raw vSLAM pose (any scale; SE(3) poses convert with Sim3d(rigid)). Absent: no geometric search
  // area and no pose-prior check. With SearchStrategy::kGlobal the keyframe is searched globally
  // as usual; with another strategy it is treated as "tracking lost" and relocalised against every
  // stored keyframe with a pose (Options::relocalize_without_pose; see LoopDetector::Relocalize).
  std::optional<Sim3d> world_from_cam;
  // The vSLAM re-initialised (tracking lost, a new map): world_from_cam is in a new world frame
  // (origin, orientation, scale) from this keyframe on. The detector starts a new pose segment:
  // the search area and the pose checks use this segment's keyframes only, and the earlier
  // segments are searched by appearance (a found place is a relocalisation, CandidateSource::
  // kEarlierSegment). Needs world_from_cam. Without the flag the detector still notices a raw pose
  // that jumps (Options::pose_jump_factor / pose_jump_max_deg / pose_jump_max_scale).
  bool pose_reset = false;
  // Optional: what the vSLAM knows of the uncertainty of its raw step from the previous keyframe
  // with a pose to this one (LoopClosing's odometry edge; the detector ignores it): covariance of
  // the relative pose in tangent order [translation(3), rotation(3)] (raw units^2, rad^2; the order
  // of a ROS 6x6 pose covariance), symmetric positive definite. Absent: the default model
  // (OdometryWeighting: a fraction of the step length, a rotation sigma per step).
  std::optional<Eigen::Matrix<double, 6, 6>> odometry_covariance;
  // Optional informative area: pixels the vSLAM mapped (feature-based SLAM) with optional depths
  // (same length, <= 0 unknown, in the pose's units), or a mask of its high-gradient pixels.
  // Pixels and depths must be finite (Process refuses NaN / infinity naming the entry).
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
  kRejectedByTemporal,     // verified, but a weak pair without agreement, or no revisit
};
const char* ToString(LoopStatus status);

// Where the loop's candidate came from.
enum class CandidateSource {
  kSearchArea,  // the search area on the raw trajectory (the paper's wedge, or global search)
  kAppearance,  // the appearance fallback over every stored keyframe (Options::appearance_fallback)
  kEarlierSegment,  // a keyframe before a raw pose reset, by appearance (a relocalisation)
};
const char* ToString(CandidateSource source);  // "area" | "appearance" | "segment"

// Why a keyframe starts a new pose segment (KeyframeInput::pose_reset, Options::pose_jump_*).
enum class PoseReset {
  kNone,             // same world frame as the keyframe before
  kCaller,           // KeyframeInput::pose_reset
  kTranslationJump,  // the raw step is pose_jump_factor x longer than the segment's usual step
  kRotationJump,     // the raw rotation step exceeds pose_jump_max_deg
  kScaleJump,        // the Sim(3) scale changed by more than pose_jump_max_scale x
};
const char* ToString(PoseReset reset);  // "none" | "caller" | "translation" | "rotation" | "scale"

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
  // Their ids, ascending (far along the path, the overlap walk; before the kAnn retrieval, which
  // compares only its top-voted): the stored keyframes this query could find by the area. Empty
  // when the area did not run (relocalisation, non-check keyframe). frames.csv column `area`.
  std::vector<int64_t> area;
  // Query without a pose: search-area keyframes dropped because they still share the scene with
  // the query (Options::overlap_gap), count; 0 otherwise.
  int overlap_excluded = 0;
  // Keyframes the appearance fallback matched with the whole extraction (after its pre-ranking,
  // Options::fallback_candidates), count; 0 when the fallback did not run.
  int appearance_candidates = 0;
  // kAppearance when the search area gave no loop and the appearance fallback found match_id;
  // kEarlierSegment when match_id is before a raw pose reset (then relocalization is true).
  CandidateSource source = CandidateSource::kSearchArea;
  // Raw pose segments: the query's segment (0 until the first reset; a keyframe without a pose is
  // in the segment of the posed keyframe before it), and whether and why it started one.
  int pose_segment = 0;
  PoseReset pose_reset = PoseReset::kNone;
  // The raw step at the query (raw units): the distance from the previous keyframe with a pose;
  // across a pose reset the last step before it; 0 for the first pose or without one.
  double raw_step = 0.0;
  int matches = 0;     // descriptor matches with match_id, count
  int inliers = 0;     // geometric inliers with match_id, count
  double score = 0.0;  // inliers / K (K = options.features.max_features), in [0, 1]
  VerificationMethod method = VerificationMethod::kEssential;
  RelativePoseKind pose_kind = RelativePoseKind::kNone;
  // p_in_match = match_from_query * p_in_query; see pose_kind for what is meaningful.
  Sim3d match_from_query;
  // Information of match_from_query from the verifying inliers (VerificationResult::information:
  // PnP / Sim(3) only, zero for a two-view pose); the pose graph's loop edge uses it.
  PoseInformation7 information = PoseInformation7::Zero();
  // Angle between the verified rotation and the pose prior along the loop graph (the raw relative
  // rotation, or through an accepted loop: see Options::consistency_per_keyframe_deg), degrees;
  // -1 when no prior was available.
  double rotation_error_vs_prior_deg = -1.0;
  // Local-map PnP (Options::local_map): points of the local map around match_id, and the PnP
  // inliers among them, when it gave the pose (method kPnP, pose_kind kSE3Metric); 0 otherwise.
  // `inliers` stays the two-view count that detected the loop.
  int local_map_points = 0;
  int local_map_inliers = 0;
  // The relative poses between keyframes inside that local geometry (each map keyframe and its
  // neighbours, each map keyframe and the match, the query and the keyframes before it): how many
  // came from the images (RelativePoseFromImages) and how many from the raw poses. Both 0 for a
  // loop measured without a local geometry (two-view, or the vSLAM's depths).
  int local_poses_from_images = 0;
  int local_poses_raw = 0;
  // The pose is a planar alternative (Options::planar_alternatives), not the lowest-cost
  // two-view model, which the consistency check rejected; `inliers` are the alternative's.
  bool planar_alternative = false;
  // Session of match_id: 0 = this detector's own keyframes (the current session); > 0 = an
  // earlier session loaded with AddPriorKeyframes (its id, e.g. the map's session id).
  int64_t match_session = 0;
  // Relocalisation / multi-session output (has_world_from_query), set when detected, the matched
  // keyframe has a raw pose and pose_kind != kNone: the query camera in the MATCHED keyframe's
  // world frame, world_from_matched * match_from_query. Units are those of the matched session.
  // Scale caveat: with kSE3UnitTranslation (no depths, monocular) the query sits at unit distance
  // (in the matched camera's frame, i.e. 1 / scale of world_from_matched in world units) along the
  // verified direction: the orientation is right, the position is only a direction.
  bool has_world_from_query = false;
  Sim3d world_from_query;       // valid when has_world_from_query
  bool relocalization = false;  // the query had no pose (or came through Relocalize())
  // Keyframe ids geometrically verified for this query, best-ranked first (at most
  // Options::max_verify per search, stopping at the first loop; without a pose all of them,
  // Options::best_of_verified): those the search area gave, then those the appearance fallback
  // ranked (Options::appearance_fallback, when the area gave none).
  std::vector<int64_t> verified_in_area;
  std::vector<int64_t> verified_by_appearance;
  StageTimings timings;
  bool detected() const { return status == LoopStatus::kDetected; }
};

class LoopDetector {
 public:
  using Options = LoopDetectorOptions;

  explicit LoopDetector(Options options);
  ~LoopDetector();
  LoopDetector(LoopDetector&&) noexcept;
  LoopDetector& operator=(LoopDetector&&) noexcept;

  // Extracts and stores the keyframe's features, then (every N keyframes) searches for a loop.
  LoopResult Process(const KeyframeInput& input);

  const Options& options() const;
  size_t num_keyframes() const;
  // The stored record of keyframe `id`, unpacked (its values as stored: quantised, see
  // core/packed_keyframe.h).
  KeyframeRecord record(int64_t id) const;
  // The stored bytes of keyframe `id` (what a map stores for it).
  const PackedKeyframe& packed_record(int64_t id) const;
  // Sum of PackedKeyframe::Bytes() over the stored keyframes.
  size_t StoredBytes() const;
  // Memory of the ANN retrieval index (0 unless retrieval == kAnn), bytes; not in StoredBytes().
  size_t RetrievalIndexBytes() const;
  // Memory of the bounded buffers of recent extractions (Options::repeatability_window,
  // Options::overlap_features: descriptor bytes); not in StoredBytes(), does not grow with the
  // map.
  size_t RecentBufferBytes() const;

  // Query/match against stored records only (no extraction), for benchmarks and tests: matches
  // `query` against the given candidate ids and verifies the best.
  LoopResult MatchAgainst(const KeyframeRecord& query, const std::vector<int64_t>& candidate_ids);

  // Multi-session: adds the keyframe records of an earlier session (`session` > 0, each session
  // once; ids unique inside the session; focal_px > 0). Their poses are kept only to report
  // LoopResult::world_from_query in that session's frame. Throws std::invalid_argument (nothing
  // added) on a bad session id or record.
  void AddPriorKeyframes(int64_t session, std::vector<KeyframeRecord> records);
  size_t num_prior_keyframes() const;
  // Loops that anchor the rotation prior and the search area (a weak pair does not), count.
  size_t num_anchor_loops() const;
  KeyframeRecord prior_record(int64_t session, int64_t id) const;

  // Relocalisation: extracts the input's features and matches them against every stored keyframe
  // that has a pose (this session and all prior sessions), with geometric verification and no
  // pose-prior check. Stores nothing; the input's id, timestamp and pose are not used. On success
  // (status kDetected) world_from_query is the query pose in the matched keyframe's world frame.
  LoopResult Relocalize(const KeyframeInput& input);

 private:
  struct Impl;  // src/loop/loop_detector_impl.h
  std::unique_ptr<Impl> impl_;
};

}  // namespace sparseloop
