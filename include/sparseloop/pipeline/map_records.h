#pragma once
// Conversion between the detector's KeyframeRecord (features layer, OpenCV types) and the map's
// StoredKeyframe (core-only layer), and loading earlier map sessions into a LoopDetector for
// multi-session loop closure and relocalisation (docs/MULTISESSION.md).
//
// What survives the round trip: id, timestamp, has_pose + raw pose, focal_px, descriptors,
// normalised keypoint coordinates (x, y) and depths. Not stored: the ORB angle and octave
// (verification does not use them); they come back as 0.
#include <cstdint>

#include "sparseloop/features/informative_features.h"
#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/map/map_database.h"
#include "sparseloop/runtime/loop_closing.h"

namespace sparseloop {

StoredKeyframe ToStoredKeyframe(const KeyframeRecord& record, int64_t session);

// `fallback_focal_px` (> 0) replaces a stored focal of 0 (keyframes migrated from a schema-1
// map, which did not store it). Throws std::invalid_argument when both are <= 0.
KeyframeRecord FromStoredKeyframe(const StoredKeyframe& stored, float fallback_focal_px);

// Loads every session of `map` except `skip_session` (e.g. the session being written now) into
// `detector` with AddPriorKeyframes(session id, records). Returns the number of keyframes loaded.
size_t LoadPriorSessions(const MapDatabase& map, float fallback_focal_px, LoopDetector* detector,
                         int64_t skip_session = -1);
// The same into an online LoopClosing (its AddPriorKeyframes).
size_t LoadPriorSessions(const MapDatabase& map, float fallback_focal_px, LoopClosing* closing,
                         int64_t skip_session = -1);

}  // namespace sparseloop
