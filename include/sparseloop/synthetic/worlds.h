#pragma once
// Built-in worlds and trajectories: `aerial` (drone over a non-repeating ground mosaic, with
// flight plans that revisit places) and `street` (KITTI-like: facades along a given trajectory).
#include <cstdint>
#include <memory>
#include <string>

#include <Eigen/Core>

#include "sparseloop/core/camera.h"
#include "sparseloop/core/trajectory.h"
#include "sparseloop/synthetic/world.h"

namespace sparseloop::synthetic {

// ---------------------------------------------------------------------------------------------
// Aerial world. World frame: x east, y north, z up; the ground is the plane z = 0.
struct AerialWorldOptions {
  double tile_size = 24.0;         // metres, side of one mosaic tile
  double texels_per_metre = 20.0;  // texture resolution on the ground (before per-tile scale)
  double min_scale = 0.7;          // per-tile scale range of the texture mapping
  double max_scale = 1.4;
  double blend_fraction = 0.15;  // fraction of a tile cross-faded with its neighbour
  uint64_t seed = 11;            // tile hash seed
  void Check() const;
};
World MakeAerialWorld(std::shared_ptr<const TextureSet> textures,
                      const AerialWorldOptions& options = {});

enum class FlightPlan {
  kCircuit,    // a rounded rectangle flown `laps` times
  kFigure8,    // a lemniscate flown `laps` times (crosses itself in the middle)
  kLawnmower,  // back-and-forth strips, then a diagonal return leg across all of them
};
// "circuit", "figure8", "lawnmower"; anything else throws std::invalid_argument.
FlightPlan ParseFlightPlan(const std::string& name);
std::string ToString(FlightPlan plan);

struct FlightPlanOptions {
  FlightPlan plan = FlightPlan::kCircuit;
  double altitude = 40.0;       // metres above the ground
  double size = 200.0;          // metres, side of the area the plan covers
  double tilt_deg = 0.0;        // degrees from nadir, towards the direction of flight
  int laps = 2;                 // circuit / figure8: number of laps
  int lawnmower_strips = 5;     // lawnmower: number of strips
  int frames = 2000;            // frames sampled uniformly along the path
  double frame_rate_hz = 10.0;  // timestamps = index / frame_rate_hz
  void Check() const;
};
// Camera poses (world_from_cam, camera x right, y down, z forward) along the plan, heading along
// the direction of flight. Timestamps index / frame_rate_hz.
Trajectory MakeFlightTrajectory(const FlightPlanOptions& options);

// Downward-looking default camera: 640x480, fx = fy = 500 (about 65 deg horizontal FOV).
CameraIntrinsics DefaultAerialCamera();

// ---------------------------------------------------------------------------------------------
// Street world along a KITTI-style trajectory (camera x right, y down, z forward; the ground is
// roughly the x-z plane and "down" is +y).
//
// Geometry: the trajectory is cut into segments of `segment_length` metres of path. Each segment
// gets a ground strip (road + pavement, at camera_height below the camera) and two facades at
// +-lateral_offset, with a hashed height. Revisits: a new segment whose facade (or ground strip)
// would lie within `merge_distance` of an existing, parallel one (either direction) is dropped,
// so the second pass sees the very quads of the first pass. Cross streets: facades that come
// within `road_clearance` of ANY trajectory pose are removed, so the car never drives into a wall
// and intersections open up. Texture: each facade's (texture, offset, scale, albedo) is a hash of
// the world grid cell (facade_cell metres) of its centre, its (s, t) frame is anchored on the quad
// itself; the ground uses a world-anchored mosaic on world (x, z). Nothing depends on time.
struct StreetWorldOptions {
  double segment_length = 10.0;     // metres of path per facade / ground quad
  double lateral_offset = 8.0;      // metres, facade distance from the trajectory
  double camera_height = 1.65;      // metres, camera above the road (KITTI cam0)
  double min_facade_height = 6.0;   // metres
  double max_facade_height = 22.0;  // metres
  double ground_half_width = 14.0;  // metres, lateral half-width of the ground strips
  double merge_distance = 4.0;      // metres, revisit merge radius
  double road_clearance = 5.0;      // metres, facades closer than this to any pose are removed
  double facade_cell = 10.0;        // metres, world grid cell hashed for the facade texture
  double facade_texels_per_metre = 48.0;            // texture resolution on facades
  double ground_texels_per_metre = 64.0;            // texture resolution on the ground
  Eigen::Vector3d down = Eigen::Vector3d::UnitY();  // world "down" (KITTI: +y)
  uint64_t seed = 13;
  void Check() const;
};
World MakeStreetWorld(const Trajectory& trajectory, std::shared_ptr<const TextureSet> textures,
                      const StreetWorldOptions& options = {});

// KITTI odometry rectified cam0 intrinsics for sequence 0..21 (00-02, 03, 04-21 calibrations).
// Throws std::invalid_argument outside 0..21.
CameraIntrinsics KittiCam0Intrinsics(int sequence);

}  // namespace sparseloop::synthetic
