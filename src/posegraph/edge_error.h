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
#include <ceres/jet.h>
#include <ceres/sized_cost_function.h>

#include "posegraph/sim3_jet.h"
#include "sparseloop/core/sim3.h"
#include "sparseloop/posegraph/types.h"

namespace sparseloop {

// Conversions between core's Sim3d and the templated double Sim(3) of sim3_jet.h (same storage
// order, Sim3d::ToVector).
inline jet::Sim3<double> ToJetSim3(const Sim3d& x) {
  const Vector8d v = x.ToVector();
  return jet::Sim3<double>::FromArray(v.data());
}
inline Sim3d FromJetSim3(const jet::Sim3<double>& x) {
  Vector8d v;
  x.ToArray(v.data());
  return Sim3d::FromVector(v);
}

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

// The same residual with analytic Jacobians, for Sim(3) vertices (Sim3Manifold) only.
//
// With E = Z^-1 * inv(A) * B and e = log(E), right perturbations A exp(da), B exp(db) give
//   d e / d db = Jl(E)                    := d log(E exp(d)) / dd at d = 0
//   d e / d da = -Jl(E) * Ad(inv(inv(A) B))   (exp(-d) inv(A) B = inv(A) B exp(-Ad(..) d))
// Jl(E) = Jr^-1(log E) is a Bernoulli series in the algebra adjoint when the rotation and scale
// parts of log E are small (every odometry edge near a solution; truncation below 1e-15), else
// 7-dimensional Jets over the small map at d = 0 (see LogJacobian); autodiff through the whole
// residual needs 16-dimensional Jets through two products, an inverse and the log. Ad is the Sim(3)
// adjoint, exp(Ad(T) x) = T exp(x) inv(T):
//   [[s R, [t]x R, -t], [0, R, 0], [0, 0, 1]]   (Sophus' Sim3::Adj, same tangent order). Ceres
//   wants Jacobians w.r.t. the 8 ambient
// parameters and multiplies them by the manifold's PlusJacobian P (8x7); we return
// J_tangent * P^+ with the left inverse P^+ of P = d(x exp(d))/dd at d = 0:
//   rows upsilon: R^T / s on t;  rows omega: 2 [qw I + [qv]x ; -qv^T]^T on q;  row sigma: 1/s on s
// so that J_ambient * P = J_tangent. Checked against EdgeError in pose_graph_test.cc.
class Sim3EdgeCost : public ceres::SizedCostFunction<7, 8, 8> {
 public:
  Sim3EdgeCost(const Sim3d& a_from_b, const Matrix7d& sqrt_information)
      : z_inv_(ToJetSim3(a_from_b.Inverse())), sqrt_information_(sqrt_information) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const jet::Sim3<double> a = jet::Sim3<double>::FromArray(parameters[0]);
    const jet::Sim3<double> b = jet::Sim3<double>::FromArray(parameters[1]);
    const jet::Sim3<double> a_inv_b = a.Inverse() * b;
    const jet::Sim3<double> e = z_inv_ * a_inv_b;
    Eigen::Map<Eigen::Matrix<double, 7, 1>> r(residuals);
    const jet::Vector7<double> xi = e.Log();
    r = sqrt_information_ * xi;
    if (jacobians == nullptr) return true;
    const Matrix7d j_b = sqrt_information_ * LogJacobian(e, xi);
    if (jacobians[1] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 7, 8, Eigen::RowMajor>> j(jacobians[1]);
      j = j_b * PlusJacobianLeftInverse(parameters[1]);
    }
    if (jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 7, 8, Eigen::RowMajor>> j(jacobians[0]);
      j = -j_b * Adjoint(a_inv_b.Inverse()) * PlusJacobianLeftInverse(parameters[0]);
    }
    return true;
  }

  static ceres::CostFunction* Create(const Sim3d& a_from_b, const Matrix7d& sqrt_information) {
    return new Sim3EdgeCost(a_from_b, sqrt_information);
  }

