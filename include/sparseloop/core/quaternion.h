#pragma once
// The one place where quaternion component order is converted. Eigen's constructor takes
// (w, x, y, z) but stores (x, y, z, w); TUM files write "qx qy qz qw"; EuRoC CSV writes
// "qw qx qy qz". Always go through these helpers.
#include <array>

#include <Eigen/Geometry>

namespace sparseloop {

inline Eigen::Quaterniond QuaternionFromXyzw(double qx, double qy, double qz, double qw) {
  return Eigen::Quaterniond(qw, qx, qy, qz);
}
inline Eigen::Quaterniond QuaternionFromWxyz(double qw, double qx, double qy, double qz) {
  return Eigen::Quaterniond(qw, qx, qy, qz);
}
inline std::array<double, 4> QuaternionToXyzw(const Eigen::Quaterniond& q) {
  return {q.x(), q.y(), q.z(), q.w()};
}
inline std::array<double, 4> QuaternionToWxyz(const Eigen::Quaterniond& q) {
  return {q.w(), q.x(), q.y(), q.z()};
}

}  // namespace sparseloop
