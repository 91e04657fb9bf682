#include "sparseloop/core/trajectory.h"

namespace sparseloop {

std::vector<Eigen::Vector3d> Trajectory::Positions() const {
  std::vector<Eigen::Vector3d> out;
  out.reserve(poses.size());
  for (const auto& p : poses) out.push_back(p.world_from_cam.translation);
  return out;
}

std::vector<double> Trajectory::CumulativeDistances() const {
  std::vector<double> out(poses.size(), 0.0);
  for (size_t i = 1; i < poses.size(); ++i) {
    out[i] = out[i - 1] +
             (poses[i].world_from_cam.translation - poses[i - 1].world_from_cam.translation).norm();
  }
  return out;
}

}  // namespace sparseloop
