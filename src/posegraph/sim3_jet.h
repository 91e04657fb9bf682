#pragma once
// Templated Sim(3) / SO(3) group operations for Ceres automatic differentiation.
//
// The double versions live in core (Sim3d::Exp / Sim3d::Log, ExpSO3 / LogSO3); these templates
// compute the same maps for any scalar T (double or ceres::Jet) and are tested against core in
// tests/posegraph/sim3_jet_test.cc, so the math exists in one verified place per scalar type.
//
// Storage of a Sim(3) element in a parameter block is core's Sim3d::ToVector order:
//   [qx qy qz qw tx ty tz s]   (Eigen's internal quaternion order; no reordering needed)
// Tangent order follows core / Sophus: [upsilon (3), omega (3), sigma = log(s)].
//
// Branches compare only the scalar part of a Jet; every small-angle branch keeps the Taylor terms
// up to the order whose derivative is still non-negligible, so Jacobians stay correct at the
// identity (where pose-graph residuals are evaluated at convergence).
#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace sparseloop::jet {

template <typename T>
using Vector3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Vector7 = Eigen::Matrix<T, 7, 1>;
template <typename T>
using Matrix3 = Eigen::Matrix<T, 3, 3>;

template <typename T>
Matrix3<T> Hat(const Vector3<T>& v) {
  Matrix3<T> m;
  m << T(0), -v.z(), v.y(), v.z(), T(0), -v.x(), -v.y(), v.x(), T(0);
  return m;
}

// SO(3) exponential: axis-angle (rad) -> unit quaternion.
template <typename T>
Eigen::Quaternion<T> ExpSO3(const Vector3<T>& omega) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta_sq = omega.squaredNorm();
  T imag_factor;
  T real;
  if (theta_sq < T(1e-10)) {
    imag_factor = T(0.5) - theta_sq / T(48.0);
    real = T(1.0) - theta_sq / T(8.0);
  } else {
    const T theta = sqrt(theta_sq);
    imag_factor = sin(T(0.5) * theta) / theta;
    real = cos(T(0.5) * theta);
  }
  return Eigen::Quaternion<T>(real, imag_factor * omega.x(), imag_factor * omega.y(),
                              imag_factor * omega.z());
}

// SO(3) logarithm of a unit quaternion; the result has norm in [0, pi].
template <typename T>
Vector3<T> LogSO3(const Eigen::Quaternion<T>& q_in) {
  using std::atan2;
  using std::sqrt;
  Vector3<T> vec = q_in.vec();
  T w = q_in.w();
  if (w < T(0)) {  // q and -q are the same rotation: take w >= 0 so the angle is in [0, pi]
    vec = -vec;
    w = -w;
  }
  const T sin_half_sq = vec.squaredNorm();
  T factor;
  if (sin_half_sq < T(1e-16)) {
    // theta / sin(theta/2) = 2 / w * (1 + sin^2(theta/2) / 3 / w^2 + ...) -> first order 2 / w.
    factor = T(2.0) / w;
  } else {
    const T sin_half = sqrt(sin_half_sq);
    factor = T(2.0) * atan2(sin_half, w) / sin_half;
  }
  return factor * vec;
}

// W(omega, sigma) with t = W * upsilon in the Sim(3) exponential (see core's Sim3LeftJacobianW):
// W = A [w]x + B [w]x^2 + C I.
template <typename T>
Matrix3<T> Sim3W(const Vector3<T>& omega, const T& sigma) {
  using std::abs;
  using std::cos;
  using std::exp;
  using std::sin;
  using std::sqrt;
  const T theta_sq = omega.squaredNorm();
  const Matrix3<T> w = Hat(omega);
  const T scale = exp(sigma);
  const bool sigma_small = abs(sigma) < T(1e-4);
  // C = (e^s - 1) / s
  const T c = sigma_small ? T(1.0) + sigma / T(2.0) + sigma * sigma / T(6.0) +
                                sigma * sigma * sigma / T(24.0)
                          : (scale - T(1.0)) / sigma;
  T a;
  T b;
  if (theta_sq < T(1e-8)) {
    if (abs(sigma) < T(1e-3)) {
      // Double Taylor series around (theta, sigma) = (0, 0).
      const T s2 = sigma * sigma;
      a = T(0.5) + sigma / T(3.0) + s2 / T(8.0) + s2 * sigma / T(30.0) - theta_sq / T(24.0);
      b = T(1.0 / 6.0) + sigma / T(8.0) + s2 / T(20.0) + s2 * sigma / T(72.0) - theta_sq / T(120.0);
    } else {
      const T s2 = sigma * sigma;
      a = ((sigma - T(1.0)) * scale + T(1.0)) / s2;
      b = (scale * T(0.5) * s2 + scale - T(1.0) - sigma * scale) / (s2 * sigma);
    }
  } else {
    const T theta = sqrt(theta_sq);
    const T sa = scale * sin(theta);
    const T sb = scale * cos(theta);
    const T den = theta_sq + sigma * sigma;
    a = (sa * sigma + (T(1.0) - sb) * theta) / (theta * den);
    b = (c - ((sb - T(1.0)) * sigma + sa * theta) / den) / theta_sq;
  }
  return a * w + b * (w * w) + c * Matrix3<T>::Identity();
}

// A Sim(3) element x -> s R x + t with scalar type T.
template <typename T>
struct Sim3 {
  Eigen::Quaternion<T> rotation = Eigen::Quaternion<T>::Identity();
  Vector3<T> translation = Vector3<T>::Zero();
  T scale = T(1.0);

  // From a parameter block [qx qy qz qw tx ty tz s].
  static Sim3 FromArray(const T* p) {
    Sim3 out;
    out.rotation = Eigen::Quaternion<T>(p[3], p[0], p[1], p[2]);
    out.translation = Vector3<T>(p[4], p[5], p[6]);
    out.scale = p[7];
    return out;
  }
  void ToArray(T* p) const {
    p[0] = rotation.x();
    p[1] = rotation.y();
    p[2] = rotation.z();
    p[3] = rotation.w();
    p[4] = translation.x();
    p[5] = translation.y();
    p[6] = translation.z();
    p[7] = scale;
  }

  Sim3 Inverse() const {
    Sim3 out;
    out.rotation = rotation.conjugate();
    out.scale = T(1.0) / scale;
    out.translation = -(out.scale * (out.rotation * translation));
    return out;
  }

  static Sim3 Exp(const Vector7<T>& tangent) {
    using std::exp;
    const Vector3<T> upsilon = tangent.template head<3>();
    const Vector3<T> omega = tangent.template segment<3>(3);
    const T sigma = tangent[6];
    Sim3 out;
    out.rotation = ExpSO3<T>(omega);
    out.translation = Sim3W<T>(omega, sigma) * upsilon;
    out.scale = exp(sigma);
    return out;
  }

  Vector7<T> Log() const {
    using std::log;
    const Vector3<T> omega = LogSO3<T>(rotation);
    const T sigma = log(scale);
    Vector7<T> out;
    out.template head<3>() = Sim3W<T>(omega, sigma).inverse() * translation;
    out.template segment<3>(3) = omega;
    out[6] = sigma;
    return out;
  }
};

template <typename T>
Sim3<T> operator*(const Sim3<T>& a, const Sim3<T>& b) {
  Sim3<T> out;
  out.rotation = a.rotation * b.rotation;
  out.translation = a.scale * (a.rotation * b.translation) + a.translation;
  out.scale = a.scale * b.scale;
  return out;
}

}  // namespace sparseloop::jet
