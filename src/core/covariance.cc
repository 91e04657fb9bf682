#include "sparseloop/core/covariance.h"

#include <fmt/format.h>
#include <Eigen/Eigenvalues>

namespace sparseloop {

std::optional<CovarianceProblem> CheckCovariance(const Eigen::Matrix<double, 6, 6>& covariance) {
  if (!covariance.allFinite())
    return CovarianceProblem{"a finite covariance", "a NaN or an infinite entry"};
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(covariance,
                                                                       Eigen::EigenvaluesOnly);
  const double smallest = eig.eigenvalues().minCoeff();
  const double largest = eig.eigenvalues().maxCoeff();
  if (eig.info() != Eigen::Success || !(smallest > 0.0))
    return CovarianceProblem{"a positive definite covariance",
                             fmt::format("a smallest eigenvalue of {:g}", smallest)};
  if (smallest < kMinCovarianceEigenvalue)
    return CovarianceProblem{
        fmt::format("covariance eigenvalues of at least {:g} (the inverse weights the step)",
                    kMinCovarianceEigenvalue),
        fmt::format("a smallest eigenvalue of {:g}", smallest)};
  if (largest > kMaxCovarianceCondition * smallest)
    return CovarianceProblem{
        fmt::format("covariance eigenvalues within a factor {:g} of each other",
                    kMaxCovarianceCondition),
        fmt::format("eigenvalues {:g} and {:g}", smallest, largest)};
  return std::nullopt;
}

}  // namespace sparseloop
