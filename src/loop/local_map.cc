// LoopDetector: verification against a local map triangulated around the match (PnP / Sim(3)),
// and the relative scale of a PnP loop from the query's depths.
#include "loop_detector_impl.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/timer.h"

namespace sparseloop {

namespace {

// PnP of the query against the match's local map fixes the query camera in match units; the
// query's own triangulated depths (query units) of the same inliers then give the relative scale
// (AddScaleFromQueryDepths; castle 29 -> 02's Sim(3) RANSAC falls short and PnP is kept). Needs
// kMinScalePairs inliers with a query depth.
constexpr int kMinScalePairs = 8;

}  // namespace

const KeyframeRecord& LoopDetector::Impl::QueryWithTriangulatedDepths(const KeyframeRecord& query,
                                                                      size_t query_index) const {
  if (query_points_ && query_points_->id == query.id && query_points_->size == query.size())
    return query_points_->record;
  query_points_ = QueryPoints{query.id, query.size(), query};
  // The query's own points, triangulated with the keyframes before it (in the query's local
  // scale, raw units at the query).
  KeyframeRecord& q = query_points_->record;
  if (!query.has_pose) return q;
  const Options::LocalMapOptions& lm = options_.local_map;
  std::vector<const KeyframeRecord*> before;
  // Only the query's recent stretch (the keyframes a search excludes): a keyframe that can be the
  // match would make the loop pose the raw relative pose it was triangulated with.
  const int64_t recent =
      std::min<int64_t>(lm.neighbours, std::max(0, options_.search.exclude_recent));
  for (int64_t k = 1; k <= recent; ++k) {
    const int64_t i = static_cast<int64_t>(query_index) - k;
    if (i >= 0 && records_[static_cast<size_t>(i)].has_pose() &&
        SameSegment(static_cast<size_t>(i), query_index))
      before.push_back(&Stored(static_cast<size_t>(i)));
  }
  const TriangulationResult tri =
      TriangulateFromNeighbours(query, before, lm.triangulation, &relative_poses_);
  if (tri.triangulated > 0) q.depths = tri.depths;
  query_points_->image_poses = tri.image_poses;
  query_points_->raw_poses = tri.raw_poses;
  return q;
}

VerificationResult LoopDetector::Impl::VerifyWithQueryPoints(
    const KeyframeRecord& query, size_t match_index, const std::vector<DescriptorMatch>& matches,
    PoseSources* sources) const {
  VerificationResult none;
  none.method = VerificationMethod::kPnP;
  const KeyframeRecord& q = QueryWithTriangulatedDepths(query, index_of_.at(query.id));
  *sources = PoseSources{query_points_->image_poses, query_points_->raw_poses};
  if (!q.has_depths()) return none;
  int usable = 0;
  for (const DescriptorMatch& m : matches) usable += q.depths[static_cast<size_t>(m.query)] > 0;
  if (usable < verify_.min_inliers) return none;
  // Only the query's points: PnP of the match's 2D keypoints against them (points in the query
  // frame, translation in the query's raw units; the relative scale stays free).
  KeyframeRecord match = Stored(match_index);
  match.depths.clear();
  VerificationResult v = VerifyPair(q, match, matches, verify_);
  return v.success && v.pose_kind == RelativePoseKind::kSE3Metric ? v : none;
}

VerificationResult LoopDetector::Impl::VerifyAgainstLocalMap(const KeyframeRecord& query,
                                                             size_t match_index, int* map_points,
                                                             PoseSources* sources) const {
  const Options::LocalMapOptions& lm = options_.local_map;
  const KeyframeRecord& match = Stored(match_index);
  // Only keyframes well before the query: the map must not contain the query's own stretch.
  const size_t query_index = index_of_.at(query.id);
  const size_t exclude = static_cast<size_t>(std::max(0, options_.search.exclude_recent));
  const size_t end = query_index > exclude ? query_index - exclude : 0;
  auto usable = [&](int64_t i) {
    return i >= 0 && static_cast<size_t>(i) < end && records_[static_cast<size_t>(i)].has_pose() &&
           SameSegment(static_cast<size_t>(i), match_index);
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
    const TriangulationResult tri =
        TriangulateFromNeighbours(kf, neighbours, lm.triangulation, &relative_poses_);
    sources->images += tri.image_poses;
    sources->raw += tri.raw_poses;
    if (tri.triangulated == 0) continue;
    // The map keyframe in the match's frame: from the images where they fix it (the raw relative
    // rotation carries the odometry's rotation drift between the two), else the raw poses.
    Sim3d match_from_kf = match_from_world * kf.world_from_cam;
    if (w != mi) {
      const std::optional<Sim3d> from_images = relative_poses_.Get(
          kf, match, MatchDescriptors(kf.descriptors, match.descriptors, lm.triangulation.match),
          match_from_kf, lm.triangulation);
      ++(from_images ? sources->images : sources->raw);
      if (from_images) match_from_kf = *from_images;
    }
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
  const KeyframeRecord& q = QueryWithTriangulatedDepths(query, query_index);
  sources->images += query_points_->image_poses;
  sources->raw += query_points_->raw_poses;
  VerifyOptions verify = verify_;
  verify.scale_from_query_depths_min = kMinScalePairs;
  const VerificationResult v = VerifyPair(q, map, matches, verify);
  return v.pose_kind == RelativePoseKind::kSE3Metric || v.pose_kind == RelativePoseKind::kSim3
             ? v
             : none;
}

}  // namespace sparseloop
