#include "sparseloop/synthetic/world.h"

#include <algorithm>
#include <cmath>

#include "sparseloop/core/check.h"
#include "sparseloop/synthetic/image.h"

namespace sparseloop::synthetic {

void World::Check() const {
  SL_CHECK_MSG(textures != nullptr && !textures->empty(), "world has no textures");
  for (size_t m = 0; m < materials.size(); ++m) {
    const auto& mat = materials[m];
    SL_CHECK_MSG(mat.texture >= 0 && static_cast<size_t>(mat.texture) < textures->size(),
                 "material {} uses texture {} of {}", m, mat.texture, textures->size());
    SL_CHECK_MSG(mat.texels_per_metre > 0.0, "material {}: texels_per_metre must be > 0", m);
    SL_CHECK_MSG(mat.tile_size > 0.0, "material {}: tile_size must be > 0", m);
    SL_CHECK_MSG(mat.blend_fraction >= 0.0 && mat.blend_fraction <= 0.5,
                 "material {}: blend_fraction must be in [0, 0.5]", m);
    SL_CHECK_MSG(mat.min_scale > 0.0 && mat.max_scale >= mat.min_scale,
                 "material {}: need 0 < min_scale <= max_scale", m);
  }
  for (size_t q = 0; q < quads.size(); ++q) {
    const auto& quad = quads[q];
    SL_CHECK_MSG(quad.material >= 0 && static_cast<size_t>(quad.material) < materials.size(),
                 "quad {} uses material {} of {}", q, quad.material, materials.size());
    SL_CHECK_MSG(std::abs(quad.axis_u.norm() - 1.0) < 1e-6 &&
                     std::abs(quad.axis_v.norm() - 1.0) < 1e-6 &&
                     std::abs(quad.axis_u.dot(quad.axis_v)) < 1e-6,
                 "quad {} axes must be orthonormal", q);
    SL_CHECK_MSG(quad.infinite || (quad.size_u > 0.0 && quad.size_v > 0.0),
                 "quad {} must have positive size", q);
  }
  SL_CHECK_MSG(std::abs(sky.up.norm() - 1.0) < 1e-6, "sky.up must be a unit vector");
}

Hit World::Trace(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                 double min_distance) const {
  Hit best;
  const Eigen::Vector3d d = direction.normalized();
  for (size_t q = 0; q < quads.size(); ++q) {
    const Quad& quad = quads[q];
    const Eigen::Vector3d n = quad.Normal();
    const double denom = n.dot(d);
    if (std::abs(denom) < 1e-12) continue;
    const double dist = n.dot(quad.origin - origin) / denom;
    if (!(dist > min_distance) || dist >= best.distance) continue;
    const Eigen::Vector3d p = origin + dist * d;
    if (!quad.infinite) {
      const double a = (p - quad.origin).dot(quad.axis_u);
      const double b = (p - quad.origin).dot(quad.axis_v);
      if (a < 0.0 || a > quad.size_u || b < 0.0 || b > quad.size_v) continue;
    }
    best.quad = static_cast<int>(q);
    best.distance = dist;
    best.p_in_world = p;
  }
  if (best.quad >= 0) best.st = TextureCoordinates(best.quad, best.p_in_world);
  return best;
}

Eigen::Vector2d World::TextureCoordinates(int quad, const Eigen::Vector3d& p_in_world) const {
  const Quad& q = quads.at(quad);
  const Eigen::Vector3d r = p_in_world - q.tex_origin;
  return {r.dot(q.tex_u), r.dot(q.tex_v)};
}

namespace {

struct TileParams {
  int texture;
  double cos_a, sin_a, k;  // rotation and texels per metre
  double ox, oy;           // texel offset
};

TileParams MosaicTile(const Material& m, size_t num_textures, int64_t i, int64_t j,
                      const TextureSet& set) {
  SplitMix64 rng(HashCombine(m.seed, i, j, 0x7115));
  TileParams p;
  p.texture = static_cast<int>(rng.Next() % num_textures);
  const double angle = rng.Uniform(0.0, 2.0 * M_PI);
  p.cos_a = std::cos(angle);
  p.sin_a = std::sin(angle);
  p.k = m.texels_per_metre * rng.Uniform(m.min_scale, m.max_scale);
  p.ox = rng.Uniform() * set.textures[p.texture].width();
  p.oy = rng.Uniform() * set.textures[p.texture].height();
  return p;
}

float SampleTile(const TileParams& p, const TextureSet& set, double ds, double dt,
                 double footprint_m) {
  const double x = p.k * (p.cos_a * ds - p.sin_a * dt) + p.ox;
  const double y = p.k * (p.sin_a * ds + p.cos_a * dt) + p.oy;
  return set.textures[p.texture].Sample(x, y, footprint_m * p.k);
}

// Weight of the neighbouring tile for a fractional position f in [0, 1) of the current tile:
// 0.5 at the shared border, 0 at `b` inside; returns the neighbour offset (-1, 0, +1).
int BlendWeight(double f, double b, double* w) {
  *w = 0.0;
  if (b <= 0.0) return 0;
  if (f < b) {
    const double x = 1.0 - f / b;
    *w = 0.5 * x * x * (3.0 - 2.0 * x);
    return -1;
  }
  if (f > 1.0 - b) {
    const double x = 1.0 - (1.0 - f) / b;
    *w = 0.5 * x * x * (3.0 - 2.0 * x);
    return 1;
  }
  return 0;
}

// Smooth 3D value noise in [-1, 1].
double ValueNoise3(const Eigen::Vector3d& p, uint64_t seed) {
  const Eigen::Vector3d f = p.array().floor();
  const Eigen::Vector3d t = p - f;
  const Eigen::Vector3d s = t.array() * t.array() * (3.0 - 2.0 * t.array());
  auto lattice = [&](int dx, int dy, int dz) {
    SplitMix64 g(HashCombine(seed, static_cast<int64_t>(f.x()) + dx,
                             static_cast<int64_t>(f.y()) + dy, static_cast<int64_t>(f.z()) + dz));
    return g.Uniform(-1.0, 1.0);
  };
  double c[2][2][2];
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 2; ++b)
      for (int d = 0; d < 2; ++d) c[a][b][d] = lattice(a, b, d);
  auto lerp = [](double a, double b, double w) { return a + w * (b - a); };
  const double x00 = lerp(c[0][0][0], c[1][0][0], s.x()), x10 = lerp(c[0][1][0], c[1][1][0], s.x());
  const double x01 = lerp(c[0][0][1], c[1][0][1], s.x()), x11 = lerp(c[0][1][1], c[1][1][1], s.x());
  return lerp(lerp(x00, x10, s.y()), lerp(x01, x11, s.y()), s.z());
}

}  // namespace

