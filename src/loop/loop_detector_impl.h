#pragma once
// The state and the steps of LoopDetector behind its public face (loop/loop_detector.h).
#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <unordered_map>
#include <vector>

#include "pose_track.h"
#include "prior_sessions.h"
#include "sparseloop/loop/loop_detector.h"

namespace sparseloop {

struct LoopDetector::Impl {
  using Options = LoopDetectorOptions;
  explicit Impl(Options options);

  // The public operations (loop_detector.h says what each does).
  LoopResult Process(const KeyframeInput& input);
  KeyframeRecord record(int64_t id) const;
  const PackedKeyframe& packed_record(int64_t id) const;
  size_t StoredBytes() const;
  size_t RecentBufferBytes() const;
  LoopResult MatchAgainst(const KeyframeRecord& query, const std::vector<int64_t>& candidate_ids);
  void AddPriorKeyframes(int64_t session, std::vector<KeyframeRecord> records);
  KeyframeRecord prior_record(int64_t session, int64_t id) const;
  LoopResult Relocalize(const KeyframeInput& input);

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
  // The keyframes of earlier pose segments, by appearance (pre-ranked as the fallback is).
  void SearchEarlierSegments(const KeyframeRecord& query, size_t index, LoopResult* result);
  // Both stored keyframes are in the same raw pose segment (their raw relative pose means
  // something).
  bool SameSegment(size_t a, size_t b) const { return track_.SameSegment(a, b); }
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
  PoseTrack track_;  // raw pose segments and the previous raw pose
  // SearchArea::PathLength of each record, read once when it is stored: FarAlong reads it for
  // every candidate (the appearance fallback: every stored keyframe) without a hash lookup.
  std::vector<double> path_length_;
  std::optional<BinaryAnnIndex> ann_;  // retrieval == kAnn; labels are indices into records_
  size_t ann_indexed_ = 0;             // records_[0, ann_indexed_) are in ann_
  PriorSessions priors_;  // earlier sessions (AddPriorKeyframes), searched by appearance only
  // The K of a pair of the query and a record of `session` (0 = current): the K that record was
  // stored with. Floors and score use it. (The smaller of the two K let a K = 20 symmetric query
  // through with 8 inliers against K = 150 records: 3 wrong loops of 49; multisession_test.)
  int PairK(int64_t session) const;
};

}  // namespace sparseloop
