#pragma once
// Depths for a keyframe record that has none, triangulated against its neighbouring keyframes
// with the raw vSLAM relative poses: the local "map" a monocular loop can be verified against by
// PnP (the paper's image-to-map step), when the vSLAM hands over no depths. The raw poses are
// drifted globally but accurate between neighbours, which is all a triangulation needs.
#include <vector>

#include "sparseloop/features/informative_features.h"
#include "sparseloop/matching/descriptor_matching.h"

namespace sparseloop {

struct TriangulationOptions {
  double max_reprojection_px = 2.0;  // a point must reproject within this in both views, pixels
  double min_parallax_deg = 2.0;     // smallest angle between the two rays, degrees
  MatchOptions match;                // descriptor matching record <-> neighbour
  void Check() const;
};

struct TriangulationResult {
  // One per keypoint of the record: depth along its ray in the record's camera frame (units of
  // its raw pose, as KeyframeRecord::depths), <= 0 where no neighbour gave a valid point.
  std::vector<float> depths;
  int triangulated = 0;  // keypoints with a depth, count
};

// Every keypoint of `record` matched in a neighbour is triangulated (linear midpoint in the
// record's frame), kept when in front of both cameras, within max_reprojection_px in both and
// seen with at least min_parallax_deg; over several neighbours the largest parallax wins. Needs
// record.has_pose and each neighbour's has_pose (neighbours without one are skipped).
TriangulationResult TriangulateFromNeighbours(const KeyframeRecord& record,
                                              const std::vector<const KeyframeRecord*>& neighbours,
                                              const TriangulationOptions& options);

}  // namespace sparseloop
