#pragma once
// Private to sparseloop::features. cv::resize(src, dst, size, 0, 0, cv::INTER_LINEAR_EXACT) for
// 8-bit single-channel images, bit-identical to OpenCV 4.x's fixed-point implementation
// (docs/DETECTOR.md, "The pyramid resizes"), for the ORB pyramids:
// - OpenCV recomputes the tap offsets and 8-bit coefficients of every output column and row with
//   software floating point (cv::softdouble) at every call; here they are computed once per
//   (source size, output size) with IEEE double arithmetic (the same correctly rounded
//   operations) and cached: the image and mask pyramids of every keyframe share them;
// - the horizontal pass gathers the two taps of 8 output pixels with one byte shuffle from a
//   precomputed pattern (x86-64 with SSSE3 / SSE4.1, detected at run time) instead of 8 loads.
// Everything else (fixed-point arithmetic, border rules, rounding) is OpenCV's. Sizes where
// OpenCV takes another path (equal sizes: a copy; exactly half in both directions: INTER_AREA)
// and other types are passed to cv::resize.
#include <cstdint>
#include <memory>
#include <vector>

#include <opencv2/core.hpp>

namespace sparseloop::internal {

class LinearExactResizer {
 public:
  // simd = false: the scalar loops only (what runs on other CPUs; for the tests).
  explicit LinearExactResizer(bool simd = true);
  ~LinearExactResizer();
  LinearExactResizer(const LinearExactResizer&) = delete;
  LinearExactResizer& operator=(const LinearExactResizer&) = delete;

  // `dst` is (re)allocated to `size` unless it already has that size and type; it must not
  // share memory with `src`.
  void Resize(const cv::Mat& src, cv::Size size, cv::Mat* dst);

  struct Tables;  // tap offsets, coefficients, shuffle patterns of one size pair (in the .cc)

 private:
  const Tables& TablesFor(cv::Size src, cv::Size dst);
  std::vector<std::unique_ptr<Tables>> tables_;  // a handful of sizes (the pyramid levels)
  std::vector<uint16_t> rows_;                   // two horizontally resized source rows
  bool simd_ = true;
};

}  // namespace sparseloop::internal
