#pragma once
// Pinhole camera intrinsics with optional lens distortion.
#include <string>
#include <vector>

#include <Eigen/Core>

namespace sparseloop {

enum class DistortionModel {
  kNone,              // ideal pinhole
  kRadialTangential,  // OpenCV / EuRoC "radtan": k1 k2 p1 p2 [k3]
  kEquidistant,       // Kannala-Brandt / EuRoC "equidistant": k1 k2 k3 k4
};

// Largest |distortion coefficient| accepted: real lenses' radtan / equidistant coefficients are
// of order 1 (EuRoC's radtan k1 = -0.28); beyond 100 a coefficient is a unit or transcription
// error, which undistortion would turn into keypoints far outside the image without a word.
inline constexpr double kMaxDistortionCoefficient = 100.0;

struct CameraIntrinsics {
  double fx = 0.0;  // focal length, pixels
  double fy = 0.0;  // focal length, pixels
  double cx = 0.0;  // principal point, pixels
  double cy = 0.0;  // principal point, pixels
  int width = 0;    // image width, pixels (0 = unknown)
  int height = 0;   // image height, pixels (0 = unknown)
  DistortionModel distortion_model = DistortionModel::kNone;
  std::vector<double> distortion;  // coefficients in the model's order

  Eigen::Matrix3d K() const;
  // Throws std::invalid_argument naming the first bad field (focal length not in (0, 1e7] px,
  // principal point outside the image or beyond 1e7 px, and CheckDistortion's).
  void Check() const;
  // The distortion part of Check(): the model's number of coefficients, each finite and within
  // +-kMaxDistortionCoefficient (named: "k1", "p2", ...).
  void CheckDistortion() const;
  // Pixel -> normalised image coordinates, ignoring distortion.
  Eigen::Vector2d Unproject(const Eigen::Vector2d& pixel) const;
  // Camera-frame point (z > 0) -> pixel, ignoring distortion.
  Eigen::Vector2d Project(const Eigen::Vector3d& p_in_cam) const;
};

std::string ToString(DistortionModel model);

}  // namespace sparseloop
