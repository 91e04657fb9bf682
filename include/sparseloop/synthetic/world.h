#pragma once
// A synthetic world: textured planar quads (ground, facades) and a sky, traced exactly.
//
// Texture coordinates are a function of WORLD position only (never of time or of the camera):
// a point p on a quad has texture-space coordinates (s, t) = ((p - tex_origin) . tex_u,
// (p - tex_origin) . tex_v) in metres, which the quad's material maps to texels. A revisited
// place therefore looks the same, whichever pass or pose sees it.
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "sparseloop/synthetic/texture.h"

namespace sparseloop::synthetic {

struct Material {
  enum class Kind {
    kTexture,  // one texture, rotated/scaled/offset by the fields below
    kMosaic,   // a non-repeating mosaic: square tiles of `tile_size` metres in (s, t), each tile
               // a hashed (texture, rotation, scale, offset) of the set, blended at the borders
  };
  Kind kind = Kind::kTexture;
  int texture = 0;                 // kTexture: index into the world's TextureSet
  double texels_per_metre = 32.0;  // texels per metre of (s, t)
  double angle_rad = 0.0;          // kTexture: rotation of the texture in (s, t), radians
  Eigen::Vector2d offset_texels = Eigen::Vector2d::Zero();  // kTexture: texel offset
  float gain = 1.0f;                                        // intensity multiplier (albedo)
  double tile_size = 20.0;                                  // kMosaic: tile side, metres
  double blend_fraction = 0.15;  // kMosaic: fraction of a tile blended with the neighbour
  double min_scale = 0.7;        // kMosaic: per-tile scale range (times texels_per_metre)
  double max_scale = 1.4;
  uint64_t seed = 0;  // kMosaic: tile hash seed
};

// A planar rectangle {origin + a * size_u * axis_u + b * size_v * axis_v, a, b in [0, 1]}, or the
// whole plane when `infinite`. Quads are two-sided.
struct Quad {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();   // metres, world frame
  Eigen::Vector3d axis_u = Eigen::Vector3d::UnitX();  // unit vector
  Eigen::Vector3d axis_v = Eigen::Vector3d::UnitY();  // unit vector, orthogonal to axis_u
  double size_u = 1.0;                                // metres
  double size_v = 1.0;                                // metres
  bool infinite = false;
  int material = 0;                                      // index into World::materials
  Eigen::Vector3d tex_origin = Eigen::Vector3d::Zero();  // world point with (s, t) = (0, 0)
  Eigen::Vector3d tex_u = Eigen::Vector3d::UnitX();      // unit, direction of s in world
  Eigen::Vector3d tex_v = Eigen::Vector3d::UnitY();      // unit, direction of t in world

  Eigen::Vector3d Normal() const { return axis_u.cross(axis_v).normalized(); }
};

struct Sky {
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  // world up (unit)
  float horizon_intensity = 175.0f;               // gray level at the horizon
  float zenith_intensity = 225.0f;                // gray level straight up
  float cloud_amplitude = 25.0f;                  // gray levels of the direction-only cloud pattern
  uint64_t seed = 3;
};

struct Hit {
  int quad = -1;                                              // -1: no hit (sky)
  double distance = std::numeric_limits<double>::infinity();  // along the (unit) ray, metres
  Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
  Eigen::Vector2d st = Eigen::Vector2d::Zero();  // texture-space coordinates, metres
};

struct World {
  std::vector<Quad> quads;
  std::vector<Material> materials;
  std::shared_ptr<const TextureSet> textures;
  Sky sky;

  // Throws std::invalid_argument for bad material/texture indices or non-orthonormal axes.
  void Check() const;
  // Nearest intersection of the ray origin + d * direction (d > min_distance) with any quad.
  Hit Trace(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
            double min_distance = 1e-6) const;
  // Texture-space (s, t) of a world point on quad `quad`.
  Eigen::Vector2d TextureCoordinates(int quad, const Eigen::Vector3d& p_in_world) const;
  // Albedo (0..255 before photometric effects) of material `material` at (s, t) for a screen
  // pixel footprint of `footprint_m` metres in (s, t).
  float Shade(int material, const Eigen::Vector2d& st, double footprint_m) const;
  // Intensity of the sky in world direction `direction` (unit).
  float SkyIntensity(const Eigen::Vector3d& direction) const;
};

}  // namespace sparseloop::synthetic