  // Jl(E) = d log(E exp(d)) / dd at d = 0 = Jr^-1(xi), xi = log(E) (given). Small rotation and
  // scale parts (every odometry edge near a solution): the Bernoulli series
  //   Jr^-1(xi) = I + ad/2 + ad^2/12 - ad^4/720 + ad^6/30240   (x / (1 - exp(-x)), BCH)
  // with the Sim(3) algebra adjoint ad = ad(xi); its next term is ~8e-7 |ad|^8, below 1e-15
  // relative for max(|omega|, |sigma|) < kSeriesLimit (the translation enters ad linearly and
  // nilpotently: at most once in every product). Otherwise exact, by 7-dimensional Jets.
  static Matrix7d LogJacobian(const jet::Sim3<double>& e, const jet::Vector7<double>& xi) {
    constexpr double kSeriesLimit = 0.05;
    if (std::max(xi.segment<3>(3).norm(), std::abs(xi[6])) < kSeriesLimit) {
      const Matrix7d ad = AlgebraAdjoint(xi);
      const Matrix7d ad2 = ad * ad;
      const Matrix7d ad4 = ad2 * ad2;
      return Matrix7d::Identity() + 0.5 * ad + (1.0 / 12.0) * ad2 - (1.0 / 720.0) * ad4 +
             (1.0 / 30240.0) * (ad4 * ad2);
    }
    using Jet = ceres::Jet<double, 7>;
    jet::Vector7<Jet> d;
    for (int i = 0; i < 7; ++i) d[i] = Jet(0.0, i);
    const jet::Vector7<Jet> log = (Cast(e) * jet::Sim3<Jet>::Exp(d)).Log();
    Matrix7d j_log;
    for (int row = 0; row < 7; ++row) j_log.row(row) = log[row].v.transpose();
    return j_log;
  }

  // ad(xi) with ad(xi) y = [xi, y] in the algebra, tangent order [upsilon, omega, sigma]:
  //   [[ [w]x + s I, [u]x, -u ], [0, [w]x, 0], [0, 0, 0]]
  // (from the 4x4 algebra matrices [[ [w]x + s I, u ], [0, 0]]).
  static Matrix7d AlgebraAdjoint(const jet::Vector7<double>& xi) {
    const Eigen::Vector3d u = xi.head<3>(), w = xi.segment<3>(3);
    const double sigma = xi[6];
    Matrix7d ad = Matrix7d::Zero();
    ad.block<3, 3>(0, 0) = jet::Hat<double>(w) + sigma * Eigen::Matrix3d::Identity();
    ad.block<3, 3>(0, 3) = jet::Hat<double>(u);
    ad.block<3, 1>(0, 6) = -u;
    ad.block<3, 3>(3, 3) = jet::Hat<double>(w);
    return ad;
  }

  static Matrix7d Adjoint(const jet::Sim3<double>& x) {
    const Eigen::Matrix3d r = x.rotation.toRotationMatrix();
    Matrix7d out = Matrix7d::Zero();
    out.block<3, 3>(0, 0) = x.scale * r;
    out.block<3, 3>(0, 3) = jet::Hat<double>(x.translation) * r;
    out.block<3, 1>(0, 6) = -x.translation;
    out.block<3, 3>(3, 3) = r;
    out(6, 6) = 1.0;
    return out;
  }

  // P^+ (7x8) with P^+ P = I for P = d(x exp(d))/dd at d = 0 (x with a unit quaternion).
  static Eigen::Matrix<double, 7, 8> PlusJacobianLeftInverse(const double* x) {
    const Eigen::Quaterniond q(x[3], x[0], x[1], x[2]);
    const double s = x[7];
    Eigen::Matrix<double, 7, 8> out = Eigen::Matrix<double, 7, 8>::Zero();
    out.block<3, 3>(0, 4) = q.toRotationMatrix().transpose() / s;
    Eigen::Matrix<double, 4, 3> m;  // d(q * [v, 1]) / dv, rows x y z w
    m.topRows<3>() = q.w() * Eigen::Matrix3d::Identity() + jet::Hat<double>(q.vec());
    m.row(3) = -q.vec().transpose();
    out.block<3, 4>(3, 0) = 2.0 * m.transpose();  // P's omega block is m / 2
    out(6, 7) = 1.0 / s;
    return out;
  }

 private:
  static jet::Sim3<ceres::Jet<double, 7>> Cast(const jet::Sim3<double>& x) {
    jet::Sim3<ceres::Jet<double, 7>> out;
    out.rotation = x.rotation.cast<ceres::Jet<double, 7>>();
    out.translation = x.translation.cast<ceres::Jet<double, 7>>();
    out.scale = ceres::Jet<double, 7>(x.scale);
    return out;
  }

  jet::Sim3<double> z_inv_;
  Matrix7d sqrt_information_;
};

}  // namespace sparseloop
