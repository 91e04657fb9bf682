#pragma once
// A camera trajectory as read from or written to a file.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "sparseloop/core/rigid3.h"

namespace sparseloop {

struct StampedPose {
  double timestamp = 0.0;  // seconds; for index-only formats, equal to `frame`
  int64_t frame = 0;       // frame index (file order unless the file gives one)
  Rigid3d world_from_cam;  // camera (or body) pose in the trajectory's world frame
};

struct Trajectory {
  std::vector<StampedPose> poses;
  // False for positions-only files: orientations are identity and must not be evaluated.
  bool has_rotation = true;
  // False for formats that carry no time (KITTI, positions-only): timestamps equal frame indices.
  bool has_timestamps = true;

  size_t size() const { return poses.size(); }
  bool empty() const { return poses.empty(); }
  std::vector<Eigen::Vector3d> Positions() const;
  // Cumulative path length at each pose (metres or trajectory units), first entry 0.
  std::vector<double> CumulativeDistances() const;
};

}  // namespace sparseloop
