#pragma once
// How honest a loop's covariance is: the normalised estimation error squared (NEES) of a loop's
// relative pose against the exact one. e = log(measured^-1 * exact), in the pose graph's tangent
// [upsilon (3), omega (3), sigma = log scale] of a right perturbation measured * exp(e) (the
// loop residual's own), and NEES = e^T Omega e with Omega the loop's information; its degrees of
// freedom are the directions Omega observes (rank), so a free scale (PnP) does not count. With a
// covariance that says what the error is, NEES follows chi-square(dof): its mean is dof, and 95 %
// of loops lie below the 95 % quantile.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "sparseloop/core/rigid3.h"
#include "sparseloop/core/sim3.h"

namespace sparseloop {

// The exact match_from_query of a loop on a rendered sequence: the GT poses (metres) and the
// raw trajectory's scale at each of the two keyframes (raw units per GT metre, `raw_scale.txt`
// of `sparseloop render`). Translation in the match's raw units; scale = raw units of the match
// per raw unit of the query (what a Sim(3) loop measures).
Sim3d ExactLoopPose(const Rigid3d& gt_world_from_match, const Rigid3d& gt_world_from_query,
                    double raw_scale_match, double raw_scale_query);

struct LoopNees {
  int64_t query = -1;
  int64_t match = -1;
  int dof = 0;        // rank of the information (eigenvalues above 1e-9 of the largest)
  double nees = 0.0;  // e^T Omega e
};

// Throws std::invalid_argument for an information that is not symmetric positive semidefinite
// or not finite.
LoopNees ComputeLoopNees(const Sim3d& measured, const Eigen::Matrix<double, 7, 7>& information,
                         const Sim3d& exact);

struct LoopNeesSummary {
  int loops = 0;            // loops with dof > 0
  double mean_ratio = 0.0;  // mean of NEES / dof (1 for an honest covariance)
  double median_ratio = 0.0;
  double p95_ratio = 0.0;
  // Average NEES / dof and its two-sided 95 % band for this many loops (sum of NEES against
  // chi-square(sum of dof)): an honest covariance puts mean_ratio inside [band_low, band_high].
  double band_low = 0.0;
  double band_high = 0.0;
  int above_95 = 0;        // loops with NEES above the chi-square(dof) 95 % quantile
  int beyond_3_sigma = 0;  // loops with NEES above the 99.73 % quantile
};

LoopNeesSummary SummarizeLoopNees(const std::vector<LoopNees>& loops);

}  // namespace sparseloop
