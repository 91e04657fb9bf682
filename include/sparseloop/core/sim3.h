#pragma once
// Similarity transform in Sim(3): x -> s R x + t, s > 0. Monocular vSLAM poses live here: the
// scale of a monocular trajectory is unobservable and drifts.
// Storage is [qx qy qz qw tx ty tz s].
#include "sparseloop/core/rigid3.h"

namespace sparseloop {

using Vector8d = Eigen::Matrix<double, 8, 1>;

struct Sim3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double scale = 1.0;

  Sim3d() = default;
  Sim3d(double scale, const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation);
  explicit Sim3d(const Rigid3d& rigid) : rotation(rigid.rotation), translation(rigid.translation) {}

  static Sim3d Identity() { return {}; }

  Sim3d Inverse() const;
  // Drops the scale (the rotation and translation are kept as they are).
  Rigid3d ToRigid() const { return Rigid3d(rotation, translation); }
  Eigen::Matrix4d ToMatrix4() const;
  // [sR | t]
  Matrix3x4d ToMatrix3x4() const;
  // Scale is the cube root of det of the 3x3 block; the remainder must be a rotation within
  // `tolerance`, else std::invalid_argument.
  static Sim3d FromMatrix3x4(const Matrix3x4d& matrix, double tolerance = 1e-4);

  // Tangent order follows Sophus: [upsilon (3), omega (3), sigma = log(scale)].
  static Sim3d Exp(const Vector7d& tangent);
  Vector7d Log() const;

  Vector8d ToVector() const;
  static Sim3d FromVector(const Vector8d& v);
};

inline Sim3d operator*(const Sim3d& a, const Sim3d& b) {
  return Sim3d(a.scale * b.scale, a.rotation * b.rotation,
               a.scale * (a.rotation * b.translation) + a.translation);
}
inline Eigen::Vector3d operator*(const Sim3d& a, const Eigen::Vector3d& p) {
  return a.scale * (a.rotation * p) + a.translation;
}

// The matrix W(omega, sigma) that maps the translational tangent to the translation in the Sim(3)
// exponential: t = W * upsilon. Exposed for tests and for the pose-graph Jacobians.
Eigen::Matrix3d Sim3LeftJacobianW(const Eigen::Vector3d& omega, double sigma);

}  // namespace sparseloop
