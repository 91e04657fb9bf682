#include "sparseloop/eval/loop_nees.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Eigenvalues>

#include "sparseloop/core/statistics.h"

namespace sparseloop {

Sim3d ExactLoopPose(const Rigid3d& gt_world_from_match, const Rigid3d& gt_world_from_query,
                    double raw_scale_match, double raw_scale_query) {
  if (!(raw_scale_match > 0 && raw_scale_query > 0 && std::isfinite(raw_scale_match) &&
        std::isfinite(raw_scale_query))) {
    throw std::invalid_argument("ExactLoopPose: the raw scales must be positive and finite");
  }
  const Rigid3d metric = gt_world_from_match.Inverse() * gt_world_from_query;
  // A query point in its raw units x_q = s_q X (X in metres); in the match's raw units
  // s_m (R X + t) = (s_m / s_q) R x_q + s_m t.
  return Sim3d(raw_scale_match / raw_scale_query, metric.rotation,
               raw_scale_match * metric.translation);
}

LoopNees ComputeLoopNees(const Sim3d& measured, const Eigen::Matrix<double, 7, 7>& information,
                         const Sim3d& exact) {
  if (!information.allFinite() || (information - information.transpose()).cwiseAbs().maxCoeff() >
                                      1e-9 * std::max(1.0, information.cwiseAbs().maxCoeff())) {
    throw std::invalid_argument("ComputeLoopNees: the information must be finite and symmetric");
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 7, 7>> eig(information);
  const double largest = eig.eigenvalues().maxCoeff();
  if (eig.eigenvalues().minCoeff() < -1e-9 * std::max(largest, 1.0)) {
    throw std::invalid_argument("ComputeLoopNees: the information must be positive semidefinite");
  }
  LoopNees out;
  out.dof = static_cast<int>((eig.eigenvalues().array() > 1e-9 * largest).count());
  const Eigen::Matrix<double, 7, 1> e = (measured.Inverse() * exact).Log();
  out.nees = e.dot(information * e);
  return out;
}

LoopNeesSummary SummarizeLoopNees(const std::vector<LoopNees>& loops) {
  LoopNeesSummary s;
  std::vector<double> ratios;
  int total_dof = 0;
  double total_nees = 0.0;
  for (const LoopNees& l : loops) {
    if (l.dof <= 0) continue;
    ratios.push_back(l.nees / l.dof);
    total_dof += l.dof;
    total_nees += l.nees;
    if (l.nees > ChiSquareQuantile(0.95, l.dof)) ++s.above_95;
    if (l.nees > ChiSquareQuantile(0.9973, l.dof)) ++s.beyond_3_sigma;
  }
  s.loops = static_cast<int>(ratios.size());
  if (ratios.empty()) return s;
  s.mean_ratio = total_nees / total_dof;
  s.median_ratio = Percentile(ratios, 0.5);
  s.p95_ratio = Percentile(ratios, 0.95);
  s.band_low = ChiSquareQuantile(0.025, total_dof) / total_dof;
  s.band_high = ChiSquareQuantile(0.975, total_dof) / total_dof;
  return s;
}

}  // namespace sparseloop
