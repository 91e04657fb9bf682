#pragma once
// Whether a caller's 6x6 step covariance can weight a pose-graph edge, in one place for every
// reader of one (`run --odometry-covariance`, KeyframeInput::odometry_covariance, Python).
#include <optional>
#include <string>

#include <Eigen/Core>

namespace sparseloop {

// A covariance eigenvalue below this (raw units^2, rad^2) gives an information (1 / eigenvalue)
// above 1e18: the solver's sums and the chain reduction's Cholesky lose it to rounding.
inline constexpr double kMinCovarianceEigenvalue = 1e-18;
// Largest / smallest eigenvalue: beyond this the matrix is singular to double precision once
// summed along a chain (the same bound as the ROS node's step covariance).
inline constexpr double kMaxCovarianceCondition = 1e12;

struct CovarianceProblem {
  std::string expected;  // "covariance eigenvalues of at least 1e-18 (...)"
  std::string got;       // "a smallest eigenvalue of 1e-30"
  std::string Message() const { return "expected " + expected + ", got " + got; }
};

// nullopt when `covariance` (symmetric, checked by the caller) is usable: finite, positive
// definite, eigenvalues >= kMinCovarianceEigenvalue and within kMaxCovarianceCondition.
std::optional<CovarianceProblem> CheckCovariance(const Eigen::Matrix<double, 6, 6>& covariance);

}  // namespace sparseloop
