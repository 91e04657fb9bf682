#include "sparseloop/synthetic/worlds.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/synthetic/image.h"

namespace sparseloop::synthetic {

// ---------------------------------------------------------------------------------------------
// Aerial

void AerialWorldOptions::Check() const {
  SL_CHECK_MSG(tile_size > 0.0, "tile_size must be > 0 metres, got {}", tile_size);
  SL_CHECK_MSG(texels_per_metre > 0.0, "texels_per_metre must be > 0, got {}", texels_per_metre);
  SL_CHECK_MSG(min_scale > 0.0 && max_scale >= min_scale, "need 0 < min_scale <= max_scale");
  SL_CHECK_MSG(blend_fraction >= 0.0 && blend_fraction <= 0.5,
               "blend_fraction must be in [0, 0.5], got {}", blend_fraction);
}

World MakeAerialWorld(std::shared_ptr<const TextureSet> textures,
                      const AerialWorldOptions& options) {
  options.Check();
  SL_CHECK_MSG(textures != nullptr && !textures->empty(), "aerial world needs textures");
  World world;
  world.textures = std::move(textures);
  Material ground;
  ground.kind = Material::Kind::kMosaic;
  ground.texels_per_metre = options.texels_per_metre;
  ground.tile_size = options.tile_size;
  ground.blend_fraction = options.blend_fraction;
  ground.min_scale = options.min_scale;
  ground.max_scale = options.max_scale;
  ground.seed = options.seed;
  world.materials.push_back(ground);
  Quad plane;
  plane.infinite = true;
  plane.axis_u = Eigen::Vector3d::UnitX();
  plane.axis_v = Eigen::Vector3d::UnitY();
  plane.tex_u = Eigen::Vector3d::UnitX();
  plane.tex_v = Eigen::Vector3d::UnitY();
  world.quads.push_back(plane);
  world.sky.up = Eigen::Vector3d::UnitZ();
  world.Check();
  return world;
}

FlightPlan ParseFlightPlan(const std::string& name) {
  if (name == "circuit") return FlightPlan::kCircuit;
  if (name == "figure8") return FlightPlan::kFigure8;
  if (name == "lawnmower") return FlightPlan::kLawnmower;
  SL_CHECK_MSG(false, "unknown flight plan '{}' (expected circuit, figure8 or lawnmower)", name);
  return FlightPlan::kCircuit;
}

std::string ToString(FlightPlan plan) {
  switch (plan) {
    case FlightPlan::kCircuit:
      return "circuit";
    case FlightPlan::kFigure8:
      return "figure8";
    case FlightPlan::kLawnmower:
      return "lawnmower";
  }
  return "unknown";
}

void FlightPlanOptions::Check() const {
  // Upper bounds keep the plan's cost bounded (its dense path grows with size x laps).
  SL_CHECK_MSG(altitude > 1.0 && altitude <= 1e4, "altitude must be in (1, 10000] metres, got {}",
               altitude);
  SL_CHECK_MSG(size > 1.0 && size <= 1e5, "size must be in (1, 100000] metres, got {}", size);
  SL_CHECK_MSG(tilt_deg >= 0.0 && tilt_deg < 80.0, "tilt_deg must be in [0, 80), got {}", tilt_deg);
  SL_CHECK_MSG(laps >= 1 && laps <= 1000, "laps must be in [1, 1000], got {}", laps);
  SL_CHECK_MSG(lawnmower_strips >= 2, "lawnmower_strips must be >= 2, got {}", lawnmower_strips);
  SL_CHECK_MSG(frames >= 2, "frames must be >= 2, got {}", frames);
  SL_CHECK_MSG(frame_rate_hz > 0.0, "frame_rate_hz must be > 0, got {}", frame_rate_hz);
}

namespace {

std::vector<Eigen::Vector2d> DensePath(const FlightPlanOptions& o) {
  std::vector<Eigen::Vector2d> path;
  const double S = o.size;
  auto arc = [&](const Eigen::Vector2d& c, double r, double a0, double a1) {
    const int n = std::max(8, static_cast<int>(std::abs(a1 - a0) * r / 0.2));
    for (int i = 0; i <= n; ++i) {
      const double a = a0 + (a1 - a0) * i / n;
      path.push_back(c + r * Eigen::Vector2d(std::cos(a), std::sin(a)));
    }
  };
  auto line = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const int n = std::max(2, static_cast<int>((b - a).norm() / 0.2));
    for (int i = 0; i <= n; ++i) path.push_back(a + (b - a) * i / n);
  };
  switch (o.plan) {
    case FlightPlan::kCircuit: {
      // Stadium: straights of 0.5 S, half circles of radius 0.25 S.
      const double L = 0.5 * S, r = 0.25 * S;
      for (int lap = 0; lap < o.laps; ++lap) {
        line({-L / 2, -r}, {L / 2, -r});
        arc({L / 2, 0}, r, -M_PI / 2, M_PI / 2);
        line({L / 2, r}, {-L / 2, r});
        arc({-L / 2, 0}, r, M_PI / 2, 3 * M_PI / 2);
      }
      break;
    }
    case FlightPlan::kFigure8: {
      const double a = 0.5 * S;
      const int n = static_cast<int>(o.laps * 6.0 * a / 0.2);
      for (int i = 0; i <= n; ++i) {
        const double t = 2.0 * M_PI * o.laps * i / n;
        path.push_back({a * std::sin(t), a * std::sin(t) * std::cos(t)});
      }
      break;
    }
    case FlightPlan::kLawnmower: {
      const int k = o.lawnmower_strips;
      const double spacing = S / (k - 1), half = S / 2;
      for (int s = 0; s < k; ++s) {
        const double y = -half + s * spacing;
        const bool east = s % 2 == 0;
        line({east ? -half : half, y}, {east ? half : -half, y});
        if (s + 1 < k) {
          const Eigen::Vector2d c(east ? half : -half, y + spacing / 2);
          if (east)
            arc(c, spacing / 2, -M_PI / 2, M_PI / 2);
          else
            arc(c, spacing / 2, 3 * M_PI / 2, M_PI / 2);
        }
      }
      // Return leg: straight back to the start, across every strip.
      line(path.back(), path.front());
      break;
    }
  }
  return path;
}

}  // namespace

