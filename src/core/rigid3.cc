#include "sparseloop/core/rigid3.h"

#include <cmath>

#include "sparseloop/core/check.h"

namespace sparseloop {

Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& omega) {
  const double theta_sq = omega.squaredNorm();
  const double theta = std::sqrt(theta_sq);
  const double half = 0.5 * theta;
  double imag_factor;
  double real;
  if (theta < 1e-8) {
    // Taylor expansion of sin(theta/2)/theta and cos(theta/2).
    imag_factor = 0.5 - theta_sq / 48.0;
    real = 1.0 - theta_sq / 8.0;
  } else {
    imag_factor = std::sin(half) / theta;
    real = std::cos(half);
  }
  Eigen::Quaterniond q(real, imag_factor * omega.x(), imag_factor * omega.y(),
                       imag_factor * omega.z());
  return q.normalized();
}

Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  // q and -q are the same rotation; pick w >= 0 so the angle is in [0, pi].
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const double sin_half = q.vec().norm();
  const double w = q.w();
  double factor;
  if (sin_half < 1e-8) {
    // theta / sin(theta/2) -> 2 / w (first order).
    factor = 2.0 / w;
  } else {
    const double theta = 2.0 * std::atan2(sin_half, w);
    factor = theta / sin_half;
  }
  return factor * q.vec();
}

double RotationAngle(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return LogSO3(a.conjugate() * b).norm();
}

Rigid3d Rigid3d::Inverse() const {
  const Eigen::Quaterniond inv = rotation.conjugate();
  return Rigid3d(inv, -(inv * translation));
}

Eigen::Matrix4d Rigid3d::ToMatrix4() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = RotationMatrix();
  m.topRightCorner<3, 1>() = translation;
  return m;
}

Matrix3x4d Rigid3d::ToMatrix3x4() const {
  Matrix3x4d m;
  m.leftCols<3>() = RotationMatrix();
  m.col(3) = translation;
  return m;
}

namespace {
// Returns the nearest rotation to `r` after verifying it is one within `tolerance`.
Eigen::Matrix3d CheckedRotation(const Eigen::Matrix3d& r, double tolerance) {
  SL_CHECK_MSG(r.allFinite(), "rotation contains NaN or Inf");
  const double orth_err = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  SL_CHECK_MSG(orth_err <= tolerance, "not a rotation matrix: |R^T R - I|max = {:.3g} > {:.3g}",
               orth_err, tolerance);
  SL_CHECK_MSG(r.determinant() > 0, "rotation matrix has det <= 0 (a reflection)");
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}
}  // namespace

Rigid3d Rigid3d::FromMatrix3x4(const Matrix3x4d& matrix, double tolerance) {
  SL_CHECK_MSG(matrix.allFinite(), "3x4 pose contains NaN or Inf");
  const Eigen::Matrix3d r = CheckedRotation(matrix.leftCols<3>(), tolerance);
  return Rigid3d(Eigen::Quaterniond(r), matrix.col(3));
}

namespace {
// V matrix of the SE(3) exponential: t = V(omega) * upsilon.
Eigen::Matrix3d Se3V(const Eigen::Vector3d& omega) {
  const double theta_sq = omega.squaredNorm();
  const double theta = std::sqrt(theta_sq);
  const Eigen::Matrix3d w = Hat(omega);
  double a;
  double b;
  if (theta < 1e-5) {
    a = 0.5 - theta_sq / 24.0;
    b = 1.0 / 6.0 - theta_sq / 120.0;
  } else {
    a = (1.0 - std::cos(theta)) / theta_sq;
    b = (theta - std::sin(theta)) / (theta_sq * theta);
  }
  return Eigen::Matrix3d::Identity() + a * w + b * w * w;
}
}  // namespace

Rigid3d Rigid3d::Exp(const Vector6d& tangent) {
  const Eigen::Vector3d upsilon = tangent.head<3>();
  const Eigen::Vector3d omega = tangent.tail<3>();
  return Rigid3d(ExpSO3(omega), Se3V(omega) * upsilon);
}

Vector6d Rigid3d::Log() const {
  const Eigen::Vector3d omega = LogSO3(rotation);
  Vector6d out;
  out.head<3>() = Se3V(omega).inverse() * translation;
  out.tail<3>() = omega;
  return out;
}

Vector7d Rigid3d::ToVector() const {
  Vector7d v;
  v << rotation.x(), rotation.y(), rotation.z(), rotation.w(), translation;
  return v;
}

Rigid3d Rigid3d::FromVector(const Vector7d& v) {
  return Rigid3d(Eigen::Quaterniond(v[3], v[0], v[1], v[2]), v.tail<3>());
}

}  // namespace sparseloop
