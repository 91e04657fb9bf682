#pragma once
// Ceres manifolds for pose-graph vertices. Every vertex is stored as one 8-double parameter block
// [qx qy qz qw tx ty tz s] (core Sim3d::ToVector order); the manifold decides which degrees of
// freedom the optimiser may move:
//   Sim3     7 DoF  Plus = x * exp(d), Minus = log(inv(x) * y)   (monocular vSLAM)
//   Se3      6 DoF  same with sigma = 0: the scale stays as stored (metric input)
//   FourDof  4 DoF  x, y, z translation + yaw about the world z (gravity) axis (VIO)
//   Se2      3 DoF  x, y translation + yaw about world z (planar g2o graphs)
// Jacobians come from ceres::AutoDiffManifold over the templates in sim3_jet.h.
#include <memory>

#include <ceres/autodiff_manifold.h>
#include <ceres/manifold.h>

#include "sparseloop/posegraph/sim3_jet.h"

namespace sparseloop {

enum class VertexType {
  kSim3,     // 7 DoF similarity (monocular: scale drifts)
  kSe3,      // 6 DoF rigid (stereo / RGB-D / VIO): scale kept as stored (1)
  kFourDof,  // x, y, z, yaw (gravity-aligned VIO: roll and pitch are observable)
  kSe2,      // x, y, yaw (planar 2D graphs)
};

// Tangent dimension of a vertex type (7, 6, 4, 3).
int TangentSize(VertexType type);

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

using Sim3Manifold = ceres::AutoDiffManifold<Sim3PlusFunctor, 8, 7>;
using Se3OnSim3Manifold = ceres::AutoDiffManifold<Se3OnSim3PlusFunctor, 8, 6>;
using FourDofManifold = ceres::AutoDiffManifold<YawPlusFunctor<3>, 8, 4>;
using Se2OnSim3Manifold = ceres::AutoDiffManifold<YawPlusFunctor<2>, 8, 3>;

// A new manifold for `type` (the caller, usually ceres::Problem, takes ownership).
std::unique_ptr<ceres::Manifold> CreateVertexManifold(VertexType type);

}  // namespace sparseloop
