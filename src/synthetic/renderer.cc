#include "sparseloop/synthetic/renderer.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <optional>
#include <thread>

#include "sparseloop/core/check.h"

namespace sparseloop::synthetic {

void RenderOptions::Check() const {
  SL_CHECK_MSG(near > 0.0, "near must be > 0 metres, got {}", near);
  SL_CHECK_MSG(max_distance > near, "max_distance must exceed near, got {}", max_distance);
  SL_CHECK_MSG(noise_sigma >= 0.0, "noise_sigma must be >= 0, got {}", noise_sigma);
  SL_CHECK_MSG(blur_sigma >= 0.0 && blur_sigma <= 20.0, "blur_sigma must be in [0, 20], got {}",
               blur_sigma);
  SL_CHECK_MSG(num_threads >= 1 && num_threads <= 256, "num_threads must be in [1, 256], got {}",
               num_threads);
}

void PhotometricDriftOptions::Check() const {
  SL_CHECK_MSG(gain_amplitude >= 0.0 && gain_amplitude < 1.0,
               "gain_amplitude must be in [0, 1), got {}", gain_amplitude);
  SL_CHECK_MSG(gamma_amplitude >= 0.0 && gamma_amplitude < 1.0,
               "gamma_amplitude must be in [0, 1), got {}", gamma_amplitude);
  SL_CHECK_MSG(period_frames > 0.0, "period_frames must be > 0, got {}", period_frames);
}

Photometric PhotometricForFrame(int64_t index, const PhotometricDriftOptions& options) {
  options.Check();
  SplitMix64 rng(options.seed);
  const double phase_gain = rng.Uniform(0.0, 2.0 * M_PI);
  const double phase_gamma = rng.Uniform(0.0, 2.0 * M_PI);
  const double w = 2.0 * M_PI * static_cast<double>(index) / options.period_frames;
  return {1.0 + options.gain_amplitude * std::sin(w + phase_gain),
          1.0 + options.gamma_amplitude * std::sin(0.7 * w + phase_gamma)};
}

namespace {

struct VisibleQuad {
  int index;
  Eigen::Vector3d n, o, u, v;  // camera frame: normal, origin, axes
  double n_dot_o;
  double size_u, size_v;
  bool infinite;
  Eigen::Vector3d to, tu, tv;  // texture frame in camera coordinates
  int u0, u1, v0, v1;          // pixel bounding box, inclusive
};

// Clips a convex polygon to z >= near (Sutherland-Hodgman).
std::vector<Eigen::Vector3d> ClipNear(const std::vector<Eigen::Vector3d>& poly, double near) {
  std::vector<Eigen::Vector3d> out;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector3d& a = poly[i];
    const Eigen::Vector3d& b = poly[(i + 1) % poly.size()];
    const bool ina = a.z() >= near, inb = b.z() >= near;
    if (ina) out.push_back(a);
    if (ina != inb) out.push_back(a + (near - a.z()) / (b.z() - a.z()) * (b - a));
  }
  return out;
}

template <typename Fn>
void ParallelRows(int height, int num_threads, Fn&& fn) {
  constexpr int kChunk = 8;
  const int chunks = (height + kChunk - 1) / kChunk;
  std::atomic<int> next{0};
  auto worker = [&]() {
    for (int c = next++; c < chunks; c = next++) {
      const int end = std::min(height, (c + 1) * kChunk);
      for (int v = c * kChunk; v < end; ++v) fn(v);
    }
  };
  const int extra = std::min(num_threads, chunks) - 1;
  std::vector<std::thread> threads;
  for (int t = 0; t < extra; ++t) threads.emplace_back(worker);
  worker();
  for (auto& t : threads) t.join();
}

void GaussianBlur(std::vector<float>& img, int width, int height, double sigma, int threads) {
  const int r = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
  std::vector<float> kernel(2 * r + 1);
  double sum = 0.0;
  for (int i = -r; i <= r; ++i)
    sum += kernel[i + r] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)));
  for (auto& k : kernel) k = static_cast<float>(k / sum);
  std::vector<float> tmp(img.size());
  ParallelRows(height, threads, [&](int v) {
    const float* row = &img[static_cast<size_t>(v) * width];
    for (int u = 0; u < width; ++u) {
      float acc = 0.0f;
      for (int i = -r; i <= r; ++i) acc += kernel[i + r] * row[std::clamp(u + i, 0, width - 1)];
      tmp[static_cast<size_t>(v) * width + u] = acc;
    }
  });
  ParallelRows(height, threads, [&](int v) {
    for (int u = 0; u < width; ++u) {
      float acc = 0.0f;
      for (int i = -r; i <= r; ++i) {
        acc +=
            kernel[i + r] * tmp[static_cast<size_t>(std::clamp(v + i, 0, height - 1)) * width + u];
      }
      img[static_cast<size_t>(v) * width + u] = acc;
    }
  });
}

