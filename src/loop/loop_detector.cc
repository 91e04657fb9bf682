#include "sparseloop/loop/loop_detector.h"

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
  return source == CandidateSource::kAppearance ? "appearance" : "area";
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

void LoopDetector::Options::Check() const {
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
  SL_CHECK_MSG(std::isfinite(min_path_ratio) && min_path_ratio >= 0,
               "min_path_ratio must be >= 0, got {}", min_path_ratio);
  SL_CHECK_MSG(overlap_gap >= 0 && overlap_max_walk >= 0,
               "overlap_gap and overlap_max_walk must be >= 0, got {} and {}", overlap_gap,
               overlap_max_walk);
  SL_CHECK_MSG(overlap_match_factor >= 0 && overlap_relative >= 0 && overlap_relative <= 1,
               "overlap_match_factor must be >= 0 and overlap_relative in [0, 1], got {} and {}",
               overlap_match_factor, overlap_relative);
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
  SL_CHECK_MSG(agreement_window >= 1, "agreement_window must be >= 1 keyframe, got {}",
               agreement_window);
  SL_CHECK_MSG(temporal_window >= 0, "temporal_window must be >= 0, got {}", temporal_window);
  SL_CHECK_MSG(std::isfinite(small_k_fraction) && small_k_fraction > 0 && small_k_fraction <= 1,
               "small_k_fraction must be in (0, 1], got {}", small_k_fraction);
  SL_CHECK_MSG(small_k_floor >= 5, "small_k_floor must be >= 5, got {}", small_k_floor);
  local_map.Check();
}

void LoopDetector::Options::LocalMapOptions::Check() const {
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

int SmallKFloor(const LoopDetector::Options& o, int n) {
  const int k = o.features.max_features;
  return std::min(n,
                  std::max(o.small_k_floor, static_cast<int>(std::ceil(o.small_k_fraction * k))));
}
}  // namespace

int LoopDetector::Options::EffectiveMinInliers() const {
  return std::max(SmallKFloor(*this, verify.min_inliers),
                  static_cast<int>(std::ceil(min_inlier_fraction_of_k * features.max_features)));
}

int LoopDetector::Options::EffectiveMinMatches() const { return SmallKFloor(*this, min_matches); }

LoopDetector::LoopDetector(Options options)
    : options_(std::move(options)), search_([&] {
        options_.Check();
        return options_.search;
      }()) {
  verify_ = options_.verify;
  verify_.seed = options_.seed;
  verify_.min_inliers = options_.EffectiveMinInliers();
  if (options_.retrieval == CandidateRetrieval::kAnn) ann_.emplace(options_.ann);
}

const PackedKeyframe& LoopDetector::packed_record(int64_t id) const {
  auto it = index_of_.find(id);
  SL_CHECK_MSG(it != index_of_.end(), "unknown keyframe id {}", id);
  return records_[it->second];
}

KeyframeRecord LoopDetector::record(int64_t id) const { return UnpackRecord(packed_record(id)); }

const KeyframeRecord& LoopDetector::Unpacked(const PackedKeyframe& packed) const {
  auto it = unpacked_.find(&packed);
  if (it == unpacked_.end()) it = unpacked_.emplace(&packed, UnpackRecord(packed)).first;
  return it->second;
}

size_t LoopDetector::StoredBytes() const {
  size_t total = 0;
  for (const auto& r : records_) total += r.Bytes();
  return total;
}

