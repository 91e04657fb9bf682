#pragma once
// Ceres manifolds for pose-graph vertices. Every vertex is stored as one 8-double parameter block
// [qx qy qz qw tx ty tz s] (core Sim3d::ToVector order); the manifold decides which degrees of
// freedom the optimiser may move:
//   Sim3     7 DoF  Plus = x * exp(d), Minus = log(inv(x) * y)   (monocular vSLAM)
//   Se3      6 DoF  same with sigma = 0: the scale stays as stored (metric input)
//   FourDof  4 DoF  x, y, z translation + yaw about the world z (gravity) axis (VIO)
//   Se2      3 DoF  x, y translation + yaw about world z (planar g2o graphs)
// Plus / Minus are the templates in sim3_jet.h; PlusJacobian is closed-form, MinusJacobian
// comes from ceres::AutoDiffManifold.
#include <memory>

#include <ceres/autodiff_manifold.h>
#include <ceres/manifold.h>

#include "posegraph/sim3_jet.h"
#include "sparseloop/posegraph/types.h"

namespace sparseloop {

struct Sim3PlusFunctor {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    const jet::Vector7<T> d(delta);
    (jet::Sim3<T>::FromArray(x) * jet::Sim3<T>::Exp(d)).ToArray(x_plus_delta);
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    const jet::Vector7<T> d =
        (jet::Sim3<T>::FromArray(x).Inverse() * jet::Sim3<T>::FromArray(y)).Log();
    for (int i = 0; i < 7; ++i) y_minus_x[i] = d[i];
    return true;
  }
};

struct Se3OnSim3PlusFunctor {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    jet::Vector7<T> d;
    for (int i = 0; i < 6; ++i) d[i] = delta[i];
    d[6] = T(0.0);
    (jet::Sim3<T>::FromArray(x) * jet::Sim3<T>::Exp(d)).ToArray(x_plus_delta);
    x_plus_delta[7] = x[7];  // exact: the scale never moves
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    jet::Sim3<T> xs = jet::Sim3<T>::FromArray(x);
    jet::Sim3<T> ys = jet::Sim3<T>::FromArray(y);
    xs.scale = T(1.0);
    ys.scale = T(1.0);
    const jet::Vector7<T> d = (xs.Inverse() * ys).Log();
    for (int i = 0; i < 6; ++i) y_minus_x[i] = d[i];
    return true;
  }
};

// Yaw-only rotation increments about world z, translation increments in world coordinates.
template <int kTranslationDims>
struct YawPlusFunctor {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    using std::cos;
    using std::sin;
    const T yaw = delta[kTranslationDims];
    const Eigen::Quaternion<T> rz(cos(T(0.5) * yaw), T(0.0), T(0.0), sin(T(0.5) * yaw));
    const Eigen::Quaternion<T> q(x[3], x[0], x[1], x[2]);
    const Eigen::Quaternion<T> out = rz * q;
    x_plus_delta[0] = out.x();
    x_plus_delta[1] = out.y();
    x_plus_delta[2] = out.z();
    x_plus_delta[3] = out.w();
    for (int i = 0; i < 3; ++i) {
      x_plus_delta[4 + i] = x[4 + i] + (i < kTranslationDims ? delta[i] : T(0.0));
    }
    x_plus_delta[7] = x[7];
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    using std::atan2;
    const Eigen::Quaternion<T> qx(x[3], x[0], x[1], x[2]);
    const Eigen::Quaternion<T> qy(y[3], y[0], y[1], y[2]);
    const Eigen::Quaternion<T> rz = qy * qx.conjugate();
    for (int i = 0; i < kTranslationDims; ++i) y_minus_x[i] = y[4 + i] - x[4 + i];
    T w = rz.w();
    T z = rz.z();
    if (w < T(0.0)) {
      w = -w;
      z = -z;
    }
    y_minus_x[kTranslationDims] = T(2.0) * atan2(z, w);
    return true;
  }
};

// The manifold of a functor above with a closed-form PlusJacobian (the 8 x kTangent matrix
// d Plus(x, d) / dd at d = 0); Plus, Minus and MinusJacobian are the functor's, the latter through
// ceres::AutoDiffManifold. Ceres calls PlusJacobian for every parameter block at every new state;
// through autodiff that needed (8 + kTangent)-dimensional Jets through the Sim(3) exponential and
// was ~40 % of a 5,000-keyframe solve (bench_posegraph). `PlusJacobianFn` writes it row-major.
// Checked against the autodiff Jacobian and by Ceres' manifold invariants (sim3_jet_test.cc).
template <typename Functor, int kTangent, void (*PlusJacobianFn)(const double*, double*)>
class AnalyticPlusJacobianManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 8; }
  int TangentSize() const override { return kTangent; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    return autodiff_.Plus(x, delta, x_plus_delta);
  }
  bool PlusJacobian(const double* x, double* jacobian) const override {
    PlusJacobianFn(x, jacobian);
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    return autodiff_.Minus(y, x, y_minus_x);
  }
  bool MinusJacobian(const double* x, double* jacobian) const override {
    return autodiff_.MinusJacobian(x, jacobian);
  }

 private:
  ceres::AutoDiffManifold<Functor, 8, kTangent> autodiff_;
};

// d(x * exp(d)) / dd at d = 0 for x = [qx qy qz qw tx ty tz s] (row-major 8 x 7):
//   q rows, omega columns: m / 2 with m = d(q * [v, 1]) / dv = [qw I + [qv]x ; -qv^T]
//   t rows, upsilon columns: s R(q);   s row, sigma column: s.
void Sim3PlusJacobian(const double* x, double* jacobian);
// The same without the sigma column (8 x 6): the scale never moves.
void Se3OnSim3PlusJacobian(const double* x, double* jacobian);
// Yaw about world z (q rows: (e_z * q) / 2) and world translation increments (8 x 4 / 8 x 3).
void FourDofPlusJacobian(const double* x, double* jacobian);
void Se2OnSim3PlusJacobian(const double* x, double* jacobian);

using Sim3Manifold = AnalyticPlusJacobianManifold<Sim3PlusFunctor, 7, &Sim3PlusJacobian>;
using Se3OnSim3Manifold =
    AnalyticPlusJacobianManifold<Se3OnSim3PlusFunctor, 6, &Se3OnSim3PlusJacobian>;
using FourDofManifold = AnalyticPlusJacobianManifold<YawPlusFunctor<3>, 4, &FourDofPlusJacobian>;
using Se2OnSim3Manifold =
    AnalyticPlusJacobianManifold<YawPlusFunctor<2>, 3, &Se2OnSim3PlusJacobian>;
// The autodiff originals, kept as the reference the tests compare against.
using Sim3AutoDiffManifold = ceres::AutoDiffManifold<Sim3PlusFunctor, 8, 7>;
using Se3OnSim3AutoDiffManifold = ceres::AutoDiffManifold<Se3OnSim3PlusFunctor, 8, 6>;
using FourDofAutoDiffManifold = ceres::AutoDiffManifold<YawPlusFunctor<3>, 8, 4>;
using Se2OnSim3AutoDiffManifold = ceres::AutoDiffManifold<YawPlusFunctor<2>, 8, 3>;

// A new manifold for `type` (the caller, usually ceres::Problem, takes ownership).
std::unique_ptr<ceres::Manifold> CreateVertexManifold(VertexType type);

}  // namespace sparseloop
