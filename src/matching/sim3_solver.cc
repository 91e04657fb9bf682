#include "sparseloop/matching/sim3_solver.h"

#include <cmath>
#include <random>

#include <Eigen/SVD>

#include "sparseloop/core/check.h"

namespace sparseloop {

std::optional<Sim3d> UmeyamaSim3(const std::vector<Eigen::Vector3d>& p_source,
                                 const std::vector<Eigen::Vector3d>& p_target, bool with_scale) {
  SL_CHECK_MSG(p_source.size() == p_target.size(), "UmeyamaSim3: {} source vs {} target points",
               p_source.size(), p_target.size());
  const size_t n = p_source.size();
  if (n < 3) return std::nullopt;
  Eigen::Vector3d mu_s = Eigen::Vector3d::Zero(), mu_t = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mu_s += p_source[i];
    mu_t += p_target[i];
  }
  mu_s /= double(n);
  mu_t /= double(n);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double var_s = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d a = p_source[i] - mu_s;
    const Eigen::Vector3d b = p_target[i] - mu_t;
    cov += b * a.transpose();
    var_s += a.squaredNorm();
  }
  cov /= double(n);
  var_s /= double(n);
  if (var_s < 1e-18) return std::nullopt;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (sv(1) < 1e-12 * std::max(1.0, sv(0))) return std::nullopt;  // collinear
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) d(2, 2) = -1;
  const Eigen::Matrix3d r = svd.matrixU() * d * svd.matrixV().transpose();
  const double s = with_scale ? (sv.asDiagonal() * d).trace() / var_s : 1.0;
  if (!(s > 0) || !std::isfinite(s)) return std::nullopt;
  const Eigen::Vector3d t = mu_t - s * r * mu_s;
  return Sim3d(s, Eigen::Quaterniond(r).normalized(), t);
}

void Sim3RansacOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(max_error) && max_error > 0, "sim3.max_error must be > 0, got {}",
               max_error);
  SL_CHECK_MSG(max_iterations >= 1, "sim3.max_iterations must be >= 1, got {}", max_iterations);
  SL_CHECK_MSG(min_inliers >= 3, "sim3.min_inliers must be >= 3, got {}", min_inliers);
}

namespace {
bool ProjectsWithin(const Eigen::Vector3d& p_in_cam, const Eigen::Vector3d& observed,
                    double max_error) {
  if (p_in_cam.z() <= 0 || observed.z() <= 0) return false;
  const Eigen::Vector2d a = p_in_cam.head<2>() / p_in_cam.z();
  const Eigen::Vector2d b = observed.head<2>() / observed.z();
  return (a - b).norm() <= max_error;
}

std::vector<int> Inliers(const Sim3d& t_from_s, const std::vector<Eigen::Vector3d>& src,
                         const std::vector<Eigen::Vector3d>& dst, double max_error) {
  const Sim3d s_from_t = t_from_s.Inverse();
  std::vector<int> in;
  for (size_t i = 0; i < src.size(); ++i) {
    if (ProjectsWithin(t_from_s * src[i], dst[i], max_error) &&
        ProjectsWithin(s_from_t * dst[i], src[i], max_error))
      in.push_back(int(i));
  }
  return in;
}
}  // namespace

Sim3RansacResult RansacSim3(const std::vector<Eigen::Vector3d>& p_source,
                            const std::vector<Eigen::Vector3d>& p_target,
                            const Sim3RansacOptions& options) {
  options.Check();
  SL_CHECK_MSG(p_source.size() == p_target.size(), "RansacSim3: size mismatch");
  Sim3RansacResult result;
  const int n = static_cast<int>(p_source.size());
  if (n < std::max(3, options.min_inliers)) return result;
  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<int> best;
  for (int it = 0; it < options.max_iterations; ++it) {
    int a = pick(rng), b = pick(rng), c = pick(rng);
    if (a == b || b == c || a == c) continue;
    auto h = UmeyamaSim3({p_source[a], p_source[b], p_source[c]},
                         {p_target[a], p_target[b], p_target[c]});
    if (!h) continue;
    auto in = Inliers(*h, p_source, p_target, options.max_error);
    if (in.size() > best.size()) best = std::move(in);
    if (int(best.size()) == n) break;
  }
  if (int(best.size()) < options.min_inliers) return result;
  // Refine on the inliers, then re-collect once.
  std::vector<Eigen::Vector3d> s, t;
  for (int i : best) {
    s.push_back(p_source[i]);
    t.push_back(p_target[i]);
  }
  auto refined = UmeyamaSim3(s, t);
  if (!refined) return result;
  auto in = Inliers(*refined, p_source, p_target, options.max_error);
  if (in.size() < best.size()) {
    in = best;
  }
  if (int(in.size()) < options.min_inliers) return result;
  result.success = true;
  result.target_from_source = *refined;
  result.inliers = std::move(in);
  return result;
}

}  // namespace sparseloop
