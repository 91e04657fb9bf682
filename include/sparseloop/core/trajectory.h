#pragma once
// A camera trajectory as read from or written to a file.
#include <cstdint>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include "sparseloop/core/rigid3.h"
#include "sparseloop/core/time_association.h"

namespace sparseloop {

// The one cumulative path length: entry i is the sum of |p_k - p_(k-1)| for 0 < k <= i (entry 0
// is 0), p_k = position_of(elements[k]) (any Eigen vector). Trajectory::CumulativeDistances, the
// KITTI metric and the flight planner use it; SearchArea keeps the same sum incrementally.
template <typename Range, typename PositionOf>
std::vector<double> CumulativePathLength(const Range& elements, PositionOf position_of) {
  std::vector<double> out(std::size(elements), 0.0);
  for (size_t i = 1; i < out.size(); ++i)
    out[i] = out[i - 1] + (position_of(elements[i]) - position_of(elements[i - 1])).norm();
  return out;
}

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

// NearestInTime (core/time_association.h) over a trajectory's poses (sorted by timestamp, as the
// readers guarantee).
inline std::optional<size_t> NearestPoseInTime(const Trajectory& trajectory, double t,
                                               double max_dt) {
  return NearestInTime(trajectory.poses, t, max_dt,
                       [](const StampedPose& p) { return p.timestamp; });
}

}  // namespace sparseloop
