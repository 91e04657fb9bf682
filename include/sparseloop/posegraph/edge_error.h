#pragma once
// The pose-graph residual, shared by every vertex type.
//
// An edge from vertex a to vertex b measures b's pose in a's frame, a_from_b = Z. With the
// vertex estimates world_from_a and world_from_b the residual is
//   r = S * log( Z^-1 * inv(world_from_a) * world_from_b )  in R^7 = [upsilon, omega, sigma],
// where S is the upper-triangular square root of the 7x7 information matrix (S^T S = Info).
// It is zero when the estimate agrees with the measurement. For SE(3) graphs the sigma component
// is identically zero (scales stay 1); for 2D graphs only (upsilon_x, upsilon_y, omega_z) carry
// information.
#include <ceres/autodiff_cost_function.h>

#include "sparseloop/core/sim3.h"
#include "sparseloop/posegraph/sim3_jet.h"

namespace sparseloop {

using Matrix7d = Eigen::Matrix<double, 7, 7>;

// S with S^T S = information for a symmetric positive semi-definite 7x7 matrix (eigen
// decomposition, so rank-deficient information such as 2D edges embedded in 7D is allowed).
// Throws std::invalid_argument for a non-symmetric or indefinite matrix.
Matrix7d SqrtInformation(const Matrix7d& information);

class EdgeError {
 public:
  EdgeError(const Sim3d& a_from_b, const Matrix7d& sqrt_information)
      : b_from_a_measured_(a_from_b.Inverse()), sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* world_from_a, const T* world_from_b, T* residual) const {
    const jet::Sim3<T> a = jet::Sim3<T>::FromArray(world_from_a);
    const jet::Sim3<T> b = jet::Sim3<T>::FromArray(world_from_b);
    jet::Sim3<T> z_inv;
    z_inv.rotation = b_from_a_measured_.rotation.template cast<T>();
    z_inv.translation = b_from_a_measured_.translation.template cast<T>();
    z_inv.scale = T(b_from_a_measured_.scale);
    const jet::Vector7<T> error = (z_inv * (a.Inverse() * b)).Log();
    Eigen::Map<jet::Vector7<T>> r(residual);
    r = sqrt_information_.template cast<T>() * error;
    return true;
  }

  static ceres::CostFunction* Create(const Sim3d& a_from_b, const Matrix7d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<EdgeError, 7, 8, 8>(
        new EdgeError(a_from_b, sqrt_information));
  }

 private:
  Sim3d b_from_a_measured_;
  Matrix7d sqrt_information_;
};

}  // namespace sparseloop
