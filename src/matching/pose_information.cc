#include "sparseloop/matching/pose_information.h"

#include <algorithm>
#include <cmath>

#include "sparseloop/core/check.h"
#include "sparseloop/core/rigid3.h"

namespace sparseloop {

void PoseInformationOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(min_sigma) && min_sigma > 0,
               "pose information min_sigma must be > 0 (normalised units), got {}", min_sigma);
  SL_CHECK_MSG(std::isfinite(inlier_threshold) && inlier_threshold >= 0,
               "pose information inlier_threshold must be >= 0, got {}", inlier_threshold);
}

double TruncatedResidualSigma(double mean_r2, double threshold) {
  if (!(mean_r2 > 0)) return 0.0;
  if (!(threshold > 0)) return std::sqrt(0.5 * mean_r2);
  // m(sigma) = E[r^2 | r < R] grows monotonically from 0 (sigma -> 0) to R^2 / 2 (sigma -> inf,
  // uniform over the disc); bisection on log sigma.
  const double r2 = threshold * threshold;
  auto moment = [&](double sigma) {
    const double x = r2 / (2.0 * sigma * sigma);
    if (x > 50.0) return 2.0 * sigma * sigma;
    const double e = std::exp(-x);
    return 2.0 * sigma * sigma * (1.0 - x * e / (1.0 - e));
  };
  if (mean_r2 >= 0.49 * r2) return 10.0 * threshold;  // as flat as a uniform disc: no bound
  double lo = 1e-6 * threshold, hi = 100.0 * threshold;
  for (int i = 0; i < 100; ++i) {
    const double mid = std::sqrt(lo * hi);
    (moment(mid) < mean_r2 ? lo : hi) = mid;
  }
  return std::sqrt(lo * hi);
}

namespace {

using Matrix27 = Eigen::Matrix<double, 2, 7>;
using Matrix37 = Eigen::Matrix<double, 3, 7>;

// d pi(p) / d p for pi(p) = (x / z, y / z).
Eigen::Matrix<double, 2, 3> ProjectionJacobian(const Eigen::Vector3d& p) {
  const double iz = 1.0 / p.z();
  Eigen::Matrix<double, 2, 3> j;
  j << iz, 0.0, -p.x() * iz * iz, 0.0, iz, -p.y() * iz * iz;
  return j;
}

// Accumulates J^T J and the squared residuals of one reprojection direction; `point_jacobian`
// gives the camera-frame point and its 3x7 Jacobian with respect to d for correspondence i.
template <typename PointFn>
PoseInformation7 ReprojectionInformation(size_t n, const std::vector<Eigen::Vector2d>& observed,
                                         PointFn point_jacobian,
                                         const PoseInformationOptions& options) {
  options.Check();
  PoseInformation7 jtj = PoseInformation7::Zero();
  double sum_r2 = 0.0;
  int used = 0;
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector3d p;
    Matrix37 dp;
    point_jacobian(i, &p, &dp);
    if (!(p.z() > 1e-9) || !p.allFinite()) continue;
    const Eigen::Vector2d r = p.head<2>() / p.z() - observed[i];
    const Matrix27 j = ProjectionJacobian(p) * dp;
    jtj.noalias() += j.transpose() * j;
    sum_r2 += r.squaredNorm();
    ++used;
  }
  if (used < 4) return PoseInformation7::Zero();
  // Mean squared residual norm with the 6 fitted parameters taken out, then the truncation.
  const double mean_r2 = 2.0 * sum_r2 / std::max(1, 2 * used - 6);
  const double sigma = TruncatedResidualSigma(mean_r2, options.inlier_threshold);
  const double sigma2 = std::max(sigma * sigma, options.min_sigma * options.min_sigma);
  return jtj / sigma2;
}

}  // namespace

PoseInformation7 PnpInformationPointsInMatch(const std::vector<Eigen::Vector3d>& p_in_match,
                                             const std::vector<Eigen::Vector2d>& x_in_query,
                                             const Sim3d& match_from_query,
                                             const PoseInformationOptions& options) {
  SL_CHECK_MSG(p_in_match.size() == x_in_query.size(), "{} points for {} observations",
               p_in_match.size(), x_in_query.size());
  const Sim3d query_from_match = match_from_query.Inverse();
  // p = (Z exp(d))^-1 P = exp(-d) Z^-1 P ~ p - upsilon - omega x p - sigma p.
  return ReprojectionInformation(
      p_in_match.size(), x_in_query,
      [&](size_t i, Eigen::Vector3d* p, Matrix37* dp) {
        *p = query_from_match * p_in_match[i];
        dp->block<3, 3>(0, 0) = -Eigen::Matrix3d::Identity();
        dp->block<3, 3>(0, 3) = Hat(*p);
        dp->col(6) = -*p;
      },
      options);
}

PoseInformation7 PnpInformationPointsInQuery(const std::vector<Eigen::Vector3d>& p_in_query,
                                             const std::vector<Eigen::Vector2d>& x_in_match,
                                             const Sim3d& match_from_query,
                                             const PoseInformationOptions& options) {
  SL_CHECK_MSG(p_in_query.size() == x_in_match.size(), "{} points for {} observations",
               p_in_query.size(), x_in_match.size());
  const Eigen::Matrix3d sr = match_from_query.scale * match_from_query.rotation.toRotationMatrix();
  // p = Z exp(d) Q ~ Z (Q + upsilon + omega x Q + sigma Q).
  return ReprojectionInformation(
      p_in_query.size(), x_in_match,
      [&](size_t i, Eigen::Vector3d* p, Matrix37* dp) {
        const Eigen::Vector3d& q = p_in_query[i];
        *p = match_from_query * q;
        dp->block<3, 3>(0, 0) = sr;
        dp->block<3, 3>(0, 3) = -sr * Hat(q);
        dp->col(6) = sr * q;
      },
      options);
}

PoseInformation7 Sim3Information(const std::vector<Eigen::Vector3d>& p_in_query,
                                 const std::vector<Eigen::Vector3d>& p_in_match,
                                 const Sim3d& match_from_query,
                                 const PoseInformationOptions& options) {
  SL_CHECK_MSG(p_in_query.size() == p_in_match.size(), "{} query points for {} match points",
               p_in_query.size(), p_in_match.size());
  auto normalised = [](const std::vector<Eigen::Vector3d>& pts) {
    std::vector<Eigen::Vector2d> x;
    x.reserve(pts.size());
    for (const auto& p : pts) x.emplace_back(p.head<2>() / p.z());
    return x;
  };
  PoseInformation7 info =
      PnpInformationPointsInMatch(p_in_match, normalised(p_in_query), match_from_query, options) +
      PnpInformationPointsInQuery(p_in_query, normalised(p_in_match), match_from_query, options);
  // Scale from the depths: log z(Z q_i) - log z(m_i) = sigma + noise, per pair.
  std::vector<double> ratios;
  for (size_t i = 0; i < p_in_query.size(); ++i) {
    const double zq = (match_from_query * p_in_query[i]).z();
    const double zm = p_in_match[i].z();
    if (zq > 1e-9 && zm > 1e-9) ratios.push_back(std::log(zq / zm));
  }
  if (ratios.size() >= 4) {
    double mean = 0.0;
    for (double r : ratios) mean += r;
    mean /= static_cast<double>(ratios.size());
    double var = 0.0;
    for (double r : ratios) var += (r - mean) * (r - mean);
    var = std::max(var / static_cast<double>(ratios.size() - 1), 1e-6);
    info(6, 6) += static_cast<double>(ratios.size()) / var;
  }
  return info;
}

}  // namespace sparseloop
