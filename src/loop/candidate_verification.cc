// LoopDetector: candidates matched, ranked and verified; the gates a verified pair passes
// (pose-prior rotation, weak pairs, continuity) and the state they read; ANN voting.
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

bool LoopDetector::Impl::ContinuesRecentView(const KeyframeRecord& query, size_t query_index,
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

size_t LoopDetector::Impl::OverlapStart(const KeyframeRecord& query, size_t exclude_end) const {
  // Keyframes still in overlap_buffer_ are matched with the query's first overlap_features, at
  // the floors of a record of that size; older ones (or without the buffer) with their stored
  // records, at the record's floors.
  const bool buffered = OverlapBufferUsed(query);
  const std::span<const Descriptor> probe(
      query.descriptors.data(),
      std::min(query.size(), static_cast<size_t>(std::max(0, options_.overlap_features))));
  struct Count {
    double matches;
    bool from_buffer;
  };
  auto count = [&](size_t k) -> Count {
    if (buffered) {
      const auto it = std::lower_bound(overlap_buffer_.begin(), overlap_buffer_.end(), k,
                                       [](const auto& e, size_t i) { return e.first < i; });
      if (it != overlap_buffer_.end() && it->first == k)
        return {static_cast<double>(MatchDescriptors(probe, it->second, options_.match).size()),
                true};
    }
    return {static_cast<double>(MatchQuery(query, records_[k]).size()), false};
  };
  const double record_floor = options_.overlap_match_factor * options_.EffectiveMinMatches();
  const double buffer_floor = options_.overlap_match_factor * options_.min_matches;
  double threshold = record_floor;
  std::optional<bool> counted_from_buffer;  // the kind of count `threshold` is for
  size_t start = exclude_end;               // keyframes [start, query) are excluded
  int misses = 0;
  int walked = 0;
  for (size_t k = exclude_end; k-- > 0 && walked < options_.overlap_max_walk; ++walked) {
    const Count c = count(k);
    // The first keyframe walked, or the first one past the buffer: the overlap decays from its
    // count (counts of the two kinds are of different record sizes).
    if (counted_from_buffer != c.from_buffer) {
      counted_from_buffer = c.from_buffer;
      threshold = std::max(c.from_buffer ? buffer_floor : record_floor,
                           options_.overlap_relative * c.matches);
    }
    if (c.matches >= threshold) {
      start = k;
      misses = 0;
    } else if (++misses >= options_.overlap_gap) {
      break;
    }
  }
  return start;
}

bool LoopDetector::Impl::Agrees(size_t query_index, size_t match_index) const {
  if (!last_support_ || last_support_->first >= query_index) return false;
  const size_t dq = query_index - last_support_->first;
  const size_t dm = match_index > last_support_->second ? match_index - last_support_->second
                                                        : last_support_->second - match_index;
  const size_t window = static_cast<size_t>(options_.agreement_window);
  return dq <= window && dm <= window + dq;
}

LoopDetector::Impl::GraphPrior LoopDetector::Impl::PriorAlongLoopGraph(size_t query_index,
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
    // Raw odometry to the loop's ends must stay inside the query's raw pose segment.
    if (!SameSegment(l.query, query_index) || !SameSegment(l.match, query_index)) continue;
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

std::vector<int64_t> LoopDetector::Impl::RetrieveByVotes(const KeyframeRecord& query,
                                                         size_t query_index,
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

LoopResult LoopDetector::Impl::MatchAgainst(const KeyframeRecord& query,
                                            const std::vector<int64_t>& candidate_ids) {
  Timer total;
  ClearCallCaches();
  LoopResult result;
  result.query_id = query.id;
  SearchAndVerify(query, candidate_ids, &result);
  result.timings.total_ms = total.ElapsedMs();
  return result;
}

LoopStatus LoopDetector::Impl::RotationGate(const KeyframeRecord& query,
                                            const KeyframeRecord& match, size_t query_index,
                                            size_t match_index,
                                            const std::vector<DescriptorMatch>& matches,
                                            const VerificationResult& v, bool from_local_map,
                                            LoopResult* trial) const {
  // No prior across a raw pose reset either (MatchAgainst may be given any stored keyframe).
  if (!query.has_pose || !match.has_pose || v.pose_kind == RelativePoseKind::kNone ||
      !SameSegment(query_index, match_index))
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

bool LoopDetector::Impl::TooFarForARevisit(const KeyframeRecord& query, const KeyframeRecord& match,
                                           size_t query_index, size_t match_index,
                                           const LoopResult& trial) const {
  // Only a pose from 3D points has a metric translation (raw units of the match's segment).
  const bool metric =
      trial.pose_kind == RelativePoseKind::kSE3Metric || trial.pose_kind == RelativePoseKind::kSim3;
  if (options_.max_loop_distance_steps <= 0 || !metric || !query.has_pose || !match.has_pose ||
      !SameSegment(query_index, match_index) || query_index < 10)
    return false;
  return trial.match_from_query.translation.norm() >
         options_.max_loop_distance_steps * LocalStep(match_index, query_index);
}

double LoopDetector::Impl::LocalStep(size_t match_index, size_t query_index) const {
  // The translation is in the match's raw units (its depths or its neighbours' triangulation),
  // and a monocular trajectory's scale drifts: street00 at --drift 4 moves 1.05 raw units per
  // keyframe around keyframe 207 and 4.7 on average over the run. So the step is measured around
  // the match: posed keyframes of its segment within loop_distance_window of it, stored before
  // the query; the mean step of the whole path before the query when there are none.
  const size_t w = static_cast<size_t>(options_.loop_distance_window);
  auto usable = [&](size_t i) {
    return records_[i].has_pose() && SameSegment(i, match_index) && i < query_index;
  };
  size_t lo = match_index, hi = match_index;
  for (size_t i = match_index - std::min(match_index, w); i < match_index; ++i)
    if (usable(i)) {
      lo = i;
      break;
    }
  for (size_t i = std::min(match_index + w, query_index - 1); i > match_index; --i)
    if (usable(i)) {
      hi = i;
      break;
    }
  if (w > 0 && hi > lo && path_length_[hi] > path_length_[lo])
    return (path_length_[hi] - path_length_[lo]) / static_cast<double>(hi - lo);
  return path_length_[query_index] / static_cast<double>(query_index);
}

LoopStatus LoopDetector::Impl::TryCandidate(const KeyframeRecord& query, size_t query_index,
                                            size_t match_index,
                                            const std::vector<DescriptorMatch>& matches,
                                            const VerifyOptions& verify, bool weak_enabled,
                                            std::optional<size_t>* support, LoopResult* trial) {
  const KeyframeRecord& match = Stored(match_index);
  VerificationResult v = VerifyPair(query, match, matches, verify);
  int map_points = 0, map_inliers = 0;
  PoseSources sources;
  if (v.success && v.pose_kind == RelativePoseKind::kSE3UnitTranslation &&
      options_.local_map.enabled && match.has_pose) {
    VerificationResult m = VerifyAgainstLocalMap(query, match_index, &map_points, &sources);
    if (!m.success && options_.local_map.query_points)
      m = VerifyWithQueryPoints(query, match_index, matches, &sources);
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
  trial->local_poses_from_images = map_inliers > 0 ? sources.images : 0;
  trial->local_poses_raw = map_inliers > 0 ? sources.raw : 0;
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
  if (status == LoopStatus::kDetected &&
      TooFarForARevisit(query, match, query_index, match_index, *trial))
    status = LoopStatus::kRejectedByConsistency;
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
  return status;
}

namespace {
// How many of the ranked candidates to verify: max_verify, then the close scores.
int VerifyCount(const LoopDetectorOptions& o,
                const std::vector<loop_internal::RankedCandidate>& ranked) {
  const int available = static_cast<int>(ranked.size());
  int n = std::min(o.max_verify, available);
  // Not in the small-K regime (the floors lowered below min_matches): there the match counts
  // are small integers, most candidates are "close", and verifying up to max_verify_close of
  // them let two false weak pairs through on aerial_circuit (K = 15 preset: corrected ATE 4.0 ->
  // 22 m).
  const bool small_k = o.EffectiveMinMatches() < o.min_matches;
  if (o.verify_close_fraction <= 0 || n == 0 || small_k) return n;
  // The next candidates while their match count is near the max_verify-th's.
  const double floor = o.verify_close_fraction * static_cast<double>(ranked[n - 1].matches.size());
  const int cap = std::min(std::max(o.max_verify_close, n), available);
  while (n < cap && static_cast<double>(ranked[n].matches.size()) >= floor) ++n;
  return n;
}
}  // namespace

void LoopDetector::Impl::SearchAndVerify(const KeyframeRecord& query,
                                         std::vector<int64_t> candidates, LoopResult* result,
                                         bool weak_pairs) {
  result->candidates = static_cast<int>(candidates.size());
  if (candidates.empty()) {
    result->status = LoopStatus::kNoCandidates;
    return;
  }
  // 4. Hamming matching against every candidate; rank by match count, then score, then id.
  Timer stage;
  const bool weak_enabled =
      weak_pairs && options_.weak_pairs && options_.weak_min_inliers < verify_.min_inliers;
  VerifyOptions verify = verify_;
  if (weak_enabled) verify.min_inliers = options_.weak_min_inliers;
  std::vector<size_t> record_index(candidates.size());
  for (size_t e = 0; e < candidates.size(); ++e) record_index[e] = index_of_.at(candidates[e]);
  const loop_internal::CandidateRanking ranking = loop_internal::RankCandidates(
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
  const int n_verify = VerifyCount(options_, ranked);
  std::optional<size_t> support;  // match index of this query's first gate-passing pair
  // Keep the most informative outcome: detected > rejected > too few inliers (best inliers).
  auto rank = [](LoopStatus s) {
    return s == LoopStatus::kDetected                                                          ? 3
           : (s == LoopStatus::kRejectedByConsistency || s == LoopStatus::kRejectedByTemporal) ? 2
                                                                                               : 1;
  };
  std::vector<int64_t> verified;
  for (int r = 0; r < n_verify; ++r) {
    const auto& cand = ranked[r];
    verified.push_back(candidates[cand.entry]);
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
    // With a pose the first loop is kept (the search area and the gate already chose the
    // place); without one the ranking by matches is the only prior, so every candidate to verify
    // is verified and the loop is the one with the most inliers (Options::best_of_verified).
    if (status == LoopStatus::kDetected && (query.has_pose || !options_.best_of_verified)) break;
  }
  if (support) last_support_ = std::make_pair(query_index, *support);
  result->verified_in_area.insert(result->verified_in_area.end(), verified.begin(), verified.end());
  result->status = status;
  result->timings.verify_ms = stage.ElapsedMs();
  if (status == LoopStatus::kDetected) {
    const size_t match_index = index_of_.at(result->match_id);
    // A weak pair (below the inlier floor, accepted by the agreement of its neighbour) is a loop
    // but no anchor: its pose rests on 6-7 inliers and can be far off (aerial_figure8, K = 20:
    // 92 -> 3 with 6 PnP inliers, 36.9 deg off, put the rotation prior of the next 15 true
    // revisits 36 deg off, all rejected). Only a loop at the floor (or verified against the local
    // map) anchors the rotation prior and the search area.
    const bool anchor = result->inliers >= verify_.min_inliers || result->local_map_inliers > 0;
    if (!SameSegment(query_index, match_index)) {
      result->source = CandidateSource::kEarlierSegment;  // before a raw pose reset: relocalisation
      result->relocalization = true;
    } else if (anchor) {
      accepted_loops_.push_back({query_index, match_index, result->match_from_query.rotation});
      // The loop's rotation against the raw one: query-pass raw directions into the match
      // pass's (the uncertainty area predicts the path since the loop in the match's frame).
      const PackedKeyframe& match = records_[match_index];
      Eigen::Matrix3d correction = Eigen::Matrix3d::Identity();
      if (query.has_pose && match.has_pose() && result->pose_kind != RelativePoseKind::kNone) {
        correction = (match.world_from_cam().rotation * result->match_from_query.rotation *
                      query.world_from_cam.rotation.conjugate())
                         .toRotationMatrix();
        // Only a Sim(3) from both sides' depths knows the scale between the two passes' raw
        // units (PnP puts the query in the match's units, not its own path).
        if (result->pose_kind == RelativePoseKind::kSim3) {
          correction *= match.world_from_cam().scale * result->match_from_query.scale /
                        query.world_from_cam.scale;
        }
      }
      search_.OnLoopAccepted(query.id, result->match_id, correction);
    }
  }
}

}  // namespace sparseloop
