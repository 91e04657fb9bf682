// LoopDetector: options, the store, and Process with its steps (validate, extract, store, search
// area, the fallbacks); the candidates are verified in candidate_verification.cc, the local map in
// local_map.cc, earlier sessions and relocalisation in prior_sessions.cc.
#include "loop_detector_impl.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/timer.h"

namespace sparseloop {

const char* ToString(LoopStatus status) {
  switch (status) {
    case LoopStatus::kDetected:
      return "detected";
    case LoopStatus::kSkipped:
      return "skipped";
    case LoopStatus::kNoFeatures:
      return "no_features";
    case LoopStatus::kNoCandidates:
      return "no_candidates";
    case LoopStatus::kTooFewMatches:
      return "too_few_matches";
    case LoopStatus::kTooFewInliers:
      return "too_few_inliers";
    case LoopStatus::kRejectedByConsistency:
      return "rejected_by_consistency";
    case LoopStatus::kRejectedByTemporal:
      return "rejected_by_temporal";
  }
  return "unknown";
}

const char* ToString(CandidateSource source) {
  switch (source) {
    case CandidateSource::kSearchArea:
      return "area";
    case CandidateSource::kAppearance:
      return "appearance";
    case CandidateSource::kEarlierSegment:
      return "segment";
  }
  return "unknown";
}

const char* ToString(PoseReset reset) {
  switch (reset) {
    case PoseReset::kNone:
      return "none";
    case PoseReset::kCaller:
      return "caller";
    case PoseReset::kTranslationJump:
      return "translation";
    case PoseReset::kRotationJump:
      return "rotation";
    case PoseReset::kScaleJump:
      return "scale";
  }
  return "unknown";
}

const char* ToString(CandidateRetrieval retrieval) {
  return retrieval == CandidateRetrieval::kAnn ? "ann" : "brute_force";
}

CandidateRetrieval ParseCandidateRetrieval(const std::string& name) {
  if (name == "brute_force") return CandidateRetrieval::kBruteForce;
  if (name == "ann") return CandidateRetrieval::kAnn;
  SL_CHECK_MSG(false, "unknown candidate retrieval '{}' (expected brute_force | ann)", name);
  return CandidateRetrieval::kBruteForce;
}

void LoopDetectorOptions::Check() const {
  features.Check();
  search.Check();
  match.Check();
  verify.Check();
  ann.Check();
  SL_CHECK_MSG(check_every >= 1, "check_every must be >= 1 keyframe, got {}", check_every);
  SL_CHECK_MSG(min_matches >= 5, "min_matches must be >= 5, got {}", min_matches);
  SL_CHECK_MSG(repeatability_window >= 0 && repeatability_window <= 16 && repeatability_pool >= 5,
               "repeatability_window must be in [0, 16] keyframes and repeatability_pool >= 5, "
               "got {} and {}",
               repeatability_window, repeatability_pool);
  SL_CHECK_MSG(query_max_features >= 5, "query_max_features must be >= 5, got {}",
               query_max_features);
  SL_CHECK_MSG(max_verify >= 1, "max_verify must be >= 1, got {}", max_verify);
  SL_CHECK_MSG(verify_close_fraction >= 0 && verify_close_fraction <= 1 && max_verify_close >= 1,
               "verify_close_fraction must be in [0, 1] and max_verify_close >= 1, got {} and {}",
               verify_close_fraction, max_verify_close);
  SL_CHECK_MSG(std::isfinite(max_loop_distance_steps) && max_loop_distance_steps >= 0,
               "max_loop_distance_steps must be >= 0, got {}", max_loop_distance_steps);
  SL_CHECK_MSG(loop_distance_window >= 0, "loop_distance_window must be >= 0, got {}",
               loop_distance_window);
  SL_CHECK_MSG(std::isfinite(min_path_ratio) && min_path_ratio >= 0,
               "min_path_ratio must be >= 0, got {}", min_path_ratio);
  SL_CHECK_MSG(overlap_gap >= 0 && overlap_max_walk >= 0,
               "overlap_gap and overlap_max_walk must be >= 0, got {} and {}", overlap_gap,
               overlap_max_walk);
  SL_CHECK_MSG(overlap_match_factor >= 0 && overlap_relative >= 0 && overlap_relative <= 1,
               "overlap_match_factor must be >= 0 and overlap_relative in [0, 1], got {} and {}",
               overlap_match_factor, overlap_relative);
  SL_CHECK_MSG(overlap_features >= 0 && overlap_window >= 1,
               "overlap_features must be >= 0 and overlap_window >= 1, got {} and {}",
               overlap_features, overlap_window);
  SL_CHECK_MSG(consistency_base_deg >= 0 && consistency_per_keyframe_deg >= 0 &&
                   two_view_consistency_per_keyframe_deg >= 0 &&
                   consistency_max_deg >= consistency_base_deg,
               "consistency tolerances must be >= 0 and max >= base (got {}, {}, {})",
               consistency_base_deg, consistency_per_keyframe_deg, consistency_max_deg);
  SL_CHECK_MSG(min_inlier_fraction_of_k >= 0 && min_inlier_fraction_of_k <= 1,
               "min_inlier_fraction_of_k must be in [0, 1], got {}", min_inlier_fraction_of_k);
  SL_CHECK_MSG(std::isfinite(planar_alternative_tolerance) && planar_alternative_tolerance > 0 &&
                   planar_alternative_tolerance <= 1,
               "planar_alternative_tolerance must be in (0, 1], got {}",
               planar_alternative_tolerance);
  SL_CHECK_MSG(weak_min_inliers >= 5, "weak_min_inliers must be >= 5, got {}", weak_min_inliers);
  SL_CHECK_MSG(fallback_candidates >= 0 && fallback_coarse_features >= 0 &&
                   fallback_coarse_probe >= 0 && fallback_fine_features >= 0,
               "fallback_candidates, fallback_coarse_features, fallback_coarse_probe and "
               "fallback_fine_features must be >= 0, got {}, {}, {} and {}",
               fallback_candidates, fallback_coarse_features, fallback_coarse_probe,
               fallback_fine_features);
  SL_CHECK_MSG(pose_jump_factor >= 0 && pose_jump_max_deg >= 0,
               "pose_jump_factor and pose_jump_max_deg must be >= 0 (0: off), got {} and {}",
               pose_jump_factor, pose_jump_max_deg);
  SL_CHECK_MSG(pose_jump_max_scale == 0 || pose_jump_max_scale >= 1,
               "pose_jump_max_scale must be >= 1 (0: off), got {}", pose_jump_max_scale);
  SL_CHECK_MSG(agreement_window >= 1, "agreement_window must be >= 1 keyframe, got {}",
               agreement_window);
  SL_CHECK_MSG(std::isfinite(small_k_fraction) && small_k_fraction > 0 && small_k_fraction <= 1,
               "small_k_fraction must be in (0, 1], got {}", small_k_fraction);
  SL_CHECK_MSG(small_k_floor >= 5, "small_k_floor must be >= 5, got {}", small_k_floor);
  local_map.Check();
}

void LoopDetectorOptions::LocalMapOptions::Check() const {
  SL_CHECK_MSG(window >= 0, "local_map.window must be >= 0 keyframes, got {}", window);
  SL_CHECK_MSG(neighbours >= 1, "local_map.neighbours must be >= 1 keyframe, got {}", neighbours);
  triangulation.Check();
}

namespace {
// The record a keyframe stores: the first k features of `order` (indices into its ranked
// extraction), in vectors of exactly that size. With the identity order these are the K an
// extraction of K keeps (the ranking is a total order).
KeyframeRecord StoredSubset(const KeyframeRecord& full, const std::vector<int>& order, int k) {
  KeyframeRecord rec;
  rec.id = full.id;
  rec.timestamp = full.timestamp;
  rec.has_pose = full.has_pose;
  rec.world_from_cam = full.world_from_cam;
  rec.focal_px = full.focal_px;
  const size_t n = std::min(order.size(), static_cast<size_t>(std::max(0, k)));
  rec.descriptors.reserve(n);
  rec.keypoints.reserve(n);
  if (full.has_depths()) rec.depths.reserve(n);
  for (size_t j = 0; j < n; ++j) {
    const size_t i = static_cast<size_t>(order[j]);
    rec.descriptors.push_back(full.descriptors[i]);
    rec.keypoints.push_back(full.keypoints[i]);
    if (full.has_depths()) rec.depths.push_back(full.depths[i]);
  }
  return rec;
}

int SmallKFloor(const LoopDetectorOptions& o, int n, int k) {
  return std::min(n,
                  std::max(o.small_k_floor, static_cast<int>(std::ceil(o.small_k_fraction * k))));
}
}  // namespace

int LoopDetectorOptions::EffectiveMinInliers(int k) const {
  return std::max(SmallKFloor(*this, verify.min_inliers, k),
                  static_cast<int>(std::ceil(min_inlier_fraction_of_k * k)));
}

int LoopDetectorOptions::EffectiveMinMatches(int k) const {
  return SmallKFloor(*this, min_matches, k);
}

LoopDetector::Impl::Impl(Options options)
    : options_(std::move(options)),
      search_([&] {
        options_.Check();
        return options_.search;
      }()),
      track_(PoseTrack::Rules{options_.pose_jump_factor, options_.pose_jump_max_deg,
                              options_.pose_jump_max_scale}) {
  verify_ = options_.verify;
  verify_.seed = options_.seed;
  verify_.min_inliers = options_.EffectiveMinInliers();
  if (options_.retrieval == CandidateRetrieval::kAnn) ann_.emplace(options_.ann);
}

// The public face: each operation is the Impl's.
LoopDetector::LoopDetector(Options options) : impl_(std::make_unique<Impl>(std::move(options))) {}
LoopDetector::~LoopDetector() = default;
LoopDetector::LoopDetector(LoopDetector&&) noexcept = default;
LoopDetector& LoopDetector::operator=(LoopDetector&&) noexcept = default;
LoopResult LoopDetector::Process(const KeyframeInput& input) { return impl_->Process(input); }
const LoopDetector::Options& LoopDetector::options() const { return impl_->options_; }
size_t LoopDetector::num_keyframes() const { return impl_->records_.size(); }
KeyframeRecord LoopDetector::record(int64_t id) const { return impl_->record(id); }
const PackedKeyframe& LoopDetector::packed_record(int64_t id) const {
  return impl_->packed_record(id);
}
size_t LoopDetector::StoredBytes() const { return impl_->StoredBytes(); }
size_t LoopDetector::RetrievalIndexBytes() const { return impl_->ann_ ? impl_->ann_->Bytes() : 0; }
size_t LoopDetector::RecentBufferBytes() const { return impl_->RecentBufferBytes(); }
LoopResult LoopDetector::MatchAgainst(const KeyframeRecord& query,
                                      const std::vector<int64_t>& candidate_ids) {
  return impl_->MatchAgainst(query, candidate_ids);
}
void LoopDetector::AddPriorKeyframes(int64_t session, std::vector<KeyframeRecord> records) {
  impl_->AddPriorKeyframes(session, std::move(records));
}
size_t LoopDetector::num_prior_keyframes() const { return impl_->priors_.size(); }
size_t LoopDetector::num_anchor_loops() const { return impl_->accepted_loops_.size(); }
KeyframeRecord LoopDetector::prior_record(int64_t session, int64_t id) const {
  return impl_->prior_record(session, id);
}
LoopResult LoopDetector::Relocalize(const KeyframeInput& input) { return impl_->Relocalize(input); }

const PackedKeyframe& LoopDetector::Impl::packed_record(int64_t id) const {
  auto it = index_of_.find(id);
  SL_CHECK_MSG(it != index_of_.end(), "unknown keyframe id {}", id);
  return records_[it->second];
}

KeyframeRecord LoopDetector::Impl::record(int64_t id) const {
  return UnpackRecord(packed_record(id));
}

const KeyframeRecord& LoopDetector::Impl::Unpacked(const PackedKeyframe& packed) const {
  auto it = unpacked_.find(&packed);
  if (it == unpacked_.end()) it = unpacked_.emplace(&packed, UnpackRecord(packed)).first;
  return it->second;
}

size_t LoopDetector::Impl::StoredBytes() const {
  size_t total = 0;
  for (const auto& r : records_) total += r.Bytes();
  return total;
}

size_t LoopDetector::Impl::RecentBufferBytes() const {
  size_t total = 0;
  for (const auto& d : recent_) total += d.size() * sizeof(Descriptor);
  for (const auto& [index, d] : overlap_buffer_) total += d.size() * sizeof(Descriptor);
  return total;
}

bool LoopDetector::Impl::ValidateInput(const KeyframeInput& input) const {
  SL_CHECK_MSG(!index_of_.count(input.id), "keyframe id {} was already processed", input.id);
  SL_CHECK_MSG(std::isfinite(input.timestamp), "keyframe {}: timestamp is not finite", input.id);
  SL_CHECK_MSG(records_.empty() || input.timestamp > records_.back().timestamp(),
               "keyframe {}: timestamp {} must increase (previous keyframe: {})", input.id,
               input.timestamp, records_.empty() ? 0.0 : records_.back().timestamp());
  ValidateImageInput(input);
  SL_CHECK_MSG(!input.pose_reset || input.world_from_cam,
               "keyframe {}: pose_reset needs a pose (the first pose in the new world frame)",
               input.id);
  if (input.world_from_cam) {
    const Sim3d& pose = *input.world_from_cam;
    SL_CHECK_MSG(pose.translation.allFinite() && pose.rotation.coeffs().allFinite() &&
                     std::isfinite(pose.scale) && pose.scale > 0,
                 "keyframe {}: pose is not finite (or scale <= 0)", input.id);
    SL_CHECK_MSG(std::abs(pose.rotation.norm() - 1.0) < 1e-6,
                 "keyframe {}: pose has a non-unit quaternion (norm {})", input.id,
                 pose.rotation.norm());
  }
  // Without a pose under a geometric search strategy: "tracking lost", relocalise.
  const bool relocalize =
      !input.world_from_cam && options_.search.strategy != SearchStrategy::kGlobal;
  if (relocalize) {
    SL_CHECK_MSG(options_.relocalize_without_pose,
                 "keyframe {} has no pose: only the global search strategy works without poses "
                 "(or enable relocalize_without_pose)",
                 input.id);
  }
  return relocalize;
}

size_t LoopDetector::Impl::Store(PackedKeyframe rec, bool relocalize) {
  ClearCallCaches();
  const size_t index = records_.size();
  // A keyframe without a pose (global search only) stays where the last posed one was: the
  // path length across the gap is the chord between the posed keyframes around it.
  track_.Store(rec.has_pose() ? std::optional<Eigen::Vector3d>(rec.world_from_cam().translation)
                              : std::nullopt);
  index_of_[rec.id()] = index;
  // No place on the trajectory without a pose (its path length is never read: FarAlong needs
  // both poses).
  if (!relocalize) search_.Add(rec.id(), track_.last_position());
  path_length_.push_back(relocalize ? 0.0 : search_.PathLength(rec.id()));
  records_.push_back(std::move(rec));
  return index;
}

void LoopDetector::Impl::RelocalizeStored(const KeyframeRecord& query, LoopResult* result) const {
  result->relocalization = true;
  if (records_.back().size() < 5) {
    result->status = LoopStatus::kNoFeatures;
    return;
  }
  std::vector<PoolEntry> pool;
  for (size_t i = 0; i + 1 < records_.size(); ++i)
    if (records_[i].has_pose()) pool.push_back({0, &records_[i]});
  for (size_t i = 0; i < priors_.size(); ++i)
    if (priors_.record(i).has_pose()) pool.push_back({priors_.session(i), &priors_.record(i)});
  MatchAndVerifyPool(query, pool, result);
}

bool LoopDetector::Impl::FarAlong(const KeyframeRecord& query, size_t query_index,
                                  size_t ci) const {
  const PackedKeyframe& c = records_[ci];
  if (options_.min_path_ratio <= 0 || !query.has_pose || !c.has_pose()) return true;
  const double chord = (query.world_from_cam.translation - c.world_from_cam().translation).norm();
  return path_length_[query_index] - path_length_[ci] >= options_.min_path_ratio * chord;
}

std::vector<int64_t> LoopDetector::Impl::SearchCandidates(const KeyframeRecord& query, size_t index,
                                                          LoopResult* result) {
  const SearchAreaResult area = search_.Query(query.id);
  std::vector<int64_t> candidates;
  candidates.reserve(area.candidates.size());
  for (int64_t id : area.candidates)
    if (FarAlong(query, index, index_of_.at(id))) candidates.push_back(id);
  if (!query.has_pose && options_.overlap_gap > 0 && !candidates.empty()) {
    const size_t exclude = static_cast<size_t>(std::max(0, options_.search.exclude_recent));
    const size_t start = OverlapStart(query, index > exclude ? index - exclude : 0);
    result->overlap_excluded = 0;
    std::vector<int64_t> kept;
    for (int64_t id : candidates) {
      if (index_of_.at(id) < start) {
        kept.push_back(id);
      } else {
        ++result->overlap_excluded;
      }
    }
    candidates = std::move(kept);
  }
  result->area = candidates;
  std::sort(result->area.begin(), result->area.end());
  if (options_.retrieval == CandidateRetrieval::kAnn)
    candidates = RetrieveByVotes(query, index, candidates);  // index insert + vote query
  return candidates;
}

void LoopDetector::Impl::MergeSubSearch(LoopResult sub, CandidateSource source,
                                        LoopResult* result) {
  // A sub-search after the search area's (the appearance fallback, earlier pose segments, earlier
  // sessions): its matching and verification time is the query's; when it detected, its loop is
  // the result, with what the area and the sub-searches before it reported.
  result->timings.match_ms += sub.timings.match_ms;
  result->timings.verify_ms += sub.timings.verify_ms;
  if (!sub.detected()) return;
  sub.timings = result->timings;
  sub.source = source;
  sub.candidates = result->candidates;
  sub.overlap_excluded = result->overlap_excluded;
  sub.area = std::move(result->area);
  sub.appearance_candidates = result->appearance_candidates;
  sub.verified_in_area = std::move(result->verified_in_area);
  sub.verified_by_appearance = std::move(result->verified_by_appearance);
  *result = std::move(sub);
}

void LoopDetector::Impl::AppearanceFallback(const KeyframeRecord& query, size_t index,
                                            std::vector<int64_t> in_area, LoopResult* result) {
  // Every eligible stored keyframe the area did not hold, far along the path.
  Timer stage;
  std::sort(in_area.begin(), in_area.end());
  const size_t exclude = static_cast<size_t>(std::max(0, options_.search.exclude_recent));
  std::vector<size_t> eligible;
  for (size_t ci = 0; ci + exclude < index; ++ci) {
    const PackedKeyframe& c = records_[ci];
    if (c.has_pose() && SameSegment(ci, index) && FarAlong(query, index, ci) &&
        !std::binary_search(in_area.begin(), in_area.end(), c.id()))
      eligible.push_back(ci);
  }
  std::vector<int64_t> others = PreRankByAppearance(query, index, eligible);
  const double fallback_search_ms = stage.ElapsedMs();
  // Outside the search area the raw trajectory vouches for nothing: a weak pair there (6-7
  // inliers of K = 20, confirmed only by its neighbour) is as likely the same texture elsewhere
  // (aerial_circuit, street00: runs of false weak pairs 100-420 m from their match); only pairs
  // at the inlier floor.
  LoopResult fallback;
  fallback.query_id = query.id;
  SearchAndVerify(query, std::move(others), &fallback, /*weak_pairs=*/false);
  result->timings.search_ms += fallback_search_ms;
  result->appearance_candidates = fallback.candidates;
  result->verified_by_appearance = std::move(fallback.verified_in_area);
  MergeSubSearch(std::move(fallback), CandidateSource::kAppearance, result);
}

std::vector<int64_t> LoopDetector::Impl::PreRankByAppearance(
    const KeyframeRecord& query, size_t index, const std::vector<size_t>& indices) const {
  // The query's own K (its repeatable features when ranked so; its first fallback_fine_features
  // at a large K, as on the stored side), then its best extracted ones.
  std::span<const Descriptor> own = records_[index].descriptors();
  if (options_.fallback_fine_features > 0)
    own = own.first(std::min(own.size(), static_cast<size_t>(options_.fallback_fine_features)));
  std::vector<Descriptor> probe(own.begin(), own.end());
  ProbeRankOptions ro;
  ro.keep = static_cast<size_t>(options_.fallback_candidates);
  ro.coarse_features = static_cast<size_t>(options_.fallback_coarse_features);
  ro.coarse_keep = 10 * ro.keep;
  ro.fine_features = static_cast<size_t>(options_.fallback_fine_features);
  ro.coarse_probe = static_cast<size_t>(options_.fallback_coarse_probe);
  ro.max_distance = options_.match.max_distance;
  const std::vector<size_t> best = RankByProbe(
      indices.size(), [&](size_t i) { return records_[indices[i]].descriptors(); }, probe, ro);
  std::vector<int64_t> ids;
  ids.reserve(best.size());
  for (const size_t i : best) ids.push_back(records_[indices[i]].id());
  return ids;
}

void LoopDetector::Impl::SearchEarlierSegments(const KeyframeRecord& query, size_t index,
                                               LoopResult* result) {
  // Their world frame is not this segment's: no search area, no pose check, as for earlier
  // sessions; every keyframe counts, the ones just before the reset included (a relocalisation,
  // not a loop: the nearest place in time ties the two frames best).
  std::vector<size_t> earlier_segments;
  for (size_t i = 0; i < index; ++i)
    if (records_[i].has_pose() && !SameSegment(i, index)) earlier_segments.push_back(i);
  const std::vector<int64_t> ids = PreRankByAppearance(query, index, earlier_segments);
  std::vector<PoolEntry> pool;
  pool.reserve(ids.size());
  for (const int64_t id : ids) pool.push_back({0, &records_[index_of_.at(id)]});
  LoopResult earlier;
  earlier.query_id = query.id;
  MatchAndVerifyPool(query, pool, &earlier);
  MergeSubSearch(std::move(earlier), CandidateSource::kEarlierSegment, result);
}

void LoopDetector::Impl::SearchPriorSessions(const KeyframeRecord& query,
                                             LoopResult* result) const {
  // Earlier sessions, by appearance only (their world frame is not ours).
  std::vector<PoolEntry> pool;
  pool.reserve(priors_.size());
  for (size_t i = 0; i < priors_.size(); ++i)
    pool.push_back({priors_.session(i), &priors_.record(i)});
  LoopResult prior;
  prior.query_id = query.id;
  MatchAndVerifyPool(query, pool, &prior);
  const CandidateSource source = prior.source;
  MergeSubSearch(std::move(prior), source, result);
}

LoopResult LoopDetector::Impl::Process(const KeyframeInput& input) {
  Timer total;
  LoopResult result;
  result.query_id = input.id;
  // Validate everything before any state changes, so a rejected keyframe leaves the stored map
  // exactly as it was (docs/ROBUSTNESS.md).
  const bool relocalize = ValidateInput(input);
  const PoseReset reset = track_.Classify(input.world_from_cam, input.pose_reset);

  // 1. Informative features: the query's extraction (all it matches with), and the K stored.
  Timer stage;
  KeyframeRecord query = ExtractRecord(input);
  query.has_pose = input.world_from_cam.has_value();
  if (query.has_pose) query.world_from_cam = *input.world_from_cam;
  KeyframeRecord stored = StoredSubset(query, StoredOrder(query), options_.features.max_features);
  PackedKeyframe rec = PackRecord(stored);
  if (options_.repeatability_window > 0) {
    recent_.push_back(query.descriptors);
    if (recent_.size() > static_cast<size_t>(options_.repeatability_window)) recent_.pop_front();
  }
  result.timings.extract_ms = stage.ElapsedMs();

  // 2. Store (packed: the stored pose, keypoints and depths are the quantised ones from here on,
  // the same after a round trip through the map), in a new raw pose segment after a reset.
  const double raw_step = track_.Advance(input.world_from_cam, reset);
  if (reset != PoseReset::kNone) search_ = SearchArea(options_.search);
  const size_t index = Store(std::move(rec), relocalize);
  if (!query.has_pose && OverlapBufferUsed(query)) {
    const size_t n = std::min(query.size(), static_cast<size_t>(options_.overlap_features));
    overlap_buffer_.emplace_back(
        index, std::vector<Descriptor>(query.descriptors.begin(), query.descriptors.begin() + n));
    if (overlap_buffer_.size() > static_cast<size_t>(options_.overlap_window))
      overlap_buffer_.pop_front();
  }
  const auto finish = [&] {
    result.pose_segment = track_.current_segment();  // (the fallbacks replace the result)
    result.pose_reset = reset;
    result.raw_step = raw_step;
    result.timings.total_ms = total.ElapsedMs();
    return result;
  };
  if (relocalize) {
    RelocalizeStored(query, &result);
    return finish();
  }
  if ((index + 1) % static_cast<size_t>(options_.check_every) != 0) {
    result.status = LoopStatus::kSkipped;
    return finish();
  }
  if (records_.back().size() < 5) {
    result.status = LoopStatus::kNoFeatures;
    return finish();
  }

  // 3. Search area, then the scale-free "far along the path" filter (FarAlong).
  stage.Restart();
  std::vector<int64_t> candidates = SearchCandidates(query, index, &result);
  result.timings.search_ms = stage.ElapsedMs();

  // 4. Match, verify, check (SearchAndVerify); the fallbacks when that finds nothing.
  SearchAndVerify(query, candidates, &result);
  if (!result.detected() && options_.appearance_fallback && query.has_pose &&
      options_.search.strategy != SearchStrategy::kGlobal) {
    AppearanceFallback(query, index, std::move(candidates), &result);
  }
  if (!result.detected() && query.has_pose && track_.current_segment() > 0)
    SearchEarlierSegments(query, index, &result);
  if (result.detected()) {
    SetWorldFromQuery(Stored(index_of_.at(result.match_id)), &result);
  } else if (options_.search_prior_sessions && !priors_.empty()) {
    SearchPriorSessions(query, &result);
  }
  result.relocalization =
      !query.has_pose || (result.detected() && result.source == CandidateSource::kEarlierSegment);
  return finish();
}

void LoopDetector::Impl::ValidateImageInput(const KeyframeInput& input) const {
  input.intrinsics.Check();
  SL_CHECK_MSG(!input.image.empty(), "keyframe {}: image must not be empty", input.id);
  SL_CHECK_MSG(input.image.type() == CV_8UC1,
               "keyframe {}: image must be 8-bit grayscale (CV_8UC1)", input.id);
  const int min_side = options_.features.MinImageSide();
  SL_CHECK_MSG(input.image.cols >= min_side && input.image.rows >= min_side,
               "keyframe {}: image of {}x{} pixels is too small: expected at least {}x{} (ORB's "
               "31-pixel patch and {} pyramid levels of scale {})",
               input.id, input.image.cols, input.image.rows, min_side, min_side,
               options_.features.orb_levels, options_.features.orb_scale_factor);
  SL_CHECK_MSG((input.intrinsics.width == 0 || input.image.cols == input.intrinsics.width) &&
                   (input.intrinsics.height == 0 || input.image.rows == input.intrinsics.height),
               "keyframe {}: image size {}x{} does not match the intrinsics {}x{}", input.id,
               input.image.cols, input.image.rows, input.intrinsics.width, input.intrinsics.height);
  SL_CHECK_MSG(
      input.mapped_depths.empty() || input.mapped_depths.size() == input.mapped_pixels.size(),
      "mapped_depths ({}) must match mapped_pixels ({})", input.mapped_depths.size(),
      input.mapped_pixels.size());
  // As the mapped-pixels file reader refuses a non-finite number; a depth <= 0 is "unknown".
  for (size_t i = 0; i < input.mapped_pixels.size(); ++i) {
    const cv::Point2f& p = input.mapped_pixels[i];
    SL_CHECK_MSG(std::isfinite(p.x) && std::isfinite(p.y),
                 "keyframe {}: mapped_pixels[{}]: expected finite pixel coordinates (u, v), got "
                 "({}, {})",
                 input.id, i, p.x, p.y);
  }
  for (size_t i = 0; i < input.mapped_depths.size(); ++i) {
    SL_CHECK_MSG(std::isfinite(input.mapped_depths[i]),
                 "keyframe {}: mapped_depths[{}]: expected a finite depth (<= 0: unknown), got {}",
                 input.id, i, input.mapped_depths[i]);
  }
}

KeyframeRecord LoopDetector::Impl::ExtractRecord(const KeyframeInput& input) const {
  KeyframeRecord rec;
  rec.id = input.id;
  rec.timestamp = input.timestamp;
  FeatureInput fin;
  fin.image = &input.image;
  fin.intrinsics = &input.intrinsics;
  if (!input.high_gradient_mask.empty()) fin.mask = &input.high_gradient_mask;
  if (!input.mapped_pixels.empty()) fin.mapped_pixels = &input.mapped_pixels;
  if (!input.mapped_depths.empty()) fin.mapped_depths = &input.mapped_depths;
  FeatureOptions features = options_.features;
  features.max_features = QueryFeatureCount();
  ExtractInformativeFeatures(fin, features, &rec);
  return rec;
}

int LoopDetector::Impl::QueryFeatureCount() const {
  const FeatureOptions& f = options_.features;
  if (!options_.asymmetric_matching && options_.repeatability_window == 0) return f.max_features;
  return std::clamp(options_.query_max_features, f.max_features, f.orb_candidates);
}

std::vector<int> LoopDetector::Impl::StoredOrder(const KeyframeRecord& full) const {
  const int k = options_.features.max_features;
  const int pool =
      std::min(static_cast<int>(full.size()),
               options_.repeatability_window > 0 ? std::max(k, options_.repeatability_pool) : k);
  std::vector<int> order(static_cast<size_t>(std::max(0, pool)));
  std::iota(order.begin(), order.end(), 0);
  // Without a pose the persistent features are kept out: nothing but the decay of the shared
  // view tells a keyframe still seen ahead from a revisit (the overlap walk), and the features
  // that persist longest are the ones that defeat that decay (Options::repeatability_window).
  if (options_.repeatability_window == 0 || recent_.empty() || !full.has_pose) return order;
  const std::vector<Descriptor> candidates(full.descriptors.begin(),
                                           full.descriptors.begin() + pool);
  std::vector<int> found(order.size(), 0);
  for (const std::vector<Descriptor>& before : recent_)
    for (const DescriptorMatch& m : MatchDescriptors(candidates, before, options_.match))
      ++found[static_cast<size_t>(m.query)];
  // Re-found most first; among equals, the extraction's own ranking (stable).
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return found[static_cast<size_t>(a)] > found[static_cast<size_t>(b)];
  });
  return order;
}

std::vector<DescriptorMatch> LoopDetector::Impl::MatchQuery(
    const KeyframeRecord& query, std::span<const Descriptor> stored) const {
  if (options_.asymmetric_matching && query.size() > stored.size())
    return MatchStoredIntoQuery(query.descriptors, stored, options_.match);
  return MatchDescriptors(query.descriptors, stored, options_.match);
}

void LoopDetector::Impl::SetWorldFromQuery(const KeyframeRecord& match, LoopResult* result) const {
  if (result->detected() && match.has_pose && result->pose_kind != RelativePoseKind::kNone) {
    result->world_from_query = match.world_from_cam * result->match_from_query;
    result->has_world_from_query = true;
  }
}

}  // namespace sparseloop