// Quad q in the camera frame with its pixel bounding box; nothing when it is farther than
// max_distance, behind the near plane or outside the image.
std::optional<VisibleQuad> ProjectQuad(const Quad& quad, int index, const Rigid3d& world_from_cam,
                                       const CameraIntrinsics& camera,
                                       const RenderOptions& options) {
  const int W = camera.width, H = camera.height;
  const Rigid3d cam_from_world = world_from_cam.Inverse();
  const Eigen::Matrix3d R = cam_from_world.RotationMatrix();
  const Eigen::Vector3d cam_in_world = world_from_cam.translation;
  VisibleQuad vq;
  vq.index = index;
  vq.infinite = quad.infinite;
  vq.size_u = quad.size_u;
  vq.size_v = quad.size_v;
  if (!quad.infinite) {
    // Closest point of the rectangle to the camera, for distance culling.
    const Eigen::Vector3d r = cam_in_world - quad.origin;
    const double a = std::clamp(r.dot(quad.axis_u), 0.0, quad.size_u);
    const double b = std::clamp(r.dot(quad.axis_v), 0.0, quad.size_v);
    const Eigen::Vector3d closest = quad.origin + a * quad.axis_u + b * quad.axis_v;
    if ((closest - cam_in_world).norm() > options.max_distance) return std::nullopt;
  }
  vq.o = cam_from_world * quad.origin;
  vq.u = R * quad.axis_u;
  vq.v = R * quad.axis_v;
  vq.n = vq.u.cross(vq.v).normalized();
  vq.n_dot_o = vq.n.dot(vq.o);
  vq.to = cam_from_world * quad.tex_origin;
  vq.tu = R * quad.tex_u;
  vq.tv = R * quad.tex_v;
  if (quad.infinite) {
    vq.u0 = 0, vq.u1 = W - 1, vq.v0 = 0, vq.v1 = H - 1;
    return vq;
  }
  const std::vector<Eigen::Vector3d> corners = {vq.o, vq.o + quad.size_u * vq.u,
                                                vq.o + quad.size_u * vq.u + quad.size_v * vq.v,
                                                vq.o + quad.size_v * vq.v};
  const auto clipped = ClipNear(corners, options.near);
  if (clipped.empty()) return std::nullopt;
  double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
  for (const auto& p : clipped) {
    const double pu = camera.fx * p.x() / p.z() + camera.cx;
    const double pv = camera.fy * p.y() / p.z() + camera.cy;
    umin = std::min(umin, pu), umax = std::max(umax, pu);
    vmin = std::min(vmin, pv), vmax = std::max(vmax, pv);
  }
  vq.u0 = static_cast<int>(std::max(0.0, std::floor(umin)));
  vq.u1 = static_cast<int>(std::min(W - 1.0, std::ceil(umax)));
  vq.v0 = static_cast<int>(std::max(0.0, std::floor(vmin)));
  vq.v1 = static_cast<int>(std::min(H - 1.0, std::ceil(vmax)));
  if (vq.u0 > vq.u1 || vq.v0 > vq.v1) return std::nullopt;
  return vq;
}

// Texture-space footprint of the pixel whose ray d hits quad q at X: the step to the hits of
// the neighbouring pixel rays on the quad's plane.
double TextureFootprint(const VisibleQuad& q, const Eigen::Vector3d& d, const Eigen::Vector3d& X,
                        const CameraIntrinsics& camera) {
  double footprint = 0.0;
  for (const Eigen::Vector3d& step :
       {Eigen::Vector3d(1.0 / camera.fx, 0, 0), Eigen::Vector3d(0, 1.0 / camera.fy, 0)}) {
    const Eigen::Vector3d d1 = d + step;
    const double denom = q.n.dot(d1);
    const double z1 = std::abs(denom) > 1e-12 ? q.n_dot_o / denom : -1.0;
    double f;
    if (z1 > 0.0) {
      const Eigen::Vector3d dX = z1 * d1 - X;
      f = std::max(std::abs(dX.dot(q.tu)), std::abs(dX.dot(q.tv)));
    } else {
      f = 1e3;  // grazing: the neighbour ray misses the plane; use the coarsest level
    }
    footprint = std::max(footprint, f);
  }
  return footprint;
}