Trajectory MakeFlightTrajectory(const FlightPlanOptions& o) {
  o.Check();
  const std::vector<Eigen::Vector2d> dense = DensePath(o);
  const std::vector<double> cum =
      CumulativePathLength(dense, [](const Eigen::Vector2d& p) { return p; });
  const double total = cum.back();
  std::vector<Eigen::Vector2d> xy(o.frames);
  size_t j = 0;
  for (int i = 0; i < o.frames; ++i) {
    const double s = total * i / (o.frames - 1);
    while (j + 2 < dense.size() && cum[j + 1] < s) ++j;
    const double seg = std::max(cum[j + 1] - cum[j], 1e-12);
    const double w = std::clamp((s - cum[j]) / seg, 0.0, 1.0);
    xy[i] = dense[j] + w * (dense[j + 1] - dense[j]);
  }
  Trajectory traj;
  traj.has_timestamps = true;
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  const double tilt = o.tilt_deg * M_PI / 180.0;
  Eigen::Vector3d last_forward = Eigen::Vector3d::UnitX();
  for (int i = 0; i < o.frames; ++i) {
    const int a = std::max(0, i - 1), b = std::min(o.frames - 1, i + 1);
    Eigen::Vector2d t2 = xy[b] - xy[a];
    Eigen::Vector3d forward = last_forward;
    if (t2.norm() > 1e-9) forward = Eigen::Vector3d(t2.x(), t2.y(), 0.0).normalized();
    last_forward = forward;
    const Eigen::Vector3d z = (std::cos(tilt) * (-up) + std::sin(tilt) * forward).normalized();
    const Eigen::Vector3d x = forward.cross(up).normalized();
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Matrix3d R;
    R.col(0) = x, R.col(1) = y, R.col(2) = z;
    StampedPose pose;
    pose.frame = i;
    pose.timestamp = i / o.frame_rate_hz;
    pose.world_from_cam =
        Rigid3d(Eigen::Quaterniond(R), Eigen::Vector3d(xy[i].x(), xy[i].y(), o.altitude));
    traj.poses.push_back(pose);
  }
  return traj;
}