bool LoopDetector::ValidateInput(const KeyframeInput& input) const {
  SL_CHECK_MSG(!index_of_.count(input.id), "keyframe id {} was already processed", input.id);
  SL_CHECK_MSG(std::isfinite(input.timestamp), "keyframe {}: timestamp is not finite", input.id);
  SL_CHECK_MSG(records_.empty() || input.timestamp > records_.back().timestamp(),
               "keyframe {}: timestamp {} must increase (previous keyframe: {})", input.id,
               input.timestamp, records_.empty() ? 0.0 : records_.back().timestamp());
  ValidateImageInput(input);
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

size_t LoopDetector::Store(PackedKeyframe rec, bool relocalize) {
  unpacked_.clear();
  const size_t index = records_.size();
  // A keyframe without a pose (global search only) stays where the last posed one was: the
  // path length across the gap is the chord between the posed keyframes around it.
  if (rec.has_pose()) last_position_ = rec.world_from_cam().translation;
  any_pose_ |= rec.has_pose();
  any_missing_pose_ |= !rec.has_pose();
  index_of_[rec.id()] = index;
  // No place on the trajectory without a pose.
  if (!relocalize) search_.Add(rec.id(), last_position_);
  records_.push_back(std::move(rec));
  return index;
}

void LoopDetector::RelocalizeStored(const KeyframeRecord& query, LoopResult* result) const {
  result->relocalization = true;
  if (records_.back().size() < 5) {
    result->status = LoopStatus::kNoFeatures;
    return;
  }
  std::vector<PoolEntry> pool;
  for (size_t i = 0; i + 1 < records_.size(); ++i)
    if (records_[i].has_pose()) pool.push_back({0, &records_[i]});
  for (size_t i = 0; i < prior_records_.size(); ++i)
    if (prior_records_[i].has_pose()) pool.push_back({prior_session_[i], &prior_records_[i]});
  MatchAndVerifyPool(query, pool, result);
}

bool LoopDetector::FarAlong(const KeyframeRecord& query, size_t ci) const {
  const PackedKeyframe& c = records_[ci];
  if (options_.min_path_ratio <= 0 || !query.has_pose || !c.has_pose()) return true;
  const double chord = (query.world_from_cam.translation - c.world_from_cam().translation).norm();
  return search_.PathLength(query.id) - search_.PathLength(c.id()) >=
         options_.min_path_ratio * chord;
}

std::vector<int64_t> LoopDetector::SearchCandidates(const KeyframeRecord& query, size_t index,
                                                    LoopResult* result) {
  const SearchAreaResult area = search_.Query(query.id);
  std::vector<int64_t> candidates;
  candidates.reserve(area.candidates.size());
  for (int64_t id : area.candidates)
    if (FarAlong(query, index_of_.at(id))) candidates.push_back(id);
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
  if (options_.retrieval == CandidateRetrieval::kAnn)
    candidates = RetrieveByVotes(query, index, candidates);  // index insert + vote query
  return candidates;
}

void LoopDetector::AppearanceFallback(const KeyframeRecord& query, size_t index,
                                      std::vector<int64_t> in_area, LoopResult* result) {
  // Every eligible stored keyframe the area did not hold, far along the path.
  Timer stage;
  std::sort(in_area.begin(), in_area.end());
  const size_t exclude = static_cast<size_t>(std::max(0, options_.search.exclude_recent));
  std::vector<int64_t> others;
  for (size_t ci = 0; ci + exclude < index; ++ci) {
    const PackedKeyframe& c = records_[ci];
    if (c.has_pose() && FarAlong(query, ci) &&
        !std::binary_search(in_area.begin(), in_area.end(), c.id()))
      others.push_back(c.id());
  }
  const double fallback_search_ms = stage.ElapsedMs();
  LoopResult fallback;
  fallback.query_id = query.id;
  SearchAndVerify(query, std::move(others), &fallback);
  result->timings.search_ms += fallback_search_ms;
  result->timings.match_ms += fallback.timings.match_ms;
  result->timings.verify_ms += fallback.timings.verify_ms;
  if (fallback.detected()) {
    fallback.timings = result->timings;
    fallback.source = CandidateSource::kAppearance;
    *result = fallback;
  }
}

void LoopDetector::SearchPriorSessions(const KeyframeRecord& query, LoopResult* result) const {
  // Earlier sessions, by appearance only (their world frame is not ours).
  std::vector<PoolEntry> pool;
  pool.reserve(prior_records_.size());
  for (size_t i = 0; i < prior_records_.size(); ++i)
    pool.push_back({prior_session_[i], &prior_records_[i]});
  LoopResult prior;
  prior.query_id = query.id;
  MatchAndVerifyPool(query, pool, &prior);
  if (prior.detected()) {
    prior.timings.extract_ms = result->timings.extract_ms;
    prior.timings.search_ms = result->timings.search_ms;
    prior.timings.match_ms += result->timings.match_ms;
    prior.timings.verify_ms += result->timings.verify_ms;
    *result = prior;
  } else {
    result->timings.match_ms += prior.timings.match_ms;
    result->timings.verify_ms += prior.timings.verify_ms;
  }
}

LoopResult LoopDetector::Process(const KeyframeInput& input) {
  Timer total;
  LoopResult result;
  result.query_id = input.id;
  // Validate everything before any state changes, so a rejected keyframe leaves the stored map
  // exactly as it was (docs/ROBUSTNESS.md).
  const bool relocalize = ValidateInput(input);

  // 1. Informative features: the query's extraction (all it matches with), and the K stored.
  Timer stage;
  KeyframeRecord query = ExtractRecord(input);
  query.has_pose = input.world_from_cam.has_value();
  if (query.has_pose) query.world_from_cam = *input.world_from_cam;
  PackedKeyframe rec =
      PackRecord(StoredSubset(query, StoredOrder(query), options_.features.max_features));
  if (options_.repeatability_window > 0) {
    recent_.push_back(query.descriptors);
    if (recent_.size() > static_cast<size_t>(options_.repeatability_window)) recent_.pop_front();
  }
  result.timings.extract_ms = stage.ElapsedMs();

  // 2. Store (packed: the stored pose, keypoints and depths are the quantised ones from here on,
  // the same after a round trip through the map).
  const size_t index = Store(std::move(rec), relocalize);
  const auto finish = [&] {
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
  if (result.detected()) {
    SetWorldFromQuery(Stored(index_of_.at(result.match_id)), &result);
  } else if (options_.search_prior_sessions && !prior_records_.empty()) {
    SearchPriorSessions(query, &result);
  }
  result.relocalization = !query.has_pose;
  return finish();
}

void LoopDetector::AddPriorKeyframes(int64_t session, std::vector<KeyframeRecord> records) {
  SL_CHECK_MSG(session > 0, "prior session id must be > 0 (0 is the current session), got {}",
               session);
  SL_CHECK_MSG(!prior_index_.count(session), "prior session {} was already added", session);
  std::unordered_map<int64_t, size_t> index;
  for (size_t i = 0; i < records.size(); ++i) {
    const KeyframeRecord& r = records[i];
    SL_CHECK_MSG(index.emplace(r.id, prior_records_.size() + i).second,
                 "prior session {}: duplicate keyframe id {}", session, r.id);
    SL_CHECK_MSG(std::isfinite(r.focal_px) && r.focal_px > 0,
                 "prior session {} keyframe {}: focal_px must be > 0, got {}", session, r.id,
                 r.focal_px);
    SL_CHECK_MSG(r.keypoints.size() == r.descriptors.size() &&
                     (r.depths.empty() || r.depths.size() == r.descriptors.size()),
                 "prior session {} keyframe {}: {} descriptors, {} keypoints, {} depths", session,
                 r.id, r.descriptors.size(), r.keypoints.size(), r.depths.size());
    if (r.has_pose) {
      const Sim3d& pose = r.world_from_cam;
      SL_CHECK_MSG(pose.translation.allFinite() && pose.rotation.coeffs().allFinite() &&
                       std::isfinite(pose.scale) && pose.scale > 0 &&
                       std::abs(pose.rotation.norm() - 1.0) < 1e-6,
                   "prior session {} keyframe {}: pose is not finite / not a unit quaternion",
                   session, r.id);
    }
  }
  unpacked_.clear();  // prior_records_ may move
  std::vector<PackedKeyframe> packed;
  packed.reserve(records.size());
  for (const auto& r : records) packed.push_back(PackRecord(r));
  prior_index_[session] = std::move(index);
  prior_records_.reserve(prior_records_.size() + packed.size());
  for (auto& r : packed) {
    prior_records_.push_back(std::move(r));
    prior_session_.push_back(session);
  }
}

KeyframeRecord LoopDetector::prior_record(int64_t session, int64_t id) const {
  auto s = prior_index_.find(session);
  SL_CHECK_MSG(s != prior_index_.end(), "unknown prior session {}", session);
  auto it = s->second.find(id);
  SL_CHECK_MSG(it != s->second.end(), "unknown keyframe id {} in prior session {}", id, session);
  return UnpackRecord(prior_records_[it->second]);
}

void LoopDetector::ValidateImageInput(const KeyframeInput& input) const {
  input.intrinsics.Check();
  SL_CHECK_MSG(!input.image.empty(), "keyframe {}: image must not be empty", input.id);
  SL_CHECK_MSG(input.image.type() == CV_8UC1,
               "keyframe {}: image must be 8-bit grayscale (CV_8UC1)", input.id);
  SL_CHECK_MSG((input.intrinsics.width == 0 || input.image.cols == input.intrinsics.width) &&
                   (input.intrinsics.height == 0 || input.image.rows == input.intrinsics.height),
               "keyframe {}: image size {}x{} does not match the intrinsics {}x{}", input.id,
               input.image.cols, input.image.rows, input.intrinsics.width, input.intrinsics.height);
  SL_CHECK_MSG(
      input.mapped_depths.empty() || input.mapped_depths.size() == input.mapped_pixels.size(),
      "mapped_depths ({}) must match mapped_pixels ({})", input.mapped_depths.size(),
      input.mapped_pixels.size());
}

KeyframeRecord LoopDetector::ExtractRecord(const KeyframeInput& input) const {
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

int LoopDetector::QueryFeatureCount() const {
  const FeatureOptions& f = options_.features;
  if (!options_.asymmetric_matching && options_.repeatability_window == 0) return f.max_features;
  return std::clamp(options_.query_max_features, f.max_features, f.orb_candidates);
}

std::vector<int> LoopDetector::StoredOrder(const KeyframeRecord& full) const {
  const int k = options_.features.max_features;
  const int pool =
      std::min(static_cast<int>(full.size()),
               options_.repeatability_window > 0 ? std::max(k, options_.repeatability_pool) : k);
  std::vector<int> order(static_cast<size_t>(std::max(0, pool)));
  std::iota(order.begin(), order.end(), 0);
  if (options_.repeatability_window == 0 || recent_.empty()) return order;
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

std::vector<DescriptorMatch> LoopDetector::MatchQuery(const KeyframeRecord& query,
                                                      std::span<const Descriptor> stored) const {
  if (options_.asymmetric_matching && query.size() > stored.size())
    return MatchStoredIntoQuery(query.descriptors, stored, options_.match);
  return MatchDescriptors(query.descriptors, stored, options_.match);
}

LoopResult LoopDetector::Relocalize(const KeyframeInput& input) {
  Timer total;
  ValidateImageInput(input);
  LoopResult result;
  result.query_id = input.id;
  result.relocalization = true;
  unpacked_.clear();
  Timer stage;
  KeyframeRecord rec = ExtractRecord(input);
  result.timings.extract_ms = stage.ElapsedMs();
  if (std::min<size_t>(rec.size(), options_.features.max_features) < 5) {
    result.status = LoopStatus::kNoFeatures;
  } else {
    std::vector<PoolEntry> pool;
    for (const auto& r : records_)
      if (r.has_pose()) pool.push_back({0, &r});
    for (size_t i = 0; i < prior_records_.size(); ++i)
      if (prior_records_[i].has_pose()) pool.push_back({prior_session_[i], &prior_records_[i]});
    MatchAndVerifyPool(rec, pool, &result);
  }
  result.timings.total_ms = total.ElapsedMs();
  return result;
}

void LoopDetector::SetWorldFromQuery(const KeyframeRecord& match, LoopResult* result) const {
  if (result->detected() && match.has_pose && result->pose_kind != RelativePoseKind::kNone) {
    result->world_from_query = match.world_from_cam * result->match_from_query;
    result->has_world_from_query = true;
  }
}

namespace {

// Hamming matching of the query against each candidate record, then the candidates with at least
// options.EffectiveMinMatches() ranked by match count, then score, then `tie_key` (ascending). Both
// the in-session search and the appearance-only pool matching use it, so they rank identically.
struct RankedCandidate {
  size_t entry;  // position in the candidate list
  std::vector<DescriptorMatch> matches;
  double score;
  size_t tie_key;
};
struct CandidateRanking {
  std::vector<RankedCandidate> ranked;
  int best_count = 0;     // most matches of any candidate (also below min_matches)
  size_t best_entry = 0;  // its position in the candidate list
};

template <typename RecordAt, typename TieKey, typename Match>
CandidateRanking RankCandidates(size_t num_candidates, RecordAt&& record_at, TieKey&& tie_key,
                                Match&& match, int min_matches, int max_distance) {
  CandidateRanking out;
  for (size_t e = 0; e < num_candidates; ++e) {
    auto m = match(record_at(e));
    const int n = static_cast<int>(m.size());
    if (n > out.best_count) {
      out.best_count = n;
      out.best_entry = e;
    }
    if (n < min_matches) continue;
    const double s = MatchScore(m, max_distance);
    out.ranked.push_back({e, std::move(m), s, tie_key(e)});
  }
  std::sort(out.ranked.begin(), out.ranked.end(),
            [](const RankedCandidate& a, const RankedCandidate& b) {
              if (a.matches.size() != b.matches.size()) return a.matches.size() > b.matches.size();
              if (a.score != b.score) return a.score > b.score;
              return a.tie_key < b.tie_key;
            });
  return out;
}

}  // namespace

void LoopDetector::MatchAndVerifyPool(const KeyframeRecord& query,
                                      const std::vector<PoolEntry>& pool,
                                      LoopResult* result) const {
  result->candidates = static_cast<int>(pool.size());
  if (pool.empty()) {
    result->status = LoopStatus::kNoCandidates;
    return;
  }
  Timer stage;
  const CandidateRanking ranking = RankCandidates(
      pool.size(), [&](size_t e) -> const PackedKeyframe& { return *pool[e].record; },
      [](size_t e) { return e; }, [&](const PackedKeyframe& r) { return MatchQuery(query, r); },
      options_.EffectiveMinMatches(), options_.match.max_distance);
  const auto& ranked = ranking.ranked;
  result->timings.match_ms += stage.ElapsedMs();
  if (ranked.empty()) {
    result->status = LoopStatus::kTooFewMatches;
    result->match_id = pool[ranking.best_entry].record->id();
    result->match_session = pool[ranking.best_entry].session;
    result->matches = ranking.best_count;
    return;
  }
  stage.Restart();
  result->status = LoopStatus::kTooFewInliers;
  bool have_best = false;
  const int n_verify = std::min<int>(options_.max_verify, static_cast<int>(ranked.size()));
  for (int r = 0; r < n_verify; ++r) {
    const RankedCandidate& cand = ranked[r];
    const PoolEntry& entry = pool[cand.entry];
    const KeyframeRecord& match = Unpacked(*entry.record);
    VerificationResult v = VerifyPair(query, match, cand.matches, verify_);
    if (have_best && !v.success && v.inliers <= result->inliers) continue;
    result->match_id = match.id;
    result->match_session = entry.session;
    result->matches = static_cast<int>(cand.matches.size());
    result->inliers = v.inliers;
    result->score = static_cast<double>(v.inliers) / options_.features.max_features;
    result->method = v.method;
    result->pose_kind = v.pose_kind;
    result->match_from_query = v.match_from_query;
    result->status = v.success ? LoopStatus::kDetected : LoopStatus::kTooFewInliers;
    have_best = true;
    if (v.success) {
      SetWorldFromQuery(match, result);
      break;
    }
  }
  result->timings.verify_ms += stage.ElapsedMs();
}

namespace {

// PnP of the query against the match's local map fixes the query camera in match units; the
// query's own triangulated depths (query units) of the same inliers then give the relative scale
// directly: s = z(query_from_match * P) / z_query per inlier, robustly the median. A 3-point
// Sim(3) RANSAC between two noisy triangulated clouds rarely passes the 2 px check in both
// cameras (castle 29 -> 02 falls back to PnP), while this needs no 3D-3D hypothesis. The loop
// becomes kSim3 with the scale's information n / var(log s_i) added to the PnP information.
// Needs kMinScalePairs inliers with a query depth.
constexpr int kMinScalePairs = 8;

}  // namespace

void LoopDetector::AddQueryScale(const KeyframeRecord& query, const KeyframeRecord& map,
                                 const std::vector<DescriptorMatch>& matches,
                                 VerificationResult* v) const {
  const Sim3d query_from_match = v->match_from_query.Inverse();
  std::vector<double> log_ratio;
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> observed;
  for (int i : v->inlier_matches) {
    const DescriptorMatch& m = matches[static_cast<size_t>(i)];
    const CompactKeypoint& k = map.keypoints[static_cast<size_t>(m.train)];
    const CompactKeypoint& kq = query.keypoints[static_cast<size_t>(m.query)];
    const float zm = map.depths[static_cast<size_t>(m.train)];
    const float zq = query.depths[static_cast<size_t>(m.query)];
    points.push_back(double(zm) * Eigen::Vector3d(k.x, k.y, 1.0));
    observed.emplace_back(kq.x, kq.y);
    if (zq <= 0 || zm <= 0) continue;
    const double z = (query_from_match * points.back()).z();
    if (z > 0) log_ratio.push_back(std::log(z / zq));
  }
  if (static_cast<int>(log_ratio.size()) < kMinScalePairs) return;
  std::vector<double> sorted = log_ratio;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median = sorted[sorted.size() / 2];
  // Robust spread: 1.4826 x the median absolute deviation, floored (a few identical ratios).
  std::vector<double> dev;
  for (double r : log_ratio) dev.push_back(std::abs(r - median));
  std::nth_element(dev.begin(), dev.begin() + dev.size() / 2, dev.end());
  const double sigma = std::max(1.4826 * dev[dev.size() / 2], 1e-3);
  v->match_from_query.scale = std::exp(median);
  // The PnP information again at the scaled pose (its translation columns scale with s).
  const float focal = std::max(1.0f, 0.5f * (query.focal_px + map.focal_px));
  v->information = PnpInformationPointsInMatch(points, observed, v->match_from_query,
                                               verify_.InformationOptions(focal));
  v->information(6, 6) += static_cast<double>(log_ratio.size()) / (sigma * sigma);
  v->pose_kind = RelativePoseKind::kSim3;
}

VerificationResult LoopDetector::VerifyAgainstLocalMap(const KeyframeRecord& query,
                                                       size_t match_index, int* map_points) const {
  const Options::LocalMapOptions& lm = options_.local_map;
  const KeyframeRecord& match = Stored(match_index);
  // Only keyframes well before the query: the map must not contain the query's own stretch.
  const size_t query_index = index_of_.at(query.id);
  const size_t exclude = static_cast<size_t>(std::max(0, options_.search.exclude_recent));
  const size_t end = query_index > exclude ? query_index - exclude : 0;
  auto usable = [&](int64_t i) {
    return i >= 0 && static_cast<size_t>(i) < end && records_[static_cast<size_t>(i)].has_pose();
  };
  // The map, in the match camera's frame: every window keyframe's triangulated keypoints as
  // points (bearing + depth) of one virtual record, with their own descriptors.
  KeyframeRecord map;
  map.id = match.id;
  map.has_pose = true;
  map.world_from_cam = match.world_from_cam;
  map.focal_px = match.focal_px;
  std::vector<DescriptorMatch> matches;
  std::vector<int> best_distance(query.size(), std::numeric_limits<int>::max());
  std::vector<int> query_match(query.size(), -1);  // index into `matches`
  const Sim3d match_from_world = match.world_from_cam.Inverse();
  const int64_t mi = static_cast<int64_t>(match_index);
  for (int64_t w = mi - lm.window; w <= mi + lm.window; ++w) {
    if (!usable(w)) continue;
    const KeyframeRecord& kf = Stored(static_cast<size_t>(w));
    std::vector<const KeyframeRecord*> neighbours;
    for (int64_t k = 1; k <= lm.neighbours; ++k) {
      if (usable(w + k)) neighbours.push_back(&Stored(static_cast<size_t>(w + k)));
      if (usable(w - k)) neighbours.push_back(&Stored(static_cast<size_t>(w - k)));
    }
    const TriangulationResult tri = TriangulateFromNeighbours(kf, neighbours, lm.triangulation);
    if (tri.triangulated == 0) continue;
    const Sim3d match_from_kf = match_from_world * kf.world_from_cam;
    std::vector<int> map_index(kf.size(), -1);
    for (size_t j = 0; j < kf.size(); ++j) {
      if (tri.depths[j] <= 0) continue;
      const Eigen::Vector3d p =
          match_from_kf *
          (double(tri.depths[j]) * Eigen::Vector3d(kf.keypoints[j].x, kf.keypoints[j].y, 1.0));
      if (p.z() <= 0) continue;
      CompactKeypoint c = kf.keypoints[j];
      c.x = static_cast<float>(p.x() / p.z());
      c.y = static_cast<float>(p.y() / p.z());
      map_index[j] = static_cast<int>(map.keypoints.size());
      map.keypoints.push_back(c);
      map.descriptors.push_back(kf.descriptors[j]);
      map.depths.push_back(static_cast<float>(p.z()));
    }
    // Matched per keyframe (the ratio test within one keyframe; the same point seen from two map
    // keyframes would fail it across them), then the closest descriptor per query keypoint.
    for (const DescriptorMatch& m : MatchQuery(query, kf.descriptors)) {
      if (map_index[m.train] < 0 || m.distance >= best_distance[m.query]) continue;
      best_distance[m.query] = m.distance;
      const DescriptorMatch dm{m.query, map_index[m.train], m.distance};
      if (query_match[m.query] < 0) {
        query_match[m.query] = static_cast<int>(matches.size());
        matches.push_back(dm);
      } else {
        matches[static_cast<size_t>(query_match[m.query])] = dm;
      }
    }
  }
  *map_points = static_cast<int>(map.size());
  VerificationResult none;
  none.method = VerificationMethod::kPnP;
  if (static_cast<int>(matches.size()) < verify_.min_inliers) return none;
  std::sort(matches.begin(), matches.end(),
            [](const DescriptorMatch& a, const DescriptorMatch& b) { return a.query < b.query; });
  // The query's own points, triangulated with the keyframes before it (in the query's local
  // scale): with both sides in 3D the relative pose is a Sim(3), whose scale is the scale drift
  // between the two places; VerifyPair falls back to PnP (the map against the query's 2D) when
  // the 3D-3D model does not verify.
  KeyframeRecord q = query;
  if (query.has_pose) {
    std::vector<const KeyframeRecord*> before;
    for (int64_t k = 1; k <= lm.neighbours; ++k) {
      const int64_t i = static_cast<int64_t>(query_index) - k;
      if (i >= 0 && records_[static_cast<size_t>(i)].has_pose())
        before.push_back(&Stored(static_cast<size_t>(i)));
    }
    const TriangulationResult tri = TriangulateFromNeighbours(query, before, lm.triangulation);
    if (tri.triangulated > 0) q.depths = tri.depths;
  }
  VerificationResult v = VerifyPair(q, map, matches, verify_);
  if (v.pose_kind == RelativePoseKind::kSE3Metric && q.has_depths())
    AddQueryScale(q, map, matches, &v);
  return v.pose_kind == RelativePoseKind::kSE3Metric || v.pose_kind == RelativePoseKind::kSim3
             ? v
             : none;
}

bool LoopDetector::ContinuesRecentView(const KeyframeRecord& query, size_t query_index,
                                       size_t match_index, int inliers,
                                       const VerifyOptions& verify) const {
  const size_t span = query_index - match_index;
  for (const size_t k : {match_index + span / 2, match_index + 3 * span / 4}) {
    if (k <= match_index || k >= query_index) continue;
    const std::vector<DescriptorMatch> matches = MatchQuery(query, records_[k]);
    if (static_cast<int>(matches.size()) < inliers) continue;  // cannot reach `inliers`
    const VerificationResult v = VerifyPair(query, Stored(k), matches, verify);
    if (v.success && v.inliers >= inliers) return true;
  }
  return false;
}

size_t LoopDetector::OverlapStart(const KeyframeRecord& query, size_t exclude_end) const {
  const double floor = options_.overlap_match_factor * options_.EffectiveMinMatches();
  double threshold = floor;
  size_t start = exclude_end;  // keyframes [start, query) are excluded
  int misses = 0;
  int walked = 0;
  for (size_t k = exclude_end; k-- > 0 && walked < options_.overlap_max_walk; ++walked) {
    const double matches = static_cast<double>(MatchQuery(query, records_[k]).size());
    if (walked == 0) threshold = std::max(floor, options_.overlap_relative * matches);
    if (matches >= threshold) {
      start = k;
      misses = 0;
    } else if (++misses >= options_.overlap_gap) {
      break;
    }
  }
  return start;
}

bool LoopDetector::Agrees(size_t query_index, size_t match_index) const {
  if (!last_support_ || last_support_->first >= query_index) return false;
  const size_t dq = query_index - last_support_->first;
  const size_t dm = match_index > last_support_->second ? match_index - last_support_->second
                                                        : last_support_->second - match_index;
  const size_t window = static_cast<size_t>(options_.agreement_window);
  return dq <= window && dm <= window + dq;
}

LoopDetector::GraphPrior LoopDetector::PriorAlongLoopGraph(size_t query_index,
                                                           size_t match_index) const {
  auto dist = [](size_t x, size_t y) { return x > y ? x - y : y - x; };
  auto rotation = [&](size_t i) { return records_[i].world_from_cam().rotation; };
  // a_from_b of the raw rotations.
  auto raw = [&](size_t a, size_t b) { return rotation(a).conjugate() * rotation(b); };
  GraphPrior best;
  best.keyframes = dist(query_index, match_index);
  best.match_from_query = raw(match_index, query_index);
  for (const AcceptedLoop& l : accepted_loops_) {
    if (!records_[l.query].has_pose() || !records_[l.match].has_pose()) continue;
    // query ~ loop query, match ~ loop match; or the loop used the other way round.
    const size_t forward = dist(query_index, l.query) + dist(l.match, match_index);
    const size_t backward = dist(query_index, l.match) + dist(l.query, match_index);
    if (forward < best.keyframes) {
      best.keyframes = forward;
      best.match_from_query =
          raw(match_index, l.match) * l.match_from_query * raw(l.query, query_index);
    }
    if (backward < best.keyframes) {
      best.keyframes = backward;
      best.match_from_query =
          raw(match_index, l.query) * l.match_from_query.conjugate() * raw(l.match, query_index);
    }
  }
  return best;
}

std::vector<int64_t> LoopDetector::RetrieveByVotes(const KeyframeRecord& query, size_t query_index,
                                                   const std::vector<int64_t>& allowed) {
  // Keyframes the search area may return (index < query index - exclude_recent) enter the index;
  // the recent ones stay out, else they would absorb every query descriptor's nearest neighbours.
  const size_t exclude = static_cast<size_t>(std::max(0, options_.search.exclude_recent));
  const size_t eligible = query_index > exclude ? query_index - exclude : 0;
  for (; ann_indexed_ < eligible; ++ann_indexed_)
    ann_->Add(static_cast<int64_t>(ann_indexed_), records_[ann_indexed_].descriptors());
  if (allowed.empty()) return {};
  std::vector<int64_t> allowed_sorted = allowed;
  std::sort(allowed_sorted.begin(), allowed_sorted.end());
  std::vector<int64_t> out;
  for (const KeyframeVotes& v : ann_->Query(query.descriptors)) {
    const int64_t id = records_[static_cast<size_t>(v.keyframe_id)].id();
    if (!std::binary_search(allowed_sorted.begin(), allowed_sorted.end(), id)) continue;
    out.push_back(id);
    if (static_cast<int>(out.size()) >= options_.ann.max_candidates) break;
  }
  return out;
}

LoopResult LoopDetector::MatchAgainst(const KeyframeRecord& query,
                                      const std::vector<int64_t>& candidate_ids) {
  Timer total;
  unpacked_.clear();
  LoopResult result;
  result.query_id = query.id;
  SearchAndVerify(query, candidate_ids, &result);
  result.timings.total_ms = total.ElapsedMs();
  return result;
}

LoopStatus LoopDetector::RotationGate(const KeyframeRecord& query, const KeyframeRecord& match,
                                      size_t query_index, size_t match_index,
                                      const std::vector<DescriptorMatch>& matches,
                                      const VerificationResult& v, bool from_local_map,
                                      LoopResult* trial) const {
  if (!query.has_pose || !match.has_pose || v.pose_kind == RelativePoseKind::kNone)
    return LoopStatus::kDetected;
  // A pose from 3D points (PnP / Sim(3) against the local map or depths) has no two-view
  // ambiguity: the gate may be as wide as the odometry between the two places allows. A
  // two-view pose can be the wrong one of two supported solutions (castle 29 -> 02: 27 deg
  // off), so it keeps the narrow rate (docs/DETECTOR.md, "Rotation gate").
  const bool from_3d =
      v.pose_kind == RelativePoseKind::kSE3Metric || v.pose_kind == RelativePoseKind::kSim3;
  const GraphPrior graph_prior = PriorAlongLoopGraph(query_index, match_index);
  const double tolerance_deg = std::min(
      options_.consistency_max_deg,
      options_.consistency_base_deg + (from_3d ? options_.consistency_per_keyframe_deg
                                               : options_.two_view_consistency_per_keyframe_deg) *
                                          static_cast<double>(graph_prior.keyframes));
  auto error_deg = [&](const Sim3d& pose) {
    return RotationAngle(graph_prior.match_from_query, pose.rotation) * 180.0 / M_PI;
  };
  trial->rotation_error_vs_prior_deg = error_deg(v.match_from_query);
  if (!options_.check_consistency || trial->rotation_error_vs_prior_deg <= tolerance_deg)
    return LoopStatus::kDetected;
  if (!options_.planar_alternatives || from_local_map) return LoopStatus::kRejectedByConsistency;
  for (const VerificationResult& alt : PlanarAlternatives(query, match, matches, v, verify_)) {
    const double err = error_deg(alt.match_from_query);
    if (err > options_.planar_alternative_tolerance * tolerance_deg) continue;
    trial->rotation_error_vs_prior_deg = err;
    trial->inliers = alt.inliers;
    trial->score = static_cast<double>(alt.inliers) / options_.features.max_features;
    trial->match_from_query = alt.match_from_query;
    trial->information = alt.information;
    trial->planar_alternative = true;
    return LoopStatus::kDetected;
  }
  return LoopStatus::kRejectedByConsistency;
}

LoopStatus LoopDetector::TryCandidate(const KeyframeRecord& query, size_t query_index,
                                      size_t match_index,
                                      const std::vector<DescriptorMatch>& matches,
                                      const VerifyOptions& verify, bool weak_enabled,
                                      std::optional<size_t>* support, LoopResult* trial) {
  const KeyframeRecord& match = Stored(match_index);
  VerificationResult v = VerifyPair(query, match, matches, verify);
  int map_points = 0, map_inliers = 0;
  if (v.success && v.pose_kind == RelativePoseKind::kSE3UnitTranslation &&
      options_.local_map.enabled && match.has_pose) {
    VerificationResult m = VerifyAgainstLocalMap(query, match_index, &map_points);
    if (m.success) {
      map_inliers = m.inliers;
      v.method = m.method;
      v.pose_kind = m.pose_kind;
      v.match_from_query = m.match_from_query;
      v.information = m.information;
    }
  }
  trial->local_map_points = map_inliers > 0 ? map_points : 0;
  trial->local_map_inliers = map_inliers;
  trial->match_id = match.id;
  trial->matches = static_cast<int>(matches.size());
  trial->inliers = v.inliers;
  trial->score = static_cast<double>(v.inliers) / options_.features.max_features;
  trial->method = v.method;
  trial->pose_kind = v.pose_kind;
  trial->match_from_query = v.match_from_query;
  trial->information = v.information;
  if (!v.success) return LoopStatus::kTooFewInliers;
  LoopStatus status =
      RotationGate(query, match, query_index, match_index, matches, v, map_inliers > 0, trial);
  if (status == LoopStatus::kDetected && weak_enabled) {
    // Passed the gate: support for the next queries (committed after this query's loop).
    if (!*support) *support = match_index;
    const bool is_weak = trial->inliers < verify_.min_inliers && map_inliers == 0;
    if (is_weak && !Agrees(query_index, match_index)) status = LoopStatus::kRejectedByTemporal;
  }
  if (status == LoopStatus::kDetected && options_.continuity_check && !query.has_pose &&
      ContinuesRecentView(query, query_index, match_index, trial->inliers, verify)) {
    status = LoopStatus::kRejectedByTemporal;
  }
  if (status == LoopStatus::kDetected && options_.temporal_check) {
    const bool confirmed =
        last_verified_ && std::llabs(static_cast<int64_t>(last_verified_->second) -
                                     static_cast<int64_t>(match_index)) <= options_.temporal_window;
    last_verified_ = std::make_pair(query_index, match_index);
    if (!confirmed) status = LoopStatus::kRejectedByTemporal;
  }
  return status;
}

void LoopDetector::SearchAndVerify(const KeyframeRecord& query, std::vector<int64_t> candidates,
                                   LoopResult* result) {
  result->candidates = static_cast<int>(candidates.size());
  if (candidates.empty()) {
    result->status = LoopStatus::kNoCandidates;
    return;
  }
  // 4. Hamming matching against every candidate; rank by match count, then score, then id.
  Timer stage;
  const bool weak_enabled = options_.weak_pairs && options_.weak_min_inliers < verify_.min_inliers;
  VerifyOptions verify = verify_;
  if (weak_enabled) verify.min_inliers = options_.weak_min_inliers;
  std::vector<size_t> record_index(candidates.size());
  for (size_t e = 0; e < candidates.size(); ++e) record_index[e] = index_of_.at(candidates[e]);
  const CandidateRanking ranking = RankCandidates(
      candidates.size(),
      [&](size_t e) -> const PackedKeyframe& { return records_[record_index[e]]; },
      [&](size_t e) { return record_index[e]; },
      [&](const PackedKeyframe& r) { return MatchQuery(query, r); },
      weak_enabled ? std::min(options_.EffectiveMinMatches(), options_.weak_min_inliers)
                   : options_.EffectiveMinMatches(),
      options_.match.max_distance);
  const auto& ranked = ranking.ranked;
  result->timings.match_ms = stage.ElapsedMs();
  if (ranked.empty()) {
    result->status = LoopStatus::kTooFewMatches;
    result->match_id = ranking.best_count > 0 ? candidates[ranking.best_entry] : -1;
    result->matches = ranking.best_count;
    return;
  }

  // 5. Geometric verification of the best few, then the pose-prior consistency check.
  stage.Restart();
  const size_t query_index = index_of_.at(query.id);
  LoopStatus status = LoopStatus::kTooFewInliers;
  bool have_best = false;
  const int n_verify = std::min<int>(options_.max_verify, static_cast<int>(ranked.size()));
  std::optional<size_t> support;  // match index of this query's first gate-passing pair
  // Keep the most informative outcome: detected > rejected > too few inliers (best inliers).
  auto rank = [](LoopStatus s) {
    return s == LoopStatus::kDetected                                                          ? 3
           : (s == LoopStatus::kRejectedByConsistency || s == LoopStatus::kRejectedByTemporal) ? 2
                                                                                               : 1;
  };
  for (int r = 0; r < n_verify; ++r) {
    const auto& cand = ranked[r];
    LoopResult trial = *result;
    const LoopStatus trial_status =
        TryCandidate(query, query_index, record_index[cand.entry], cand.matches, verify,
                     weak_enabled, &support, &trial);
    if (!have_best || rank(trial_status) > rank(status) ||
        (rank(trial_status) == rank(status) && trial.inliers > result->inliers)) {
      const StageTimings keep = result->timings;
      *result = trial;
      result->timings = keep;
      status = trial_status;
      have_best = true;
    }
    if (status == LoopStatus::kDetected) break;
  }
  if (support) last_support_ = std::make_pair(query_index, *support);
  result->status = status;
  result->timings.verify_ms = stage.ElapsedMs();
  if (status == LoopStatus::kDetected) {
    accepted_loops_.push_back(
        {query_index, index_of_.at(result->match_id), result->match_from_query.rotation});
    search_.OnLoopAccepted(query.id, result->match_id);
  }
}

}  // namespace sparseloop
