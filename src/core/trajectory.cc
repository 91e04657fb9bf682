#include "sparseloop/core/trajectory.h"

namespace sparseloop {

std::vector<Eigen::Vector3d> Trajectory::Positions() const {
  std::vector<Eigen::Vector3d> out;
  out.reserve(poses.size());
  for (const auto& p : poses) out.push_back(p.world_from_cam.translation);
  return out;
}

std::vector<double> Trajectory::CumulativeDistances() const {
  return CumulativePathLength(poses,
                              [](const StampedPose& p) { return p.world_from_cam.translation; });
}

}  // namespace sparseloop
