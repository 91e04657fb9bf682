#pragma once
// Plain image buffers returned by the renderer (no OpenCV types in the public API).
#include <cstdint>
#include <vector>

namespace sparseloop::synthetic {

// Row-major 8-bit grayscale image.
struct Image8 {
  int width = 0;                // pixels
  int height = 0;               // pixels
  std::vector<uint8_t> pixels;  // width * height, row-major

  uint8_t at(int u, int v) const { return pixels[static_cast<size_t>(v) * width + u]; }
};

// Row-major depth map: z of the hit point in the camera frame (metres); 0 where nothing was hit
// (sky).
struct DepthMap {
  int width = 0;             // pixels
  int height = 0;            // pixels
  std::vector<float> depth;  // width * height, row-major

  float at(int u, int v) const { return depth[static_cast<size_t>(v) * width + u]; }
};

// Deterministic, platform-independent random numbers (SplitMix64). std:: distributions are not
// specified bit-exactly across standard libraries, so the synthetic module uses only this.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1).
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  // Standard normal (Box-Muller, one value per call).
  double Normal();

 private:
  uint64_t state_;
};

// Order-dependent hash of a few integers (for per-tile / per-cell / per-row seeds).
uint64_t HashCombine(uint64_t seed, int64_t a, int64_t b = 0, int64_t c = 0);

}  // namespace sparseloop::synthetic
