#pragma once
// Association of an estimated trajectory with ground truth.
//
// kTimestamp: TimePairing::kOneToOne of core/time_association.h (TUM associate.py, with
//   |(est.t_i + offset) - gt.t_j| <= max_dt): candidates taken greedily by increasing |dt| (ties:
//   lower est index, then the earlier gt pose), each est pose and each gt pose at most once. A
//   GT pose is never counted twice. evo's associate_trajectories takes the nearest stamp for each
//   pose of the shorter trajectory without the uniqueness rule (kNearest); the two agree whenever
//   max_dt is below half the smaller sampling period (the usual case).
// kIndex: est pose with StampedPose::frame == f is paired with the gt pose with frame f.
//
// Pairs are returned sorted by est index (then gt index is increasing too for monotonic inputs).
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "sparseloop/core/trajectory.h"

namespace sparseloop {

enum class AssociationMethod { kTimestamp, kIndex };

// "time" / "timestamp" -> kTimestamp, "index" -> kIndex; else std::invalid_argument.
AssociationMethod ParseAssociationMethod(const std::string& name);
std::string ToString(AssociationMethod method);

struct AssociationOptions {
  AssociationMethod method = AssociationMethod::kTimestamp;
  double max_dt = 0.02;  // seconds; largest accepted |dt| (kTimestamp only), >= 0
  double offset = 0.0;   // seconds added to estimate timestamps before matching (kTimestamp only)
  void Check() const;
};

struct Association {
  std::vector<std::pair<size_t, size_t>> pairs;  // (est index, gt index) into Trajectory::poses
};

// Throws std::invalid_argument for invalid options or (kIndex) duplicated frame ids in either
// trajectory.
Association Associate(const Trajectory& est, const Trajectory& gt,
                      const AssociationOptions& options = {});

}  // namespace sparseloop
