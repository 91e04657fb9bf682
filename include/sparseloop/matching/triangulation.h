#pragma once
// Depths for a keyframe record that has none, triangulated against its neighbouring keyframes
// with the raw vSLAM relative poses: the local "map" a monocular loop can be verified against by
// PnP (the paper's image-to-map step), when the vSLAM hands over no depths. The raw poses drift
// globally, and a monocular odometry without an IMU also drifts in rotation between neighbours
// (a pitch or roll bias of a fraction of a degree per keyframe bends every triangulated point),
// so the relative rotation and the baseline direction come from the images where they can; the
// raw poses give the baseline length (the local scale), and the whole relative pose where the
// images cannot.
#include <cstdint>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "sparseloop/features/informative_features.h"
#include "sparseloop/matching/descriptor_matching.h"
#include "sparseloop/matching/geometric_verification.h"

namespace sparseloop {

struct TriangulationOptions {
  double max_reprojection_px = 2.0;  // a point must reproject within this in both views, pixels
  double min_parallax_deg = 2.0;     // smallest angle between the two rays, degrees
  MatchOptions match;                // descriptor matching record <-> neighbour
  // A neighbour's relative pose from the images: the essential matrix of the matches, refined from
  // the raw relative pose (RefineFromPrior), gives the rotation and the baseline direction when at
  // least this many matches agree with it and it stays within kMaxImagePoseRotationChangeDeg and
  // kMaxImagePoseDirectionChangeDeg of the raw relative pose; else the raw relative pose. 0 =
  // always the raw relative pose (an odometry whose local rotations beat two views of K features,
  // e.g. visual-inertial), count.
  int min_image_pose_inliers = 15;
  // How far the raw relative pose may be from the truth, per axis (the prior of the refinement
  // against image noise of half the 2 px inlier threshold): the rotation drift between
  // neighbouring keyframes. Smaller keeps the loosely constrained directions nearer the raw pose.
  // Degrees, (0, kMaxImagePoseRotationChangeDeg].
  double image_pose_prior_deg = 0.25;
  void Check() const;
};

// The image refinement's first inlier threshold, as an angle: wide enough for the raw relative
// pose's error (the rotation drift between neighbouring keyframes, a few degrees at most); it then
// halves down to the 2 px of the verification. Degrees.
inline constexpr double kImagePoseFirstThresholdDeg = 3.0;
// A relative rotation from the images that differs from the raw one by more than this is taken
// for a wrong model (repeated structure), not for drift: drift between neighbouring keyframes is
// a fraction of a degree per keyframe. Degrees.
inline constexpr double kMaxImagePoseRotationChangeDeg = 10.0;
// The same for the baseline direction (the raw one errs by the rotation drift, a few degrees; a
// two-view direction far from it comes from too little parallax or a wrong model). Degrees.
inline constexpr double kMaxImagePoseDirectionChangeDeg = 30.0;

// The pose of neighbour `b` relative to `a` (b_from_a: x_b = s R x_a + t) from their matches:
// rotation and translation direction from the essential matrix refined from `raw_b_from_a` (a
// RANSAC over a planar scene can pick the wrong one of two decompositions; the raw pose is near
// the right one), translation length and scale from `raw_b_from_a`. Empty when the images do not
// fix it (see min_image_pose_inliers). `inliers`, when given, receives the indices of the matches
// that agree with the returned pose.
std::optional<Sim3d> RelativePoseFromImages(const KeyframeRecord& a, const KeyframeRecord& b,
                                            const std::vector<DescriptorMatch>& matches,
                                            const Sim3d& raw_b_from_a, int min_inliers,
                                            double prior_deg, std::vector<int>* inliers = nullptr);

// The relative poses RelativePoseFromImages gave during one pass over overlapping pairs (a local
// map triangulates each keyframe with its neighbours and places each in the match's frame, so most
// pairs come up two or three times): each pair is refined once, and its reverse is the inverse.
// Keyed by the records' addresses: its owner clears it whenever those records may change.
class RelativePoseCache {
 public:
  // RelativePoseFromImages(a, b, matches, raw_b_from_a, the options' min_image_pose_inliers and
  // image_pose_prior_deg), computed on the first request for {a, b} in either order.
  std::optional<Sim3d> Get(const KeyframeRecord& a, const KeyframeRecord& b,
                           const std::vector<DescriptorMatch>& matches, const Sim3d& raw_b_from_a,
                           const TriangulationOptions& options);
  void Clear() { second_from_first_.clear(); }
  size_t size() const { return second_from_first_.size(); }  // pairs refined

 private:
  // Key (first, second) with first < second (addresses); value second_from_first.
  std::map<std::pair<uintptr_t, uintptr_t>, std::optional<Sim3d>> second_from_first_;
};

struct TriangulationResult {
  // One per keypoint of the record: depth along its ray in the record's camera frame (units of
  // its raw pose, as KeyframeRecord::depths), <= 0 where no neighbour gave a valid point.
  std::vector<float> depths;
  int triangulated = 0;  // keypoints with a depth, count
  // Neighbours whose relative pose came from the images / from the raw poses, count.
  int image_poses = 0;
  int raw_poses = 0;
};

// Every keypoint of `record` matched in a neighbour is triangulated (linear midpoint in the
// record's frame), kept when in front of both cameras, within max_reprojection_px in both and
// seen with at least min_parallax_deg; over several neighbours the largest parallax wins. The
// relative pose of each neighbour: RelativePoseFromImages (through `cache` when given), else the
// raw one. Needs record.has_pose and each neighbour's has_pose (neighbours without one, or at the
// record's position, are skipped).
TriangulationResult TriangulateFromNeighbours(const KeyframeRecord& record,
                                              const std::vector<const KeyframeRecord*>& neighbours,
                                              const TriangulationOptions& options,
                                              RelativePoseCache* cache = nullptr);

}  // namespace sparseloop
