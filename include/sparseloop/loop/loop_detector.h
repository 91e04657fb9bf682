#pragma once
// The loop-closure detector of the paper (Algorithm 1): informative features per keyframe, a
// geometric search area on the raw trajectory, Hamming matching of the K stored descriptors and
// geometric verification, plus a consistency check against the raw pose prior.
// Synchronous and deterministic: the same inputs and options give the same results.
#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "sparseloop/core/camera.h"
#include "sparseloop/core/sim3.h"
#include "sparseloop/features/informative_features.h"
#include "sparseloop/matching/descriptor_matching.h"
#include "sparseloop/matching/geometric_verification.h"
#include "sparseloop/matching/triangulation.h"
#include "sparseloop/retrieval/binary_ann_index.h"
#include "sparseloop/search/search_area.h"

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

// How the keyframes to match and verify are chosen among the search area's candidates.
enum class CandidateRetrieval {
  kBruteForce,  // Hamming-match the query's K descriptors against every candidate (the paper)
  kAnn,         // one ANN index over all stored descriptors; each query descriptor votes for the
                // keyframes of its nearest stored descriptors; the top-voted candidates are matched
                // and verified (how vocabulary-free detectors scale; the `full-ann` baseline)
};
const char* ToString(CandidateRetrieval retrieval);
// "brute_force" | "ann"; throws std::invalid_argument otherwise.
CandidateRetrieval ParseCandidateRetrieval(const std::string& name);

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
  struct Options {
    FeatureOptions features;                     // informative ORB (K = features.max_features)
    SearchAreaOptions search = DefaultSearch();  // search area on the raw trajectory
    MatchOptions match;                          // Hamming matching
    VerifyOptions verify;                        // geometric verification (seed inside)
    // Asymmetric matching: a stored record keeps its K features (memory per
    // keyframe), but the keyframe being checked is matched with its whole ranked extraction, up
    // to query_max_features (ORB extracts them anyway; only what is stored must be small). Every
    // stored descriptor then finds its best match among the query's many (the ratio test on that
    // side, MatchStoredIntoQuery), so a K = 15 record is found again by a query that saw the same
    // place with other strong corners. false: the query matches with its K stored features
    // (symmetric K x K, the paper). query_max_features in [K, features.orb_candidates] (larger
    // values are clamped to orb_candidates; smaller than K means K).
    bool asymmetric_matching = false;
    int query_max_features = 1000;
    // Keep the K that will be seen again. The paper keeps features at mapped points,
    // points the vSLAM saw in several keyframes. Measured here: a keyframe's features are ranked
    // first by how many of the previous repeatability_window keyframes re-find them (a mutual,
    // ratio-tested descriptor match against those keyframes' whole extraction, up to
    // query_max_features), then by features.ranking. A feature re-found in the keyframes before
    // lies on structure that persists under motion; a strong corner seen once (a specular
    // highlight, a moving object, noise) does not. Only the first repeatability_pool features
    // of features.ranking compete (>= K). Only a keyframe with a raw pose is ranked so: without
    // one, the persistent features defeat the overlap walk (docs/DETECTOR.md, "Sparse K = 15: what
    // makes 15 stored features recall"). Window 0: features.ranking alone (the paper's rule with
    // kPopcount). Keyframes, >= 0; pool, features.
    int repeatability_window = 0;
    int repeatability_pool = 300;
    int check_every = 1;   // run the loop check every N keyframes (paper's N), keyframes >= 1
    int min_matches = 12;  // candidates with fewer descriptor matches are not verified, count
    int max_verify = 3;    // best-ranked candidates verified geometrically, count
    // Without a pose (global search) the first verified loop among the ranked candidates need
    // not be the best: every candidate to verify is verified and the one with the most inliers
    // is the loop. With a pose the first loop is kept (the search area and the pose gate chose
    // the place). Costs up to max_verify - 1 verifications per loop without a pose
    // (rtabmap corridor, K = 20: 47 -> 10 with 9 inliers was kept before 47 -> 9 with 10).
    bool best_of_verified = true;
    // Close scores: beyond max_verify, the next candidates are verified too
    // while their descriptor match count is at least verify_close_fraction x the max_verify-th
    // candidate's, up to max_verify_close in all (stopping at the first loop, as always). Under
    // drift the true match need not rank in the top three by matches when several places look
    // alike. Measured (K = 300, raw poses): street00 x1 recall@100%P 0.83 -> 0.90
    // (0.8, 8), street00 x4, street05 x1 / x4, street07, the aerial renders unchanged, zero false
    // loops accepted in each (docs/SEARCH_AREA.md). Not below K = 30, where the small-K floors
    // apply: match counts of 6-15 make most candidates "close" (K = 15 preset, aerial_circuit:
    // 2 false weak pairs accepted with it, none without). Fraction in [0, 1] (0: off); count >= 1.
    double verify_close_fraction = 0.8;
    int max_verify_close = 8;
    // The inlier threshold grows with K: a pair needs max(verify.min_inliers,
    // ceil(min_inlier_fraction_of_k * K)) inliers (more features = more chance inliers between
    // unrelated but similar-looking places). Fraction in [0, 1].
    double min_inlier_fraction_of_k = 0.08;
    // Small K: a record of K features cannot reach 12 matches and 12 inliers with another view
    // (K = 15 on rtabmap: at most ~5-10 survive), so below K = 30 both floors become
    // ceil(small_k_fraction * K), never below small_k_floor (8: three matches beyond the
    // five-point minimal sample). K >= min_matches / small_k_fraction keeps min_matches and
    // verify.min_inliers. Measured in docs/DETECTOR.md ("Small K"). Fraction in (0, 1], floor
    // >= 5.
    double small_k_fraction = 0.4;
    int small_k_floor = 8;
    // A candidate must be "far along the path": path length between it and the query >=
    // min_path_ratio * straight-line distance (scale-free; rejects the recent, still-overlapping
    // stretch of a forward motion). Path length: SearchArea::PathLength over the stored
    // positions; across keyframes without a pose it counts the chord between the posed ones
    // around them. Needs poses; 0 disables. ratio >= 0.
    double min_path_ratio = 3.0;
    // Without a pose (global search), "far along the path" cannot be measured: a keyframe that
    // still shares the scene with the query is not a loop (kitti07_first160, a straight drive:
    // 106 of 107 detections were the road 11-25 keyframes back). Walking back from the first
    // keyframe older than search.exclude_recent, every keyframe whose descriptors still match
    // the query's is excluded too, until `overlap_gap` keyframes in a row do not (a blurred
    // frame does not end the overlap). "Still match": at least overlap_match_factor x the match
    // floor (EffectiveMinMatches; unrelated frames reach 15-39 matches of 300 on castle and
    // KITTI by chance) and overlap_relative x the first walked keyframe's count (the overlap
    // decays from there). At most overlap_max_walk keyframes are matched. overlap_gap 0 disables.
    int overlap_gap = 4;
    int overlap_max_walk = 300;
    double overlap_match_factor = 3.0;
    double overlap_relative = 0.4;
    // The walk at a small K: a stored record of K = 15-20 cannot reach the floor above (3 x 8
    // matches), so the walk would end at its first keyframe and keep the road ahead, which a
    // forward drive sees again 10-20 keyframes later, as a loop candidate. When the query is
    // extracted with more than K features (asymmetric matching or repeatability ranking), the
    // first overlap_features of the last overlap_window keyframes' extractions (keyframes without
    // a pose only) are kept in a bounded buffer and the walk matches the query's first
    // overlap_features against them, with the floors of a record of that size; beyond the buffer
    // it goes on with the stored records. Memory: overlap_window x overlap_features x 32 B,
    // whatever the map's size. 0 features: off (the walk reads the stored records only).
    // Features >= 0 (used when > K); keyframes >= 1.
    int overlap_features = 300;
    int overlap_window = 64;
    // Without a pose, after the walk: a verified candidate is not a loop when a stored keyframe
    // between it and the query (at 1/2 and 3/4 of the way) verifies with the query with at least
    // as many inliers: the query continues the view of the path since the candidate, it did not
    // come back to it (status rejected_by_temporal). A revisit after an excursion has unrelated
    // keyframes in between. kitti07_first160 (no loop): removes the 4 detections the walk leaves
    // (candidate 24-77 inliers, keyframe 3/4 of the way 110-237); rtabmap / castle true loops:
    // the keyframes in between reach 0-21 inliers against the pair's 31-193, except where the
    // one in between is itself an earlier revisit of the same place. Costs up to two
    // verifications per detected loop without a pose.
    bool continuity_check = true;
    // Pose-prior consistency: |angle(R_verified, R_prior)| <= min(max, base + per_keyframe * n),
    // n = keyframes of odometry between the candidate and the query along the loop graph: the
    // index difference, or shorter through an accepted loop (|query - loop query| + |loop match -
    // candidate|), i.e. the odometry since the two places were last tied together. The raw
    // rotation between them can have drifted by that much (a monocular VO's heading bias is up to
    // ~1 deg per keyframe: castle ring family, docs/DETECTOR.md "Rotation gate"); PCM in the pose
    // graph stays the outlier filter for loops the wider gate lets through. When the path runs
    // through an accepted loop, the prior rotation does too (raw odometry to the loop's ends, the
    // loop's verified rotation, raw odometry back), not the raw rotation between the two passes,
    // which still holds the whole drift. A pose from 3D points
    // (PnP / Sim(3)) uses consistency_per_keyframe_deg; a two-view pose (essential matrix, which
    // can pick the wrong one of two supported solutions) two_view_consistency_per_keyframe_deg.
    // Degrees.
    // A loop is a revisit: a pose from 3D points (PnP / Sim(3), metric translation) that puts the
    // query farther than max_loop_distance_steps x the raw step from the match is rejected
    // (status rejected_by_consistency), and the next candidate is tried. The step is the mean raw
    // step of the posed keyframes within loop_distance_window of the match (its segment, before
    // the query; 0 or none: the whole path's mean): the translation is in the match's raw units,
    // and a monocular scale drifts (street00 x4: 1.05 raw units per keyframe around keyframe 207,
    // 4.7 on average; "10 mean steps" let a loop 21.8 m from its match through). 50 keyframes
    // each side, not 10: the speed varies faster than the scale (street07 starts from standstill,
    // 0.4-0.6 raw units per keyframe against 1.3 on average, and with 10 its true loops 6-8 m
    // from the match were 11-14 steps; with 50, 7; the 21.8 m loop above is 15). With a wide search
    // area (search.drift_rate) the camera finds the places it keeps seeing down a long street,
    // 20-80 m on (street00: 27 such loops, each with a correct relative pose, but no revisit;
    // docs/DETECTOR.md, "Search area under drift"). Steps; 0 disables; applies from the 10th
    // keyframe, within one raw pose segment. Window: keyframes each side, >= 0.
    double max_loop_distance_steps = 10.0;
    int loop_distance_window = 50;
    bool check_consistency = true;
    double consistency_base_deg = 10.0;
    double consistency_per_keyframe_deg = 1.0;
    double two_view_consistency_per_keyframe_deg = 0.1;
    double consistency_max_deg = 45.0;
    // Planar scenes (monocular two-view loops only, when the local map gave no pose): when the
    // lowest-cost essential-matrix pose fails the consistency check, the other poses the same
    // matches support (PlanarAlternatives: a homography's decompositions, each refined as an
    // essential matrix) are tried against the same check, most inliers first; the first that
    // passes with the usual inlier floor is the loop (LoopResult::planar_alternative). Near a
    // plane, two-view geometry has two supported solutions and the lower cost is not always the
    // true one; the pose prior decides between them (docs/DETECTOR.md, "Planar alternatives").
    bool planar_alternatives = true;
    // An alternative must agree with the prior within this fraction of the consistency tolerance:
    // choosing among several hypotheses by the prior raises the chance that a false pair passes;
    // the chance that a random rotation lies within an angle grows with its cube, so at 0.4 each
    // of the (at most 3) alternatives adds ~6 % of the primary's chance. castle 29 -> 02 (not
    // planar) has alternatives 5.4 / 7.4 deg from the GT prior (tolerance 12.8 -> 5.1 deg, both
    // rejected), EuRoC pair (2,3) one 2.4 deg off (10.1 -> 4.0 deg, accepted). In (0, 1].
    double planar_alternative_tolerance = 0.4;
    // Weak pairs, when weak_pairs: a pair verified with at least weak_min_inliers inliers but
    // fewer than the inlier floor (EffectiveMinInliers) is a loop only when one of the previous
    // agreement_window keyframes verified a pair on the same place that passed the rotation
    // gate (weak or not): its match within agreement_window + (their query distance) keyframes
    // of this match. A loop is a run of keyframes; a chance pair stands alone. An unconfirmed weak
    // pair ends kRejectedByTemporal. Candidates need only weak_min_inliers descriptor matches
    // then. A weak loop anchors nothing (the rotation prior along the loop graph and the search
    // area go through loops at the floor only), and the appearance fallback takes no weak pair
    // (outside the search area the raw pose vouches for nothing: the same texture elsewhere
    // verifies with 6-7 inliers in runs). Off: the floor alone decides. weak_min_inliers >= 5 (no
    // effect at or above the floor); agreement_window in keyframes >= 1.
    bool weak_pairs = false;
    int weak_min_inliers = 6;
    int agreement_window = 3;
    // Candidate retrieval. kAnn: a keyframe enters the index once the search area may return it
    // (older than search.exclude_recent), votes only count for keyframes the search area (and
    // min_path_ratio) allow, and the ann.max_candidates top-voted go to matching + verification.
    CandidateRetrieval retrieval = CandidateRetrieval::kBruteForce;
    BinaryAnnOptions ann;  // index and voting parameters (used when retrieval == kAnn)
    // Appearance fallback: when the search area on the raw trajectory gives no
    // loop for a query with a pose, every stored keyframe it did not hold (older than
    // search.exclude_recent, far along the path: min_path_ratio) is ranked by descriptor matches
    // with the query and the best max_verify are verified, with the same floors and the same
    // rotation gate. Drift moves the true match out of the wedge (aerial circuit, K = 15:
    // recall 0.64 in the area, 0.97 with global search); a small K makes ranking all of them
    // cheap (15 x 15 Hamming per stored keyframe). LoopResult::source says which one found it.
    // On by default: where the drift outgrows the uncertainty area, the loops it finds tie the
    // two passes and the area through them holds the revisits after it. K = 300, street05 at
    // --drift 8 (raw t_err 27.7 %): recall@100%P 0.532 -> 0.672 (2 loops from the fallback); on
    // the street and aerial renders up to --drift 4 the area holds every revisit and the
    // fallback finds none (docs/SEARCH_AREA.md).
    bool appearance_fallback = true;
    // The fallback's cheap pre-ranking (it keeps the small-K verification tail short and the
    // fallback cheap as the map grows): every eligible stored keyframe is scored by how many of
    // its K descriptors have a neighbour within match.max_distance among the query's own stored K
    // (K x K Hamming distances, no ratio test), and only the fallback_candidates best are matched
    // with the query's whole extraction and verified. fallback_candidates = 0: every eligible
    // keyframe is matched in full (its cost grows with the map). 5: the same loops as with 20 on
    // street00 / 05 x4, street07, the aerial flights and the K = 15 preset, and at K = 300 each
    // candidate matched in full is 300 x 300 distances (10,000 stored keyframes: 9.4 ms with 20,
    // bench_detector).
    int fallback_candidates = 5;
    // With more than 10 x fallback_candidates eligible keyframes, a coarse stage first: each is
    // scored by its first fallback_coarse_features stored descriptors (its best ranked), and the
    // 10 x fallback_candidates best go on to the full score (a large map: the target of <= 2 ms at
    // 10,000 stored keyframes). 0: score every eligible keyframe in full.
    int fallback_coarse_features = 4;
    // The coarse stage compares each keyframe's first fallback_coarse_features with the query's
    // first fallback_coarse_probe probe descriptors (its best ranked; 0: the whole probe). 8:
    // at K = 300 over 10,000 keyframes the coarse stage with 32 was 1.2 of the
    // fallback's 3.4 ms (bench_detector BM_AppearanceFallback); the same loops on the street and
    // aerial renders at K = 300 and with the K = 15 preset.
    int fallback_coarse_probe = 8;
    // The ranking uses the first fallback_fine_features stored descriptors of each keyframe and
    // of the query's probe (their best ranked; 0: all K). At K = 15 it is all of them; at K = 300
    // scoring all 300 against the query's 300 for 200 keyframes took 16 ms per keyframe
    // (street00), and the coarse stage over 10,000 keyframes would be 12 M
    // distances; 32 of them: ~2 ms, the same loops.
    int fallback_fine_features = 32;
    // Raw pose resets the caller does not flag (KeyframeInput::pose_reset; bad input):
    // a posed keyframe starts a new pose segment when its raw step from the posed keyframe before
    // is longer than pose_jump_factor x the segment's usual step (the larger of the median of its
    // last 20 steps and its mean step), when its rotation step exceeds pose_jump_max_deg, or when
    // its Sim(3) scale differs by more than pose_jump_max_scale x; once the segment has 5 steps. A
    // vSLAM that re-initialises near its old origin, orientation and scale is not noticed: flag it.
    // 0 turns a rule off.
    double pose_jump_factor = 20.0;
    double pose_jump_max_deg = 90.0;   // degrees
    double pose_jump_max_scale = 2.0;  // ratio, >= 1 (or 0)
    // Multi-session: on a check keyframe where the current session gives no loop, match the
    // keyframes of earlier sessions (AddPriorKeyframes) by appearance: their world frame (origin,
    // scale) differs, so no search area and no pose-prior rotation check apply; the same Hamming
    // matching, ranking and geometric verification (same inlier threshold) do.
    bool search_prior_sessions = true;
    // A keyframe without a pose under a non-global search strategy is stored (no search-area
    // entry) and relocalised against every stored keyframe with a pose, all sessions. false:
    // such a keyframe is rejected with std::invalid_argument (the behaviour before relocalisation).
    bool relocalize_without_pose = true;
    // Monocular loops (no depths on either side, a verified essential matrix): the query is
    // verified again by PnP against a local map, the keypoints of the match and its neighbours
    // triangulated with relative poses from the images (RelativePoseFromImages: the raw ones
    // refined by the pair's matches, so the odometry's rotation drift between neighbours does
    // not bend the map; the raw ones where the images cannot). This is the paper's image-to-map
    // step for a vSLAM that hands over no depths, as ORB-SLAM's loop closing does against its map
    // points. It gives the translation with its length (match camera units, as depths would)
    // instead of a direction, and stays well conditioned when the loop's own baseline is short
    // (docs/DETECTOR.md, "Local-map PnP"). The two-view result is kept when PnP does not verify.
    struct LocalMapOptions {
      bool enabled = true;
      int window = 2;      // keyframes each side of the match whose points enter the map, >= 0
      int neighbours = 2;  // keyframes each side each map keyframe is triangulated with, >= 1
      // When the map around the match falls short (too few points: a match taken at standstill,
      // with no parallax between its neighbours), the other way round: the query's points,
      // triangulated with the keyframes before it, against the match's keypoints (PnP; the
      // query's raw units). A two-view loop has only a direction, and the graph has to assume its
      // length (direction_loop); this gives it.
      bool query_points = true;
      TriangulationOptions triangulation;
      void Check() const;
    };
    LocalMapOptions local_map;
    uint64_t seed = 42;  // copied into verify.seed
    void Check() const;
    // The inlier threshold actually applied: max(SmallK(verify.min_inliers),
    // ceil(min_inlier_fraction_of_k * K)), SmallK(n) = min(n, max(small_k_floor,
    // ceil(small_k_fraction * K))).
    int EffectiveMinInliers() const { return EffectiveMinInliers(features.max_features); }
    // The descriptor-match threshold actually applied: SmallK(min_matches).
    int EffectiveMinMatches() const { return EffectiveMinMatches(features.max_features); }
    // The same for a pair whose smaller record holds `k` features (a keyframe of an earlier
    // session stored at another K).
    int EffectiveMinInliers(int k) const;
    int EffectiveMinMatches(int k) const;
    static SearchAreaOptions DefaultSearch() {
      SearchAreaOptions s;
      s.exclude_recent = 10;
      // The uncertainty area: 10 % of the raw path between two passes covers the
      // drift of the benchmark's renders up to x4 (street KITTI 00 / 05 / 07, aerial), raw t_err
      // 1.7-28 %, with zero false loops accepted; docs/SEARCH_AREA.md "Uncertainty area".
      s.drift_rate = 0.1;
      return s;
    }
  };

  explicit LoopDetector(Options options);

  // Extracts and stores the keyframe's features, then (every N keyframes) searches for a loop.
  LoopResult Process(const KeyframeInput& input);

  const Options& options() const { return options_; }
  size_t num_keyframes() const { return records_.size(); }
  // The stored record of keyframe `id`, unpacked (its values as stored: quantised, see
  // core/packed_keyframe.h).
  KeyframeRecord record(int64_t id) const;
  // The stored bytes of keyframe `id` (what a map stores for it).
  const PackedKeyframe& packed_record(int64_t id) const;
  // Sum of PackedKeyframe::Bytes() over the stored keyframes.
  size_t StoredBytes() const;
  // Memory of the ANN retrieval index (0 unless retrieval == kAnn), bytes; not in StoredBytes().
  size_t RetrievalIndexBytes() const { return ann_ ? ann_->Bytes() : 0; }
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
  size_t num_prior_keyframes() const { return prior_records_.size(); }
  // Loops that anchor the rotation prior and the search area (a weak pair does not), count.
  size_t num_anchor_loops() const { return accepted_loops_.size(); }
  KeyframeRecord prior_record(int64_t session, int64_t id) const;

  // Relocalisation: extracts the input's features and matches them against every stored keyframe
  // that has a pose (this session and all prior sessions), with geometric verification and no
  // pose-prior check. Stores nothing; the input's id, timestamp and pose are not used. On success
  // (status kDetected) world_from_query is the query pose in the matched keyframe's world frame.
  LoopResult Relocalize(const KeyframeInput& input);

 private:
  // The steps of Process.
  // Checks the input (id, timestamp, image, pose) without changing any state; true when the
  // keyframe has no pose under a geometric search (relocalisation).
  bool ValidateInput(const KeyframeInput& input) const;
  // Stores the packed record (and its place on the trajectory unless relocalising); its index.
  size_t Store(PackedKeyframe record, bool relocalize);
  // A keyframe without a pose: appearance against every stored keyframe with one.
  void RelocalizeStored(const KeyframeRecord& query, LoopResult* result) const;
  // The search area's candidates, "far along the path" (FarAlong), without the still-overlapping
  // recent keyframes when there is no pose (overlap_gap), and voted (retrieval kAnn).
  std::vector<int64_t> SearchCandidates(const KeyframeRecord& query, size_t index,
                                        LoopResult* result);
  // min_path_ratio: the path between stored record `ci` and the query (record `query_index`) >=
  // ratio x their distance (true when it cannot be measured).
  bool FarAlong(const KeyframeRecord& query, size_t query_index, size_t ci) const;
  // Adds a sub-search's time to *result; when it detected, it becomes *result (source `source`)
  // keeping the area's report (candidates, area, verified ids).
  static void MergeSubSearch(LoopResult sub, CandidateSource source, LoopResult* result);
  // appearance_fallback: every eligible stored keyframe outside `in_area` is ranked and verified.
  void AppearanceFallback(const KeyframeRecord& query, size_t index, std::vector<int64_t> in_area,
                          LoopResult* result);
  // fallback_candidates: the ids of the best-scored of the records at `indices` by the cheap
  // pre-ranking (RankByProbe), best first; all of them, in order, when there are no more.
  std::vector<int64_t> PreRankByAppearance(const KeyframeRecord& query, size_t index,
                                           const std::vector<size_t>& indices) const;
  // search_prior_sessions: the keyframes of earlier sessions, by appearance.
  void SearchPriorSessions(const KeyframeRecord& query, LoopResult* result) const;
  // Raw pose segments: why `input` starts a new one (kNone: it does not).
  PoseReset DetectPoseReset(const KeyframeInput& input) const;
  // The keyframes of earlier pose segments, by appearance (pre-ranked as the fallback is).
  void SearchEarlierSegments(const KeyframeRecord& query, size_t index, LoopResult* result);
  // Both stored keyframes are in the same raw pose segment (their raw relative pose means
  // something).
  bool SameSegment(size_t a, size_t b) const { return segment_[a] == segment_[b]; }
  // Matching and ranking of the candidates, then TryCandidate on the best max_verify until one
  // is detected; the most informative outcome goes to *result. `weak_pairs`: whether
  // Options::weak_pairs applies (not to the appearance fallback's candidates).
  void SearchAndVerify(const KeyframeRecord& query, std::vector<int64_t> candidates,
                       LoopResult* result, bool weak_pairs = true);
  // One ranked candidate: verification (and the local map), then the gates (rotation, weak
  // pairs, continuity). Fills *trial; returns its status.
  LoopStatus TryCandidate(const KeyframeRecord& query, size_t query_index, size_t match_index,
                          const std::vector<DescriptorMatch>& matches, const VerifyOptions& verify,
                          bool weak_enabled, std::optional<size_t>* support, LoopResult* trial);
  // The pose-prior rotation gate of a verified pair (kDetected when it passes or cannot be
  // checked); a planar alternative that agrees with the prior replaces the pose in *trial.
  LoopStatus RotationGate(const KeyframeRecord& query, const KeyframeRecord& match,
                          size_t query_index, size_t match_index,
                          const std::vector<DescriptorMatch>& matches, const VerificationResult& v,
                          bool from_local_map, LoopResult* trial) const;
  // retrieval == kAnn: indexes the keyframes that became eligible, then returns the
  // ann.max_candidates top-voted ids among `allowed` (the filtered search-area candidates).
  std::vector<int64_t> RetrieveByVotes(const KeyframeRecord& query, size_t query_index,
                                       const std::vector<int64_t>& allowed);
  // Appearance-only matching + verification against `pool` (no pose-prior, temporal or search-area
  // state is read or changed). Used for prior sessions and relocalisation.
  struct PoolEntry {
    int64_t session;  // 0 = current
    const PackedKeyframe* record;
  };
  void MatchAndVerifyPool(const KeyframeRecord& query, const std::vector<PoolEntry>& pool,
                          LoopResult* result) const;
  void ValidateImageInput(const KeyframeInput& input) const;
  // Id, timestamp and the informative features of `input` (no pose), ranked: the query's whole
  // extraction with asymmetric matching (QueryFeatureCount), else K. Process and Relocalize.
  KeyframeRecord ExtractRecord(const KeyframeInput& input) const;
  // Features extracted per keyframe: K, or query_max_features with asymmetric matching or
  // repeatability ranking (clamped to [K, features.orb_candidates]).
  int QueryFeatureCount() const;
  // The order in which `full`'s features are stored (Options::repeatability_window: re-found
  // in recent_ first), at most max(K, repeatability_pool) indices; identity without ranking.
  std::vector<int> StoredOrder(const KeyframeRecord& full) const;
  // Descriptors of the last repeatability_window keyframes' whole extractions, oldest first.
  std::deque<std::vector<Descriptor>> recent_;
  // Descriptor matches of a query record against a stored one (asymmetric: MatchStoredIntoQuery
  // when the query holds more features, else MatchDescriptors).
  std::vector<DescriptorMatch> MatchQuery(const KeyframeRecord& query,
                                          std::span<const Descriptor> stored) const;
  std::vector<DescriptorMatch> MatchQuery(const KeyframeRecord& query,
                                          const PackedKeyframe& stored) const {
    return MatchQuery(query, stored.descriptors());
  }
  // A stored record unpacked for verification (keypoints, depths), cached for the current
  // Process / Relocalize / MatchAgainst call (the cache is cleared when the next one starts).
  const KeyframeRecord& Unpacked(const PackedKeyframe& packed) const;
  const KeyframeRecord& Stored(size_t index) const { return Unpacked(records_[index]); }
  mutable std::unordered_map<const PackedKeyframe*, KeyframeRecord> unpacked_;
  // QueryWithTriangulatedDepths' result for the current call: the same for every candidate of
  // one query (keyed by its id and size), triangulated once.
  struct QueryPoints {
    int64_t id = 0;
    size_t size = 0;
    KeyframeRecord record;
    int image_poses = 0, raw_poses = 0;  // TriangulationResult's counts
  };
  mutable std::optional<QueryPoints> query_points_;
  // The relative poses from the images of this call's local maps and query points (keyed by the
  // unpacked records' addresses, so cleared with them).
  mutable RelativePoseCache relative_poses_;
  // Clears the per-call caches (unpacked_, query_points_, relative_poses_) when a new call starts.
  void ClearCallCaches() const {
    unpacked_.clear();
    query_points_.reset();
    relative_poses_.Clear();
  }
  void SetWorldFromQuery(const KeyframeRecord& match, LoopResult* result) const;
  // Options::local_map: PnP of `query` against the map triangulated around records_[match_index].
  // Returns the verification (success false when the map or PnP falls short); *map_points = size
  // of the map; *sources counts where its relative poses came from (LoopResult::local_poses_*).
  struct PoseSources {
    int images = 0, raw = 0;
  };
  VerificationResult VerifyAgainstLocalMap(const KeyframeRecord& query, size_t match_index,
                                           int* map_points, PoseSources* sources) const;
  // `query` with depths triangulated from the recent keyframes before it (relative poses from
  // the images where they fix them, else raw; unchanged when it has no pose or nothing
  // triangulates). Computed once per call (query_points_).
  const KeyframeRecord& QueryWithTriangulatedDepths(const KeyframeRecord& query,
                                                    size_t query_index) const;
  // Options::local_map.query_points: PnP of the match's keypoints against the query's
  // triangulated points (the pair's own matches), when the map around the match falls short.
  VerificationResult VerifyWithQueryPoints(const KeyframeRecord& query, size_t match_index,
                                           const std::vector<DescriptorMatch>& matches,
                                           PoseSources* sources) const;

  Options options_;
  VerifyOptions verify_;  // options_.verify with the effective min_inliers and seed
  SearchArea search_;
  std::vector<PackedKeyframe> records_;  // the stored keyframes, packed (one allocation each)
  std::unordered_map<int64_t, size_t> index_of_;
  // The index below which keyframes no longer share the scene with the query (Options::
  // overlap_gap), for a query without a pose; `exclude_end` = first index excluded by
  // search.exclude_recent. Returns the first index that may be a candidate's upper bound + 1.
  size_t OverlapStart(const KeyframeRecord& query, size_t exclude_end) const;
  // Options::overlap_features: the first overlap_features descriptors of recent keyframes'
  // extractions (record index, descriptors), oldest first, at most overlap_window of them.
  std::deque<std::pair<size_t, std::vector<Descriptor>>> overlap_buffer_;
  bool OverlapBufferUsed(const KeyframeRecord& query) const {
    return options_.overlap_gap > 0 && options_.overlap_features > options_.features.max_features &&
           static_cast<int>(query.size()) > options_.features.max_features;
  }
  // Options::continuity_check: a keyframe between match and query (record indices) verifies
  // with the query with >= `inliers` inliers.
  bool ContinuesRecentView(const KeyframeRecord& query, size_t query_index, size_t match_index,
                           int inliers, const VerifyOptions& verify) const;
  // Every loop this detector accepted: record indices and the verified relative rotation.
  struct AcceptedLoop {
    size_t query = 0;
    size_t match = 0;
    Eigen::Quaterniond match_from_query = Eigen::Quaterniond::Identity();
  };
  std::vector<AcceptedLoop> accepted_loops_;
  // The rotation prior of a candidate pair and the keyframes of odometry it rests on, along the
  // loop graph (Options::consistency_per_keyframe_deg): the raw relative rotation over |q - m|
  // keyframes, or, shorter, raw odometry to an accepted loop's ends, the loop's own verified
  // rotation, and raw odometry back. After a loop the raw poses of the two passes are still as
  // far apart as the drift made them; only the loop knows the correction (with the raw
  // relative rotation alone, 27 true revisits in a row were rejected right after an accepted
  // loop).
  struct GraphPrior {
    size_t keyframes = 0;
    Eigen::Quaterniond match_from_query = Eigen::Quaterniond::Identity();
  };
  GraphPrior PriorAlongLoopGraph(size_t query_index, size_t match_index) const;
  // Options::max_loop_distance_steps: a metric pose puts the query too far from the match.
  bool TooFarForARevisit(const KeyframeRecord& query, const KeyframeRecord& match,
                         size_t query_index, size_t match_index, const LoopResult& trial) const;
  // The mean raw step around the match (Options::loop_distance_window), raw units per keyframe.
  double LocalStep(size_t match_index, size_t query_index) const;
  // The latest query with a verified pair that passed the rotation gate, weak or not (query
  // index, match index): Options::weak_min_inliers.
  std::optional<std::pair<size_t, size_t>> last_support_;
  // Whether last_support_ confirms a weak pair (query index, match index).
  bool Agrees(size_t query_index, size_t match_index) const;
  bool any_pose_ = false;
  bool any_missing_pose_ = false;
  Eigen::Vector3d last_position_ = Eigen::Vector3d::Zero();  // of the last keyframe with a pose
  // Raw pose segments (KeyframeInput::pose_reset, Options::pose_jump_*): the segment of each
  // record; the current segment's last raw pose, its last steps (at most 20), path and step count.
  std::vector<int> segment_;
  int current_segment_ = 0;
  std::optional<Sim3d> last_pose_;
  std::deque<double> recent_steps_;
  double segment_path_ = 0.0;
  int segment_steps_ = 0;
  // SearchArea::PathLength of each record, read once when it is stored: FarAlong reads it for
  // every candidate (the appearance fallback: every stored keyframe) without a hash lookup.
  std::vector<double> path_length_;
  std::optional<BinaryAnnIndex> ann_;  // retrieval == kAnn; labels are indices into records_
  size_t ann_indexed_ = 0;             // records_[0, ann_indexed_) are in ann_
  // Earlier sessions (AddPriorKeyframes), searched by appearance only.
  std::vector<PackedKeyframe> prior_records_;
  std::vector<int64_t> prior_session_;  // session of each prior record
  // Features per keyframe each earlier session was stored with (its records' most), by session.
  std::unordered_map<int64_t, int> prior_k_;
  // The K of a pair of the query and a record of `session` (0 = current): the K that record was
  // stored with. Floors and score use it. (The smaller of the two K let a K = 20 symmetric query
  // through with 8 inliers against K = 150 records: 3 wrong loops of 49; multisession_test.)
  int PairK(int64_t session) const;
  std::unordered_map<int64_t, std::unordered_map<int64_t, size_t>> prior_index_;  // session, id
};

}  // namespace sparseloop
