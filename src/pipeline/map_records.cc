#include "sparseloop/pipeline/map_records.h"

#include <algorithm>
#include <cstring>
#include <map>

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"

namespace sparseloop {

StoredKeyframe ToStoredKeyframe(const KeyframeRecord& r, int64_t session) {
  StoredKeyframe s;
  s.session = session;
  s.id = r.id;
  s.timestamp = r.timestamp;
  s.has_pose = r.has_pose;
  if (r.has_pose) s.raw_world_from_cam = r.world_from_cam;
  s.focal_px = r.focal_px;
  s.num_features = static_cast<int>(r.size());
  s.descriptors.resize(r.size() * sizeof(Descriptor));
  if (!r.descriptors.empty())
    std::memcpy(s.descriptors.data(), r.descriptors.data(), r.size() * sizeof(Descriptor));
  s.keypoints.reserve(r.keypoints.size() * 2);
  for (const auto& k : r.keypoints) {
    s.keypoints.push_back(k.x);
    s.keypoints.push_back(k.y);
  }
  s.depths = r.depths;
  return s;
}

KeyframeRecord FromStoredKeyframe(const StoredKeyframe& s, float fallback_focal_px) {
  static_assert(sizeof(Descriptor) == 32, "ORB descriptors are 32 bytes");
  const size_t n = static_cast<size_t>(std::max(s.num_features, 0));
  SL_CHECK_MSG(s.num_features >= 0 && s.descriptors.size() == n * 32 &&
                   s.keypoints.size() == n * 2 && (s.depths.empty() || s.depths.size() == n),
               "stored keyframe (session {}, id {}): sizes do not match {} features", s.session,
               s.id, s.num_features);
  KeyframeRecord r;
  r.id = s.id;
  r.timestamp = s.timestamp;
  r.has_pose = s.has_pose;
  if (s.has_pose) r.world_from_cam = s.raw_world_from_cam;
  r.focal_px = s.focal_px > 0 ? s.focal_px : fallback_focal_px;
  SL_CHECK_MSG(r.focal_px > 0,
               "stored keyframe (session {}, id {}) has no focal length and the fallback is {}",
               s.session, s.id, fallback_focal_px);
  r.descriptors.resize(n);
  if (n > 0) std::memcpy(r.descriptors.data(), s.descriptors.data(), n * 32);
  r.keypoints.resize(n);
  for (size_t i = 0; i < n; ++i) {
    r.keypoints[i].x = s.keypoints[2 * i];
    r.keypoints[i].y = s.keypoints[2 * i + 1];
  }
  r.depths = s.depths;
  return r;
}

namespace {

// Reads each earlier session into `sink` (LoopDetector or LoopClosing: AddPriorKeyframes).
template <typename Sink>
size_t LoadSessions(const MapDatabase& map, float fallback_focal_px, int64_t skip_session,
                    Sink* sink) {
  SL_CHECK_MSG(sink != nullptr, "LoadPriorSessions needs a detector or a loop closer");
  size_t loaded = 0;
  for (int64_t session : map.Sessions()) {
    if (session == skip_session) continue;
    const std::vector<StoredKeyframe> stored = map.LoadKeyframes(session);
    if (stored.empty()) continue;
    std::vector<KeyframeRecord> records;
    records.reserve(stored.size());
    for (const auto& s : stored) records.push_back(FromStoredKeyframe(s, fallback_focal_px));
    loaded += records.size();
    // A session stored at another K is matched with the floors of its own K (LoopDetector::PairK).
    sink->AddPriorKeyframes(session, std::move(records));
    Logger().info("{}: loaded session {} ({} keyframes) for multi-session detection",
                  map.path().string(), session, stored.size());
  }
  return loaded;
}

}  // namespace

size_t LoadPriorSessions(const MapDatabase& map, float fallback_focal_px, LoopDetector* detector,
                         int64_t skip_session) {
  return LoadSessions(map, fallback_focal_px, skip_session, detector);
}

size_t LoadPriorSessions(const MapDatabase& map, float fallback_focal_px, LoopClosing* closing,
                         int64_t skip_session) {
  return LoadSessions(map, fallback_focal_px, skip_session, closing);
}

}  // namespace sparseloop