// Optics and sensor: blur, exposure/gamma, noise, quantisation of the radiance into the image.
void ExposeImage(std::vector<float>& radiance, const RenderOptions& options,
                 const Photometric& photometric, uint64_t frame_seed, Image8* image) {
  const int W = image->width, H = image->height;
  if (options.blur_sigma > 0.0)
    GaussianBlur(radiance, W, H, options.blur_sigma, options.num_threads);
  image->pixels.resize(radiance.size());
  ParallelRows(H, options.num_threads, [&](int v) {
    SplitMix64 rng(HashCombine(options.seed, static_cast<int64_t>(frame_seed), v));
    for (int u = 0; u < W; ++u) {
      const size_t i = static_cast<size_t>(v) * W + u;
      double x = std::clamp(photometric.gain * radiance[i] / 255.0, 0.0, 1.0);
      if (photometric.gamma != 1.0) x = std::pow(x, photometric.gamma);
      double value = 255.0 * x;
      if (options.noise_sigma > 0.0) value += options.noise_sigma * rng.Normal();
      image->pixels[i] = static_cast<uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  });
}

}  // namespace

RenderedFrame RenderFrame(const World& world, const CameraIntrinsics& camera,
                          const Rigid3d& world_from_cam, const RenderOptions& options,
                          const Photometric& photometric, uint64_t frame_seed) {
  options.Check();
  camera.Check();
  SL_CHECK_MSG(camera.width > 0 && camera.height > 0, "camera needs a size, got {}x{}",
               camera.width, camera.height);
  SL_CHECK_MSG(photometric.gain > 0.0 && photometric.gamma > 0.0,
               "photometric gain and gamma must be > 0");
  SL_CHECK_MSG(world.textures != nullptr && !world.textures->empty(), "world has no textures");
  const int W = camera.width, H = camera.height;
  // 1. Visible quads in the camera frame with their pixel bounding boxes.
  std::vector<VisibleQuad> visible;
  for (size_t q = 0; q < world.quads.size(); ++q) {
    if (auto vq = ProjectQuad(world.quads[q], static_cast<int>(q), world_from_cam, camera, options))
      visible.push_back(*vq);
  }

  std::vector<double> xn(W);
  for (int u = 0; u < W; ++u) xn[u] = (u - camera.cx) / camera.fx;
  const Eigen::Matrix3d R_wc = world_from_cam.RotationMatrix();

  RenderedFrame frame;
  frame.image.width = frame.depth.width = W;
  frame.image.height = frame.depth.height = H;
  frame.depth.depth.assign(static_cast<size_t>(W) * H, 0.0f);
  std::vector<float> radiance(static_cast<size_t>(W) * H, 0.0f);

  // 2. Visibility (nearest hit per pixel) and shading, row by row.
  ParallelRows(H, options.num_threads, [&](int v) {
    const double yn = (v - camera.cy) / camera.fy;
    std::vector<double> best_z(W, std::numeric_limits<double>::infinity());
    std::vector<int> best_q(W, -1);
    for (size_t k = 0; k < visible.size(); ++k) {
      const VisibleQuad& q = visible[k];
      if (v < q.v0 || v > q.v1) continue;
      for (int u = q.u0; u <= q.u1; ++u) {
        const Eigen::Vector3d d(xn[u], yn, 1.0);
        const double denom = q.n.dot(d);
        if (std::abs(denom) < 1e-12) continue;
        const double z = q.n_dot_o / denom;
        if (!(z > options.near) || z >= best_z[u]) continue;
        if (!q.infinite) {
          const Eigen::Vector3d r = z * d - q.o;
          const double a = r.dot(q.u), b = r.dot(q.v);
          if (a < 0.0 || a > q.size_u || b < 0.0 || b > q.size_v) continue;
        }
        best_z[u] = z;
        best_q[u] = static_cast<int>(k);
      }
    }
    float* out = &radiance[static_cast<size_t>(v) * W];
    float* depth = &frame.depth.depth[static_cast<size_t>(v) * W];
    for (int u = 0; u < W; ++u) {
      const Eigen::Vector3d d(xn[u], yn, 1.0);
      if (best_q[u] < 0) {
        out[u] = world.SkyIntensity((R_wc * d).normalized());
        continue;
      }
      const VisibleQuad& q = visible[best_q[u]];
      const double z = best_z[u];
      const Eigen::Vector3d X = z * d;
      const Eigen::Vector2d st((X - q.to).dot(q.tu), (X - q.to).dot(q.tv));
      const double footprint = TextureFootprint(q, d, X, camera);
      out[u] = world.Shade(world.quads[q.index].material, st, footprint);
      depth[u] = static_cast<float>(z);
    }
  });

  // 3. Optics and sensor.
  ExposeImage(radiance, options, photometric, frame_seed, &frame.image);
  return frame;
}

}  // namespace sparseloop::synthetic
