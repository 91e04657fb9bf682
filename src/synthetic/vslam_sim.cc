#include "sparseloop/synthetic/vslam_sim.h"

#include <algorithm>
#include <cmath>

#include "sparseloop/core/check.h"

namespace sparseloop::synthetic {

void DriftOptions::Check() const {
  SL_CHECK_MSG(rotation_noise_deg_per_sqrt_m >= 0.0, "rotation_noise must be >= 0");
  SL_CHECK_MSG(rotation_bias_deg_per_100m.allFinite(), "rotation_bias must be finite");
  SL_CHECK_MSG(
      rotation_bias_deg_per_frame.allFinite() && rotation_bias_deg_per_frame.norm() < 180.0,
      "rotation_bias_per_frame must be finite, its angle (the norm) below 180 deg, got "
      "({}, {}, {})",
      rotation_bias_deg_per_frame.x(), rotation_bias_deg_per_frame.y(),
      rotation_bias_deg_per_frame.z());
  SL_CHECK_MSG(translation_noise >= 0.0 && translation_noise < 1.0,
               "translation_noise must be in [0, 1), got {}", translation_noise);
  SL_CHECK_MSG(scale_noise_per_sqrt_m >= 0.0, "scale_noise must be >= 0");
  SL_CHECK_MSG(std::isfinite(scale_bias_per_100m), "scale_bias must be finite");
  SL_CHECK_MSG(initial_scale > 0.0, "initial_scale must be > 0, got {}", initial_scale);
}

DriftResult SimulateDrift(const Trajectory& gt, const DriftOptions& o) {
  o.Check();
  SL_CHECK_MSG(!gt.empty(), "ground truth is empty");
  SplitMix64 rng(o.seed);
  DriftResult result;
  result.raw = gt;
  result.scale.assign(gt.size(), o.initial_scale);
  const double deg = M_PI / 180.0;
  double log_s = std::log(o.initial_scale);
  // No bias per frame: no extra factor, the chain of today bit for bit.
  const bool has_frame_bias = !o.rotation_bias_deg_per_frame.isZero(0.0);
  const Eigen::Quaterniond frame_bias = ExpSO3(o.rotation_bias_deg_per_frame * deg);
  Rigid3d raw(gt.poses[0].world_from_cam.rotation,
              o.initial_scale * gt.poses[0].world_from_cam.translation);
  result.raw.poses[0].world_from_cam = raw;
  for (size_t i = 0; i + 1 < gt.size(); ++i) {
    const Rigid3d rel = gt.poses[i].world_from_cam.Inverse() * gt.poses[i + 1].world_from_cam;
    const double d = rel.translation.norm();
    const double sd = std::sqrt(d);
    Eigen::Vector3d n(rng.Normal(), rng.Normal(), rng.Normal());
    const Eigen::Vector3d omega =
        (o.rotation_bias_deg_per_100m * (d / 100.0) + o.rotation_noise_deg_per_sqrt_m * sd * n) *
        deg;
    Eigen::Vector3d tn(rng.Normal(), rng.Normal(), rng.Normal());
    const Eigen::Vector3d t = rel.translation + o.translation_noise * d * tn;
    Eigen::Quaterniond q = rel.rotation * ExpSO3(omega);
    if (has_frame_bias) q = q * frame_bias;
    const double s = std::exp(log_s);
    raw = raw * Rigid3d(q, s * t);
    log_s += o.scale_bias_per_100m * d / 100.0 + o.scale_noise_per_sqrt_m * sd * rng.Normal();
    result.raw.poses[i + 1].world_from_cam = raw;
    result.scale[i + 1] = s;
  }
  return result;
}

std::vector<double> LocalScale(const Trajectory& gt, const Trajectory& raw, int half_window) {
  SL_CHECK_MSG(gt.size() == raw.size(), "gt and raw must have the same length ({} vs {})",
               gt.size(), raw.size());
  SL_CHECK_MSG(half_window >= 1, "half_window must be >= 1");
  const auto g = gt.CumulativeDistances();
  const auto r = raw.CumulativeDistances();
  std::vector<double> scale(gt.size(), 1.0);
  const int n = static_cast<int>(gt.size());
  for (int i = 0; i < n; ++i) {
    const int a = std::max(0, i - half_window), b = std::min(n - 1, i + half_window);
    const double dg = g[b] - g[a], dr = r[b] - r[a];
    if (dg > 1e-6 && dr > 1e-9)
      scale[i] = dr / dg;
    else if (i > 0)
      scale[i] = scale[i - 1];
  }
  return scale;
}

void MappedPixelOptions::Check() const {
  SL_CHECK_MSG(cell_size >= 2, "cell_size must be >= 2, got {}", cell_size);
  SL_CHECK_MSG(min_gradient >= 0.0, "min_gradient must be >= 0");
  SL_CHECK_MSG(border >= 1, "border must be >= 1");
}

std::vector<MappedPixel> SelectMappedPixels(const Image8& image, const DepthMap& depth,
                                            double scale, const MappedPixelOptions& o) {
  o.Check();
  SL_CHECK_MSG(image.width == depth.width && image.height == depth.height,
               "image and depth sizes differ");
  SL_CHECK_MSG(scale > 0.0, "scale must be > 0, got {}", scale);
  std::vector<MappedPixel> out;
  const int W = image.width, H = image.height;
  const double min_g2 = o.min_gradient * o.min_gradient;
  for (int cy = o.border; cy < H - o.border; cy += o.cell_size) {
    for (int cx = o.border; cx < W - o.border; cx += o.cell_size) {
      double best = min_g2;
      int bu = -1, bv = -1;
      for (int v = cy; v < std::min(cy + o.cell_size, H - o.border); ++v) {
        for (int u = cx; u < std::min(cx + o.cell_size, W - o.border); ++u) {
          if (!(depth.at(u, v) > 0.0f)) continue;
          const double gx = 0.5 * (image.at(u + 1, v) - image.at(u - 1, v));
          const double gy = 0.5 * (image.at(u, v + 1) - image.at(u, v - 1));
          const double g2 = gx * gx + gy * gy;
          if (g2 > best) best = g2, bu = u, bv = v;
        }
      }
      if (bu >= 0) {
        out.push_back({static_cast<float>(bu), static_cast<float>(bv),
                       static_cast<float>(depth.at(bu, bv) * scale)});
      }
    }
  }
  return out;
}

}  // namespace sparseloop::synthetic