CameraIntrinsics DefaultAerialCamera() {
  CameraIntrinsics c;
  c.fx = c.fy = 500.0;
  c.cx = 319.5;
  c.cy = 239.5;
  c.width = 640;
  c.height = 480;
  return c;
}

// ---------------------------------------------------------------------------------------------
// Street

void StreetWorldOptions::Check() const {
  SL_CHECK_MSG(segment_length >= 1.0, "segment_length must be >= 1 metre, got {}", segment_length);
  SL_CHECK_MSG(lateral_offset > 0.0, "lateral_offset must be > 0, got {}", lateral_offset);
  SL_CHECK_MSG(camera_height > 0.0, "camera_height must be > 0, got {}", camera_height);
  SL_CHECK_MSG(min_facade_height > 0.0 && max_facade_height >= min_facade_height,
               "need 0 < min_facade_height <= max_facade_height");
  SL_CHECK_MSG(ground_half_width > 0.0, "ground_half_width must be > 0");
  SL_CHECK_MSG(merge_distance >= 0.0, "merge_distance must be >= 0");
  SL_CHECK_MSG(road_clearance >= 0.0 && road_clearance < lateral_offset,
               "road_clearance must be in [0, lateral_offset), got {}", road_clearance);
  SL_CHECK_MSG(facade_cell > 0.0, "facade_cell must be > 0");
  SL_CHECK_MSG(facade_texels_per_metre > 0.0 && ground_texels_per_metre > 0.0,
               "texels_per_metre must be > 0");
  SL_CHECK_MSG(std::abs(down.norm() - 1.0) < 1e-6, "down must be a unit vector");
}

namespace {

struct CellKey {
  int64_t x, y, z;
  bool operator==(const CellKey&) const = default;
};
struct CellHash {
  size_t operator()(const CellKey& k) const { return HashCombine(1, k.x, k.y, k.z); }
};
CellKey CellOf(const Eigen::Vector3d& p, double cell) {
  return {static_cast<int64_t>(std::floor(p.x() / cell)),
          static_cast<int64_t>(std::floor(p.y() / cell)),
          static_cast<int64_t>(std::floor(p.z() / cell))};
}

// Segments already placed, for the revisit merge.
class SegmentIndex {
 public:
  explicit SegmentIndex(double cell) : cell_(cell) {}
  bool HasParallelNear(const Eigen::Vector3d& c, const Eigen::Vector3d& d, double radius) const {
    const CellKey k = CellOf(c, cell_);
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz) {
          auto it = cells_.find({k.x + dx, k.y + dy, k.z + dz});
          if (it == cells_.end()) continue;
          for (const auto& e : it->second) {
            if (std::abs(d.dot(e.d)) < 0.8) continue;
            const Eigen::Vector3d r = c - e.c;
            const double along = r.dot(e.d);
            if (std::abs(along) > e.half_length) continue;
            if ((r - along * e.d).norm() < radius) return true;
          }
        }
    return false;
  }
  void Add(const Eigen::Vector3d& c, const Eigen::Vector3d& d, double half_length) {
    cells_[CellOf(c, cell_)].push_back({c, d, half_length});
  }

 private:
  struct Entry {
    Eigen::Vector3d c, d;
    double half_length;
  };
  double cell_;
  std::unordered_map<CellKey, std::vector<Entry>, CellHash> cells_;
};

double PointSegmentDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                            const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

// Indices where the trajectory is cut into street segments of about segment_length of path
// (first and last pose included).
std::vector<size_t> SegmentCuts(const std::vector<Eigen::Vector3d>& positions,
                                double segment_length) {
  std::vector<size_t> cuts = {0};
  double acc = 0.0;
  for (size_t i = 1; i < positions.size(); ++i) {
    acc += (positions[i] - positions[i - 1]).norm();
    if (acc >= segment_length) {
      cuts.push_back(i);
      acc = 0.0;
    }
  }
  if (cuts.back() != positions.size() - 1) cuts.push_back(positions.size() - 1);
  return cuts;
}

