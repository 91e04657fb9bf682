#pragma once
// Exact ray-traced rendering of a World with a pinhole camera: 8-bit grayscale image + depth.
//
// Conventions: camera frame x right, y down, z forward. Pixel (u, v) (integers) is the centre of
// the pixel in column u, row v, i.e. the ray through (u, v) is ((u - cx) / fx, (v - cy) / fy, 1)
// in the camera frame -- the same as CameraIntrinsics::Project / Unproject. Lens distortion is
// ignored (the synthetic camera is ideal). The depth map holds the camera-frame z of the hit.
//
// Anti-aliasing: textures are sampled trilinearly from their mip chain at the level given by the
// exact pixel footprint (the texture-space distance between the hits of neighbouring pixel rays
// on the same plane), so distant ground does not alias.
//
// Determinism: every pixel is computed independently from the inputs, and the sensor noise of row
// v comes from a generator seeded by (options.seed, frame_seed, v); the output bytes are therefore
// identical for any number of threads.
#include <cstdint>

#include "sparseloop/core/camera.h"
#include "sparseloop/core/rigid3.h"
#include "sparseloop/synthetic/image.h"
#include "sparseloop/synthetic/world.h"

namespace sparseloop::synthetic {

// Per-frame photometric state (exposure and gamma change between visits).
struct Photometric {
  double gain = 1.0;   // exposure multiplier applied to the albedo
  double gamma = 1.0;  // out = 255 * (gain * in / 255)^gamma
};

struct RenderOptions {
  double near = 0.05;           // metres; hits closer than this along z are ignored
  double max_distance = 400.0;  // metres; finite quads farther than this are culled
  double noise_sigma = 1.5;     // gray levels, std-dev of the additive Gaussian sensor noise
  double blur_sigma = 0.0;      // pixels, std-dev of a Gaussian blur (0: none)
  int num_threads = 1;          // threads over rows (the output does not depend on it)
  uint64_t seed = 1;            // noise seed
  void Check() const;
};

struct RenderedFrame {
  Image8 image;
  DepthMap depth;
};

// Throws std::invalid_argument for bad options or intrinsics without a size.
RenderedFrame RenderFrame(const World& world, const CameraIntrinsics& camera,
                          const Rigid3d& world_from_cam, const RenderOptions& options,
                          const Photometric& photometric = {}, uint64_t frame_seed = 0);

// Exposure/gamma of frame `index`: slow sinusoids with the given amplitudes and period, phase
// from `seed`; so visits far apart in time see different exposures.
struct PhotometricDriftOptions {
  double gain_amplitude = 0.15;   // relative, gain in [1 - a, 1 + a]
  double gamma_amplitude = 0.10;  // gamma in [1 - a, 1 + a]
  double period_frames = 1200.0;  // frames per cycle
  uint64_t seed = 5;
  void Check() const;
};
Photometric PhotometricForFrame(int64_t index, const PhotometricDriftOptions& options);

}  // namespace sparseloop::synthetic
