#pragma once
// A minimal, RANSAC-friendly Sim(3) estimator from 3D-3D correspondences (Umeyama 1991).
// eval/align.h has a trajectory-alignment Umeyama too; matching must not depend on eval, so this
// small solver lives here and is used inside RANSAC for loop edges that carry the scale.
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "sparseloop/core/sim3.h"

namespace sparseloop {

// Least-squares target_from_source with p_target ~= s R p_source + t (with_scale = false fixes
// s = 1). nullopt for fewer than 3 points or a degenerate (collinear) configuration.
std::optional<Sim3d> UmeyamaSim3(const std::vector<Eigen::Vector3d>& p_source,
                                 const std::vector<Eigen::Vector3d>& p_target,
                                 bool with_scale = true);

struct Sim3RansacOptions {
  double max_error = 0.05;   // inlier threshold on the normalised reprojection error in both
                             // cameras (pixels / focal), unitless
  int max_iterations = 200;  // RANSAC hypotheses, count
  int min_inliers = 6;       // fewer inliers = failure, count
  uint64_t seed = 42;        // sampling seed
  void Check() const;
};

struct Sim3RansacResult {
  bool success = false;
  Sim3d target_from_source;  // refined on all inliers
  std::vector<int> inliers;  // indices into the input correspondences
};

// RANSAC over 3-point Umeyama hypotheses; a correspondence is an inlier when the source point maps
// into the target camera (and the target into the source camera) within max_error of its
// normalised projection. Points are in their camera frames (z forward). Deterministic.
Sim3RansacResult RansacSim3(const std::vector<Eigen::Vector3d>& p_source,
                            const std::vector<Eigen::Vector3d>& p_target,
                            const Sim3RansacOptions& options);

}  // namespace sparseloop