float World::Shade(int material, const Eigen::Vector2d& st, double footprint_m) const {
  const Material& m = materials[material];
  const TextureSet& set = *textures;
  if (m.kind == Material::Kind::kTexture) {
    const double c = std::cos(m.angle_rad), s = std::sin(m.angle_rad);
    const double x = m.texels_per_metre * (c * st.x() - s * st.y()) + m.offset_texels.x();
    const double y = m.texels_per_metre * (s * st.x() + c * st.y()) + m.offset_texels.y();
    return m.gain * set.textures[m.texture].Sample(x, y, footprint_m * m.texels_per_metre);
  }
  const double gs = st.x() / m.tile_size, gt = st.y() / m.tile_size;
  const double fi = std::floor(gs), fj = std::floor(gt);
  const int64_t i = static_cast<int64_t>(fi), j = static_cast<int64_t>(fj);
  double wx = 0.0, wy = 0.0;
  const int nx = BlendWeight(gs - fi, m.blend_fraction, &wx);
  const int ny = BlendWeight(gt - fj, m.blend_fraction, &wy);
  auto sample = [&](int64_t ti, int64_t tj) {
    const TileParams p = MosaicTile(m, set.size(), ti, tj, set);
    // Offsets relative to the tile centre so that the rotation pivots inside the tile.
    const double ds = st.x() - (static_cast<double>(ti) + 0.5) * m.tile_size;
    const double dt = st.y() - (static_cast<double>(tj) + 0.5) * m.tile_size;
    return SampleTile(p, set, ds, dt, footprint_m);
  };
  double value = (1.0 - wx) * (1.0 - wy) * sample(i, j);
  if (nx != 0) value += wx * (1.0 - wy) * sample(i + nx, j);
  if (ny != 0) value += (1.0 - wx) * wy * sample(i, j + ny);
  if (nx != 0 && ny != 0) value += wx * wy * sample(i + nx, j + ny);
  return m.gain * static_cast<float>(value);
}

float World::SkyIntensity(const Eigen::Vector3d& direction) const {
  const double e = std::clamp(direction.dot(sky.up), -1.0, 1.0);
  double v =
      sky.horizon_intensity + (sky.zenith_intensity - sky.horizon_intensity) * std::max(e, 0.0);
  if (e < 0.0) v = sky.horizon_intensity * (1.0 + 0.3 * e);
  const double cloud =
      ValueNoise3(direction * 3.0, sky.seed) + 0.5 * ValueNoise3(direction * 7.0, sky.seed + 1);
  v += sky.cloud_amplitude * cloud * std::max(e, 0.0);
  return static_cast<float>(v);
}

}  // namespace sparseloop::synthetic
