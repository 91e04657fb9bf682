#pragma once
// Private to sparseloop::features. Masked ORB detection that reproduces
// cv::ORB::detectAndCompute(image, mask) (OpenCV 4.x, HARRIS_SCORE, edge threshold 31, patch 31,
// first level 0, WTA_K 2) without OpenCV's masked-path cost (docs/DETECTOR.md, Speed):
//   per level: image pyramid by chained INTER_LINEAR_EXACT resizes (LinearExactResizer, bit-exact),
//   mask pyramid the same way
//   (thresholded at 254 like OpenCV), FAST with non-max suppression, drop keypoints outside the
//   level mask and within 31 px of the level border, keep the 2n best by FAST score, Harris
//   response on a 7x7 block, keep the n best (n = ORB's per-level quota).
// Orientation (intensity centroid) and descriptors are computed afterwards, only for the keypoints
// that are asked for; BRIEF by cv::ORB on a crop of the level image, so the pattern and the 7x7
// Gaussian are OpenCV's own.
// Buffers are reused per thread (no large allocation per call).
#include <vector>

#include <opencv2/core.hpp>

#include "sparseloop/features/informative_features.h"

namespace sparseloop::internal {

struct MaskedOrbParams {
  int nfeatures = 1000;
  float scale_factor = 1.2f;  // float, as cv::ORB::create takes it
  int levels = 8;
  int fast_threshold = 20;
};

// Keypoints exactly as cv::ORB would return them (full-resolution coordinates, octave, size,
// Harris response; angle NOT yet set), grouped by level in ORB's order. `mask` may be empty (no
// mask). Keeps the pyramid of this call in thread-local storage for ComputeMaskedOrbDescriptors.
void DetectMaskedOrb(const cv::Mat& image, const cv::Mat& mask, const MaskedOrbParams& params,
                     std::vector<cv::KeyPoint>* keypoints);

// Sets the ORB angle of (*keypoints)[indices[j]] and its descriptor -> (*descriptors)[j], for the
// keypoints returned by the latest DetectMaskedOrb call on this thread (same params). Call it once
// per detection: it then drops the workspace's reference to the caller's image and mask.
void ComputeMaskedOrbDescriptors(const std::vector<int>& indices, const MaskedOrbParams& params,
                                 std::vector<cv::KeyPoint>* keypoints,
                                 std::vector<Descriptor>* descriptors);

}  // namespace sparseloop::internal
