#pragma once
// Rigid body transform in SE(3): x -> R x + t.
// Naming convention: a transform is named target_from_source (world_from_cam), so that
// world_from_cam * p_in_cam == p_in_world and chains read right to left.
// Storage is [qx qy qz qw tx ty tz] (Eigen order), so a pose maps onto a Ceres parameter block.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace sparseloop {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Vector7d = Eigen::Matrix<double, 7, 1>;
using Matrix3x4d = Eigen::Matrix<double, 3, 4>;

// SO(3) exponential map: axis-angle vector (rad) -> unit quaternion. Exact near zero.
Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& omega);
// SO(3) logarithm: unit quaternion -> axis-angle vector with norm in [0, pi].
Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q);
// Skew-symmetric matrix [v]x such that [v]x w == v.cross(w).
Eigen::Matrix3d Hat(const Eigen::Vector3d& v);

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
      : rotation(rotation.normalized()), translation(translation) {}

  static Rigid3d Identity() { return {}; }

  Rigid3d Inverse() const;
  Eigen::Matrix3d RotationMatrix() const { return rotation.toRotationMatrix(); }
  Eigen::Matrix4d ToMatrix4() const;
  // [R | t]
  Matrix3x4d ToMatrix3x4() const;
  // Throws std::invalid_argument when the 3x3 block is not a rotation within `tolerance`
  // (max abs deviation of R^T R from I, and det(R) > 0). The rotation is re-orthonormalised.
  static Rigid3d FromMatrix3x4(const Matrix3x4d& matrix, double tolerance = 1e-4);

  // Tangent order follows Sophus: [upsilon (translation part), omega (rotation part)].
  static Rigid3d Exp(const Vector6d& tangent);
  Vector6d Log() const;

  // Storage [qx qy qz qw tx ty tz].
  Vector7d ToVector() const;
  static Rigid3d FromVector(const Vector7d& v);
};

inline Rigid3d operator*(const Rigid3d& a, const Rigid3d& b) {
  return Rigid3d(a.rotation * b.rotation, a.rotation * b.translation + a.translation);
}
inline Eigen::Vector3d operator*(const Rigid3d& a, const Eigen::Vector3d& p) {
  return a.rotation * p + a.translation;
}

// Angle of the relative rotation between two rotations, in radians.
double RotationAngle(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

}  // namespace sparseloop