// Trajectory positions by grid cell, for the road clearance test: does a segment pass closer
// than `clearance` to any pose?
class PoseProximity {
 public:
  PoseProximity(const std::vector<Eigen::Vector3d>& positions, double clearance)
      : positions_(positions), clearance_(clearance), cell_(std::max(clearance, 1.0)) {
    for (size_t i = 0; i < positions.size(); ++i) cells_[CellOf(positions[i], cell_)].push_back(i);
  }
  bool NearSegment(const Eigen::Vector3d& a, const Eigen::Vector3d& b) const {
    const CellKey ka = CellOf(a.cwiseMin(b), cell_), kb = CellOf(a.cwiseMax(b), cell_);
    for (int64_t x = ka.x - 1; x <= kb.x + 1; ++x)
      for (int64_t y = ka.y - 1; y <= kb.y + 1; ++y)
        for (int64_t z = ka.z - 1; z <= kb.z + 1; ++z) {
          auto it = cells_.find({x, y, z});
          if (it == cells_.end()) continue;
          for (size_t i : it->second)
            if (PointSegmentDistance(positions_[i], a, b) < clearance_) return true;
        }
    return false;
  }

 private:
  const std::vector<Eigen::Vector3d>& positions_;
  double clearance_, cell_;
  std::unordered_map<CellKey, std::vector<size_t>, CellHash> cells_;
};

// A facade's material and height, drawn from the seed of its grid cell (the same facade on a
// revisit).
Material FacadeMaterial(const StreetWorldOptions& o, const Eigen::Vector3d& centre,
                        size_t num_textures, double* height) {
  const CellKey cell = CellOf(centre, o.facade_cell);
  SplitMix64 rng(HashCombine(o.seed, cell.x, cell.y, cell.z));
  *height = rng.Uniform(o.min_facade_height, o.max_facade_height);
  Material m;
  m.kind = Material::Kind::kTexture;
  m.texture = static_cast<int>(rng.Next() % num_textures);
  m.texels_per_metre = o.facade_texels_per_metre * rng.Uniform(0.75, 1.3);
  m.offset_texels = {rng.Uniform() * 4096.0, rng.Uniform() * 4096.0};
  m.gain = static_cast<float>(rng.Uniform(0.75, 1.15));
  return m;
}

// Fallback ground plane, seen only through gaps between strips: below the LOWEST road point so
// that it can never hang above a camera on a hilly trajectory.
Quad FallbackGround(const std::vector<Eigen::Vector3d>& positions, const StreetWorldOptions& o,
                    const Eigen::Vector3d& tex_u, const Eigen::Vector3d& tex_v) {
  double lowest = -std::numeric_limits<double>::infinity();
  for (const auto& p : positions) lowest = std::max(lowest, p.dot(o.down));
  Quad plane;
  plane.infinite = true;
  plane.axis_u = tex_u;
  plane.axis_v = tex_v;
  plane.origin = (lowest + o.camera_height + 0.5) * o.down;
  plane.material = 0;
  plane.tex_u = tex_u;
  plane.tex_v = tex_v;
  return plane;
}

}  // namespace

