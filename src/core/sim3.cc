#include "sparseloop/core/sim3.h"

#include <cmath>

#include "sparseloop/core/check.h"

namespace sparseloop {

Sim3d::Sim3d(double scale, const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
    : rotation(rotation.normalized()), translation(translation), scale(scale) {
  SL_CHECK_MSG(std::isfinite(scale) && scale > 0.0, "Sim3 scale must be positive, got {}", scale);
}

Sim3d Sim3d::Inverse() const {
  const Eigen::Quaterniond inv = rotation.conjugate();
  const double inv_scale = 1.0 / scale;
  return Sim3d(inv_scale, inv, -inv_scale * (inv * translation));
}

Eigen::Matrix4d Sim3d::ToMatrix4() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = scale * rotation.toRotationMatrix();
  m.topRightCorner<3, 1>() = translation;
  return m;
}

Matrix3x4d Sim3d::ToMatrix3x4() const {
  Matrix3x4d m;
  m.leftCols<3>() = scale * rotation.toRotationMatrix();
  m.col(3) = translation;
  return m;
}

Sim3d Sim3d::FromMatrix3x4(const Matrix3x4d& matrix, double tolerance) {
  SL_CHECK_MSG(matrix.allFinite(), "3x4 pose contains NaN or Inf");
  const double det = matrix.leftCols<3>().determinant();
  SL_CHECK_MSG(det > 0, "3x4 similarity has det <= 0");
  const double s = std::cbrt(det);
  Matrix3x4d unscaled = matrix;
  unscaled.leftCols<3>() /= s;
  const Rigid3d rigid = Rigid3d::FromMatrix3x4(unscaled, tolerance);
  return Sim3d(s, rigid.rotation, matrix.col(3));
}

// W = A [w]x + B [w]x^2 + C I, following the closed form of Strasdat's thesis (as in Sophus).
Eigen::Matrix3d Sim3LeftJacobianW(const Eigen::Vector3d& omega, double sigma) {
  constexpr double kEps = 1e-6;
  const double theta = omega.norm();
  const Eigen::Matrix3d w = Hat(omega);
  const Eigen::Matrix3d w2 = w * w;
  const double scale = std::exp(sigma);
  double a;
  double b;
  double c;
  if (std::abs(sigma) < kEps) {
    c = 1.0;
    if (theta < kEps) {
      a = 0.5;
      b = 1.0 / 6.0;
    } else {
      const double theta_sq = theta * theta;
      a = (1.0 - std::cos(theta)) / theta_sq;
      b = (theta - std::sin(theta)) / (theta_sq * theta);
    }
  } else {
    c = (scale - 1.0) / sigma;
    if (theta < kEps) {
      const double sigma_sq = sigma * sigma;
      a = ((sigma - 1.0) * scale + 1.0) / sigma_sq;
      b = (scale * 0.5 * sigma_sq + scale - 1.0 - sigma * scale) / (sigma_sq * sigma);
    } else {
      const double theta_sq = theta * theta;
      const double sa = scale * std::sin(theta);
      const double sb = scale * std::cos(theta);
      const double den = theta_sq + sigma * sigma;
      a = (sa * sigma + (1.0 - sb) * theta) / (theta * den);
      b = (c - ((sb - 1.0) * sigma + sa * theta) / den) / theta_sq;
    }
  }
  return a * w + b * w2 + c * Eigen::Matrix3d::Identity();
}

Sim3d Sim3d::Exp(const Vector7d& tangent) {
  const Eigen::Vector3d upsilon = tangent.head<3>();
  const Eigen::Vector3d omega = tangent.segment<3>(3);
  const double sigma = tangent[6];
  return Sim3d(std::exp(sigma), ExpSO3(omega), Sim3LeftJacobianW(omega, sigma) * upsilon);
}

Vector7d Sim3d::Log() const {
  const Eigen::Vector3d omega = LogSO3(rotation);
  const double sigma = std::log(scale);
  Vector7d out;
  out.head<3>() = Sim3LeftJacobianW(omega, sigma).inverse() * translation;
  out.segment<3>(3) = omega;
  out[6] = sigma;
  return out;
}

Vector8d Sim3d::ToVector() const {
  Vector8d v;
  v << rotation.x(), rotation.y(), rotation.z(), rotation.w(), translation, scale;
  return v;
}

Sim3d Sim3d::FromVector(const Vector8d& v) {
  return Sim3d(v[7], Eigen::Quaterniond(v[3], v[0], v[1], v[2]), v.segment<3>(4));
}

}  // namespace sparseloop
