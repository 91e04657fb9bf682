#pragma once
// The options of LoopDetector (loop/loop_detector.h): what is extracted and stored per keyframe,
// the search area, matching, verification and the gates. The configuration keys
// (pipeline/config.cc) reach the ones a user tunes; the rest are the estimators' inner constants
// with their measured defaults.
#include <cstdint>
#include <string>

#include "sparseloop/features/informative_features.h"
#include "sparseloop/matching/descriptor_matching.h"
#include "sparseloop/matching/geometric_verification.h"
#include "sparseloop/matching/triangulation.h"
#include "sparseloop/retrieval/binary_ann_index.h"
#include "sparseloop/search/search_area.h"

namespace sparseloop {

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

struct LoopDetectorOptions {
  FeatureOptions features;   // informative ORB (K = features.max_features)
  SearchAreaOptions search;  // search area on the raw trajectory
  MatchOptions match;        // Hamming matching
  VerifyOptions verify;      // geometric verification (seed inside)
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
};

}  // namespace sparseloop