World MakeStreetWorld(const Trajectory& trajectory, std::shared_ptr<const TextureSet> textures,
                      const StreetWorldOptions& o) {
  o.Check();
  SL_CHECK_MSG(textures != nullptr && !textures->empty(), "street world needs textures");
  SL_CHECK_MSG(trajectory.size() >= 2, "street world needs a trajectory of >= 2 poses");
  World world;
  world.textures = std::move(textures);
  const size_t num_textures = world.textures->size();
  const Eigen::Vector3d down = o.down;
  const Eigen::Vector3d g = o.camera_height * down;
  // World-anchored ground texture axes (perpendicular to down).
  Eigen::Vector3d tex_u = down.unitOrthogonal();
  Eigen::Vector3d tex_v = down.cross(tex_u).normalized();

  Material ground_material;
  ground_material.kind = Material::Kind::kMosaic;
  ground_material.texels_per_metre = o.ground_texels_per_metre;
  ground_material.tile_size = 8.0;
  ground_material.gain = 0.8f;
  ground_material.seed = HashCombine(o.seed, 99);
  world.materials.push_back(ground_material);

  const std::vector<Eigen::Vector3d> positions = trajectory.Positions();
  // Segment boundaries by path length.
  const std::vector<size_t> cuts = SegmentCuts(positions, o.segment_length);
  const PoseProximity poses(positions, o.road_clearance);

  SegmentIndex ground_index(20.0), facade_index(20.0);
  size_t merged = 0, cleared = 0;
  for (size_t s = 0; s + 1 < cuts.size(); ++s) {
    const Eigen::Vector3d A = positions[cuts[s]], B = positions[cuts[s + 1]];
    const double L = (B - A).norm();
    if (L < 0.5) continue;
    const Eigen::Vector3d u = (B - A) / L;
    const Eigen::Vector3d lat_raw = down.cross(u);
    if (lat_raw.norm() < 1e-3) continue;  // vertical motion: no street
    const Eigen::Vector3d lat = lat_raw.normalized();
    const Eigen::Vector3d centre = 0.5 * (A + B);
    const double overlap = 0.3;

    if (!ground_index.HasParallelNear(centre + g, u, o.merge_distance)) {
      ground_index.Add(centre + g, u, 0.5 * L);
      Quad q;
      q.axis_u = u;
      q.axis_v = lat;
      // The first and last strips reach 30 m beyond the trajectory ends.
      const double before = s == 0 ? 30.0 : overlap;
      const double after = s + 2 == cuts.size() ? 30.0 : overlap;
      q.size_u = L + before + after;
      q.size_v = 2 * o.ground_half_width;
      q.origin = A + g - before * u - o.ground_half_width * lat;
      q.material = 0;
      q.tex_origin = Eigen::Vector3d::Zero();
      q.tex_u = tex_u;
      q.tex_v = tex_v;
      world.quads.push_back(q);
    }
    const Eigen::Vector3d v = (down - down.dot(u) * u).normalized();
    for (int side : {-1, 1}) {
      const Eigen::Vector3d offset = side * o.lateral_offset * lat;
      const Eigen::Vector3d c = centre + offset;
      if (facade_index.HasParallelNear(c, u, o.merge_distance)) {
        ++merged;
        continue;
      }
      facade_index.Add(c, u, 0.5 * L);
      if (poses.NearSegment(A + offset, B + offset)) {
        ++cleared;
        continue;
      }
      double height = 0.0;
      world.materials.push_back(FacadeMaterial(o, c, num_textures, &height));
      Quad q;
      q.axis_u = u;
      q.axis_v = v;
      q.size_u = L + 2 * overlap;
      q.size_v = height + o.camera_height + 1.0;  // reaches 1 m below the road
      q.origin = A + offset - overlap * u - height * v;
      q.material = static_cast<int>(world.materials.size() - 1);
      q.tex_origin = q.origin;
      q.tex_u = u;
      q.tex_v = v;
      world.quads.push_back(q);
    }
  }
  world.quads.push_back(FallbackGround(positions, o, tex_u, tex_v));
  world.sky.up = -down;
  Logger().info(
      "street world: {} quads ({} segments, {} facades merged on revisits, {} removed "
      "for road clearance)",
      world.quads.size(), cuts.size() - 1, merged, cleared);
  world.Check();
  return world;
}

CameraIntrinsics KittiCam0Intrinsics(int sequence) {
  SL_CHECK_MSG(sequence >= 0 && sequence <= 12, "KITTI sequence must be in 0..12, got {}",
               sequence);
  CameraIntrinsics c;
  if (sequence <= 2) {
    c.fx = c.fy = 718.856, c.cx = 607.1928, c.cy = 185.2157, c.width = 1241, c.height = 376;
  } else if (sequence == 3) {
    c.fx = c.fy = 721.5377, c.cx = 609.5593, c.cy = 172.854, c.width = 1242, c.height = 375;
  } else {
    c.fx = c.fy = 707.0912, c.cx = 601.8873, c.cy = 183.1104, c.width = 1226, c.height = 370;
  }
  return c;
}

}  // namespace sparseloop::synthetic
