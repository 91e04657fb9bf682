// Earlier map sessions (PriorSessions, LoopDetector::AddPriorKeyframes), relocalisation without a
// pose, and the appearance-only matching against a pool of records that both use.
#include "loop_detector_impl.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/timer.h"

#include "loop/candidate_ranking.h"

namespace sparseloop {

void PriorSessions::Add(int64_t session, std::vector<KeyframeRecord> records) {
  SL_CHECK_MSG(session > 0, "prior session id must be > 0 (0 is the current session), got {}",
               session);
  SL_CHECK_MSG(!index_.count(session), "prior session {} was already added", session);
  std::unordered_map<int64_t, size_t> index;
  for (size_t i = 0; i < records.size(); ++i) {
    const KeyframeRecord& r = records[i];
    SL_CHECK_MSG(index.emplace(r.id, records_.size() + i).second,
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
  size_t most = 0;
  for (const KeyframeRecord& r : records) most = std::max(most, r.size());
  k_[session] = static_cast<int>(std::max<size_t>(most, 1));
  std::vector<PackedKeyframe> packed;
  packed.reserve(records.size());
  for (const auto& r : records) packed.push_back(PackRecord(r));
  index_[session] = std::move(index);
  records_.reserve(records_.size() + packed.size());
  for (auto& r : packed) {
    records_.push_back(std::move(r));
    session_.push_back(session);
  }
}

KeyframeRecord PriorSessions::Record(int64_t session, int64_t id) const {
  auto s = index_.find(session);
  SL_CHECK_MSG(s != index_.end(), "unknown prior session {}", session);
  auto it = s->second.find(id);
  SL_CHECK_MSG(it != s->second.end(), "unknown keyframe id {} in prior session {}", id, session);
  return UnpackRecord(records_[it->second]);
}

void LoopDetector::Impl::AddPriorKeyframes(int64_t session, std::vector<KeyframeRecord> records) {
  ClearCallCaches();  // the prior records may move
  priors_.Add(session, std::move(records));
}

KeyframeRecord LoopDetector::Impl::prior_record(int64_t session, int64_t id) const {
  return priors_.Record(session, id);
}

LoopResult LoopDetector::Impl::Relocalize(const KeyframeInput& input) {
  Timer total;
  ValidateImageInput(input);
  LoopResult result;
  result.query_id = input.id;
  result.relocalization = true;
  ClearCallCaches();
  Timer stage;
  KeyframeRecord rec = ExtractRecord(input);
  result.timings.extract_ms = stage.ElapsedMs();
  if (std::min<size_t>(rec.size(), options_.features.max_features) < 5) {
    result.status = LoopStatus::kNoFeatures;
  } else {
    std::vector<PoolEntry> pool;
    for (const auto& r : records_)
      if (r.has_pose()) pool.push_back({0, &r});
    for (size_t i = 0; i < priors_.size(); ++i)
      if (priors_.record(i).has_pose()) pool.push_back({priors_.session(i), &priors_.record(i)});
    MatchAndVerifyPool(rec, pool, &result);
  }
  result.timings.total_ms = total.ElapsedMs();
  return result;
}

int LoopDetector::Impl::PairK(int64_t session) const {
  const int k = options_.features.max_features;
  if (session == 0) return k;
  return priors_.K(session);
}

void LoopDetector::Impl::MatchAndVerifyPool(const KeyframeRecord& query,
                                            const std::vector<PoolEntry>& pool,
                                            LoopResult* result) const {
  result->candidates = static_cast<int>(pool.size());
  if (pool.empty()) {
    result->status = LoopStatus::kNoCandidates;
    return;
  }
  Timer stage;
  // Each pair's floors are those of the K its record was stored with (PairK): the ranking keeps
  // what passes the lowest, each candidate is then held to its own.
  int lowest_floor = options_.EffectiveMinMatches();
  for (const auto& session_k : priors_.ks())
    lowest_floor = std::min(lowest_floor, options_.EffectiveMinMatches(session_k.second));
  const loop_internal::CandidateRanking ranking = loop_internal::RankCandidates(
      pool.size(), [&](size_t e) -> const PackedKeyframe& { return *pool[e].record; },
      [](size_t e) { return e; }, [&](const PackedKeyframe& r) { return MatchQuery(query, r); },
      lowest_floor, options_.match.max_distance);
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
    const loop_internal::RankedCandidate& cand = ranked[r];
    const PoolEntry& entry = pool[cand.entry];
    const int k = PairK(entry.session);
    if (static_cast<int>(cand.matches.size()) < options_.EffectiveMinMatches(k)) continue;
    const KeyframeRecord& match = Unpacked(*entry.record);
    VerifyOptions verify = verify_;
    verify.min_inliers = options_.EffectiveMinInliers(k);
    VerificationResult v = VerifyPair(query, match, cand.matches, verify);
    if (have_best && !v.success && v.inliers <= result->inliers) continue;
    result->match_id = match.id;
    result->match_session = entry.session;
    result->matches = static_cast<int>(cand.matches.size());
    result->inliers = v.inliers;
    result->score = static_cast<double>(v.inliers) / k;
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

}  // namespace sparseloop
