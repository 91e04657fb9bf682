#pragma once
// Informative features (paper, Algorithm 1 lines 2-3): ORB extracted only inside the area the
// vSLAM maps (its mapped pixels or, when none are given, a semi-dense high-gradient selection as
// LSD-SLAM / DSO compute it), of which at most K ranked features are kept per keyframe.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "sparseloop/core/camera.h"
#include "sparseloop/core/packed_keyframe.h"
#include "sparseloop/core/sim3.h"

namespace sparseloop {

// How the K kept features are chosen among the ORB detections.
enum class FeatureRanking {
  kPopcount,      // paper's literal "element sum" of the BRIEF descriptor (number of set bits)
  kResponse,      // ORB (Harris) detector response, strongest first
  kGridResponse,  // strongest response per cell of an image grid, round robin over cells
};
const char* ToString(FeatureRanking ranking);
// "popcount" | "response" | "grid"; throws std::invalid_argument otherwise.
FeatureRanking ParseFeatureRanking(const std::string& name);

// How ORB runs inside the extraction area. Both give the same keypoints and descriptors (measured
// bit-identical on kitti07, castle, rtabmap and EuRoC images; Features.FastOrbMatchesOpenCvOrb*).
enum class OrbBackend {
  kOpenCv,  // cv::ORB::detectAndCompute with the area as mask (reference; ~3x slower with a mask)
  kFast,    // per-level FAST + mask + Harris retention reproducing cv::ORB's masked semantics,
            // buffers reused per thread, BRIEF only for the kept features (docs/DETECTOR.md, Speed)
};
const char* ToString(OrbBackend backend);
// "opencv" | "fast"; throws std::invalid_argument otherwise.
OrbBackend ParseOrbBackend(const std::string& name);

struct GradientMaskOptions {
  int block_size = 32;            // side of the blocks of the adaptive threshold, pixels
  double threshold_offset = 7.0;  // selected when |grad| > block median + offset, grey levels
  int dilate_radius = 4;          // dilation of the selection, pixels
  void Check() const;
};

struct FeatureOptions {
  int max_features = 300;                              // K, features kept per keyframe
  FeatureRanking ranking = FeatureRanking::kResponse;  // how the K are chosen
  int orb_candidates = 1000;      // ORB detections before ranking (cv::ORB nfeatures), count
  int orb_levels = 8;             // pyramid levels, count
  double orb_scale_factor = 1.2;  // pyramid scale step, ratio > 1
  int orb_fast_threshold = 20;    // FAST threshold, grey levels
  // ORB implementation; both give the same output (see OrbBackend), kFast is 3.4x faster.
  OrbBackend orb_backend = OrbBackend::kFast;
  int grid_cols = 4;              // kGridResponse grid columns, count
  int grid_rows = 3;              // kGridResponse grid rows, count
  bool use_gradient_mask = true;  // restrict to the high-gradient area when no mask is given
  GradientMaskOptions gradient;   // semi-dense selection parameters
  void Check() const;
  // Smallest image side the extraction takes: ORB's 31-pixel patch plus one (as the dataset
  // readers' kMinImageSide), and every pyramid level at least 1 pixel (orb_levels, scale factor).
  int MinImageSide() const;
};

// 256-bit ORB descriptor as four 64-bit words (the packed record's type).
using Descriptor = Descriptor256;

inline int HammingDistance(const Descriptor& a, const Descriptor& b) {
  return __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) +
         __builtin_popcountll(a[2] ^ b[2]) + __builtin_popcountll(a[3] ^ b[3]);
}
inline int Popcount(const Descriptor& d) {
  return __builtin_popcountll(d[0]) + __builtin_popcountll(d[1]) + __builtin_popcountll(d[2]) +
         __builtin_popcountll(d[3]);
}

// A stored keypoint: undistorted normalised image coordinates (x = (u - cx) / fx after removing
// lens distortion), so records do not depend on the camera model.
struct CompactKeypoint {
  float x = 0.0f;      // normalised image x (unitless)
  float y = 0.0f;      // normalised image y (unitless)
  uint16_t angle = 0;  // ORB orientation, 1/100 degree
  uint8_t octave = 0;  // pyramid level
};

// Everything matching needs about one keyframe, and nothing more.
struct KeyframeRecord {
  int64_t id = 0;          // caller's keyframe id
  double timestamp = 0.0;  // seconds
  bool has_pose = false;   // whether world_from_cam is valid
  Sim3d world_from_cam;    // raw vSLAM pose (any scale)
  float focal_px = 0.0f;   // mean focal length used to normalise, pixels (threshold scaling)
  std::vector<Descriptor> descriptors;     // K descriptors
  std::vector<CompactKeypoint> keypoints;  // K keypoints, same order
  std::vector<float> depths;  // empty, or one per keypoint (<= 0 = unknown), raw pose units

  bool has_depths() const { return !depths.empty(); }
  size_t size() const { return descriptors.size(); }
  // Real memory held by the record: inline size plus the heap capacity of its vectors, bytes.
  size_t Bytes() const;
};

// The stored form of a record (core/packed_keyframe.h): one allocation, quantised keypoints,
// half-precision depths, float pose. ORB angle and octave are not stored (nothing reads them).
// UnpackRecord(PackRecord(r)) is r quantised, and packing that again gives the same bytes.
PackedKeyframe PackRecord(const KeyframeRecord& record);
KeyframeRecord UnpackRecord(const PackedKeyframe& packed);

// Semi-dense high-gradient selection (255 = selected) of an 8-bit grayscale image: gradient
// magnitude above a per-block adaptive threshold (block median + offset), then dilated.
cv::Mat HighGradientMask(const cv::Mat& gray, const GradientMaskOptions& options);

struct FeatureInput {
  const cv::Mat* image = nullptr;                // CV_8UC1, required
  const CameraIntrinsics* intrinsics = nullptr;  // required
  // Optional area where features may be extracted (CV_8UC1, same size, non-zero = allowed), e.g.
  // the semi-dense SLAM's high-gradient pixels or the dilated mapped pixels.
  const cv::Mat* mask = nullptr;
  // Optional mapped pixels (feature-based SLAM), pixel coordinates, with optional depth (same
  // length, <= 0 unknown). When given, the extraction area is these pixels dilated.
  const std::vector<cv::Point2f>* mapped_pixels = nullptr;
  const std::vector<float>* mapped_depths = nullptr;
};

// Extracts ORB inside the informative area, ranks and keeps at most K. Fills descriptors,
// keypoints (undistorted, normalised) and depths of `record` (other fields untouched).
// Deterministic. Throws std::invalid_argument on a bad image / intrinsics.
void ExtractInformativeFeatures(const FeatureInput& input, const FeatureOptions& options,
                                KeyframeRecord* record);

// Ranking on its own (exposed for tests): indices of at most k keypoints, in ranked order.
std::vector<int> RankFeatures(const std::vector<cv::KeyPoint>& keypoints,
                              const std::vector<Descriptor>& descriptors, FeatureRanking ranking,
                              int k, cv::Size image_size, int grid_cols, int grid_rows);

}  // namespace sparseloop
