#pragma once
// What a monocular vSLAM front-end would hand over to loop closure, simulated from ground truth:
// a drifting raw trajectory (rotation random walk + bias, translation noise, scale drift) and, per
// frame, mapped pixels with depths in the raw (drifted) scale.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "sparseloop/core/trajectory.h"
#include "sparseloop/synthetic/image.h"

namespace sparseloop::synthetic {

// The raw trajectory is a consistent chain built in the body frame:
//   raw_0 = gt_0 (translation times initial_scale),
//   raw_{i+1} = raw_i * [ R_i | s_i * t_i ],  with  [R_i | t_i] = noisy(gt_i^-1 gt_{i+1}),
// where the relative rotation is R_i = R_gt * Exp(bias * d + noise * sqrt(d) * n) * Exp(b_frame)
// (d = metres travelled in the step, n ~ N(0, I), b_frame the bias per frame), the relative
// translation gets Gaussian noise proportional to the step length, and log(s) performs a random
// walk with drift per metre. Rotation vectors are in the camera frame: x right (pitch), y down
// (yaw, the heading of a car or a level drone), z forward (roll about the optical axis).
struct DriftOptions {
  double rotation_noise_deg_per_sqrt_m = 0.02;  // deg / sqrt(m), random-walk std-dev per axis
  Eigen::Vector3d rotation_bias_deg_per_100m{0.0, 0.6, 0.0};  // deg per 100 m, camera frame
  // Rotation bias per frame (step i -> i + 1, whatever its length), degrees about camera x, y, z;
  // each step's rotation error is exactly Exp(b_frame) times the per-metre terms. |b| < 180.
  Eigen::Vector3d rotation_bias_deg_per_frame = Eigen::Vector3d::Zero();
  double translation_noise = 0.01;        // std-dev per axis, fraction of the step length
  double scale_noise_per_sqrt_m = 0.002;  // std-dev of d log(s) per sqrt(metre)
  double scale_bias_per_100m = 0.01;      // d log(s) per 100 m (monocular scale drift)
  double initial_scale = 1.0;             // raw units per metre at frame 0
  uint64_t seed = 17;
  void Check() const;
};

struct DriftResult {
  Trajectory raw;             // same frames/timestamps as the input GT
  std::vector<double> scale;  // s_i: raw units per metre around frame i
};

// Throws std::invalid_argument for bad options or an empty GT.
DriftResult SimulateDrift(const Trajectory& gt, const DriftOptions& options = {});

// Local scale (raw units per metre) of a real estimate associated to GT by index: ratio of path
// lengths over a window of +-`half_window` frames (1.0 where the GT does not move).
std::vector<double> LocalScale(const Trajectory& gt, const Trajectory& raw, int half_window = 10);

struct MappedPixel {
  float u = 0.0f;      // pixel column (pixel centres at integers)
  float v = 0.0f;      // pixel row
  float depth = 0.0f;  // camera-frame z in RAW units (metres times the local scale)
};

struct MappedPixelOptions {
  int cell_size = 16;          // pixels; at most one mapped pixel per cell x cell block
  double min_gradient = 24.0;  // gray levels, central-difference gradient magnitude threshold
  int border = 8;              // pixels ignored at the image border
  void Check() const;
};

// The strongest-gradient pixel of each cell whose depth is valid (a hit, not sky), with its depth
// multiplied by `scale`. Deterministic order: cells row-major.
std::vector<MappedPixel> SelectMappedPixels(const Image8& image, const DepthMap& depth,
                                            double scale, const MappedPixelOptions& options = {});

}  // namespace sparseloop::synthetic
