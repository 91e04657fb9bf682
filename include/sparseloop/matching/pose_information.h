#pragma once
// How well a verified relative pose is known: the information (inverse covariance) of
// match_from_query from the inlier correspondences at the solution, in the tangent order of the
// pose graph, [upsilon (3), omega (3), sigma = log scale], for a right perturbation
// match_from_query * exp(d). This is what a loop edge needs: a loop verified by many well-spread
// inliers is as tight as its geometry says, a weak one is loose (docs/POSEGRAPH.md, "Loop
// information").
//
// Gauss-Newton at the solution: information = J^T J / sigma^2, J the Jacobian of the normalised
// reprojection residuals with respect to d, sigma^2 the residuals' own variance
// (sum r^2 / (2n - 6)), floored at min_sigma (a handful of near-perfect inliers must not claim
// a sub-pixel pose). Unobservable directions come out as the null space of J^T J: PnP against
// points in the match frame leaves the relative scale free, points in the query frame leave the
// combination [R^T t / s, 0, 1] free (scaling the query's cloud about the match camera).
#include <vector>

#include <Eigen/Core>

#include "sparseloop/core/sim3.h"

namespace sparseloop {

using PoseInformation7 = Eigen::Matrix<double, 7, 7>;

struct PoseInformationOptions {
  double min_sigma =
      0.5 / 500.0;  // floor of the residual sigma, normalised units (0.5 px at f=500)
  // The inliers were selected by |r| <= inlier_threshold (normalised units; 0 = not truncated):
  // their mean squared residual then underestimates the noise (2D Gaussian noise of sigma 1.4 px
  // cut at 2 px keeps residuals with 0.42 x its second moment), so sigma is solved from the
  // truncated second moment E[r^2 | r < R] = 2 sigma^2 (1 - x e^-x / (1 - e^-x)), x = R^2 / 2
  // sigma^2.
  double inlier_threshold = 0.0;
  void Check() const;
};

// The per-axis sigma of 2D Gaussian residuals whose radius was cut at `threshold` (0: not cut)
// and whose mean squared norm is `mean_r2` (all in the same units). Exposed for its test.
double TruncatedResidualSigma(double mean_r2, double threshold);

// PnP with the 3D points in the MATCH frame observed in the QUERY image (normalised coordinates
// x = (X/Z, Y/Z)); `match_from_query` the verified pose. Points behind the query camera are
// skipped. Zero when fewer than 4 usable points.
PoseInformation7 PnpInformationPointsInMatch(const std::vector<Eigen::Vector3d>& p_in_match,
                                             const std::vector<Eigen::Vector2d>& x_in_query,
                                             const Sim3d& match_from_query,
                                             const PoseInformationOptions& options = {});

// PnP with the 3D points in the QUERY frame observed in the MATCH image.
PoseInformation7 PnpInformationPointsInQuery(const std::vector<Eigen::Vector3d>& p_in_query,
                                             const std::vector<Eigen::Vector2d>& x_in_match,
                                             const Sim3d& match_from_query,
                                             const PoseInformationOptions& options = {});

// 3D-3D Sim(3) (both sides have depths, point i of the query frame corresponds to point i of the
// match frame): both reprojection directions above, plus the relative scale from the depths
// themselves: each pair's log depth ratio log(z(match_from_query * q_i) / z(m_i)) has the scale
// as its mean, so the scale's information is n / var(log ratio) (floored like the residuals,
// 1e-3). With a short loop baseline the reprojections alone hardly see the scale; the depths do.
PoseInformation7 Sim3Information(const std::vector<Eigen::Vector3d>& p_in_query,
                                 const std::vector<Eigen::Vector3d>& p_in_match,
                                 const Sim3d& match_from_query,
                                 const PoseInformationOptions& options = {});

}  // namespace sparseloop
