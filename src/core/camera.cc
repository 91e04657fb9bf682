#include "sparseloop/core/camera.h"

#include <cmath>

#include "sparseloop/core/check.h"

namespace sparseloop {

Eigen::Matrix3d CameraIntrinsics::K() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

namespace {
// Largest focal length and principal-point coordinate accepted, pixels: beyond any lens (an
// 8000-pixel image with a 1 degree field of view has fx ~ 4.6e5), and what keeps every projection
// inside the float range of a stored keyframe.
constexpr double kMaxFocalLength = 1e7;
}  // namespace

void CameraIntrinsics::Check() const {
  SL_CHECK_MSG(std::isfinite(fx) && fx > 0, "intrinsics: fx must be positive and finite, got {}",
               fx);
  SL_CHECK_MSG(std::isfinite(fy) && fy > 0, "intrinsics: fy must be positive and finite, got {}",
               fy);
  // Below 1 pixel no lens either (fx = 1 on a 640-pixel image is a 179 degree field of view): a
  // focal length of 1e-300 passed and failed later as "keypoint coordinate is not finite".
  SL_CHECK_MSG(fx >= 1.0, "intrinsics: fx must be at least 1 pixel, got {}", fx);
  SL_CHECK_MSG(fy >= 1.0, "intrinsics: fy must be at least 1 pixel, got {}", fy);
  // Beyond any lens (an 8000-pixel image with a 1 degree field of view has fx ~ 4.6e5), and what
  // keeps every projection inside the float range of the stored keyframes.
  SL_CHECK_MSG(fx <= kMaxFocalLength, "intrinsics: fx must be at most {} pixels, got {}",
               kMaxFocalLength, fx);
  SL_CHECK_MSG(fy <= kMaxFocalLength, "intrinsics: fy must be at most {} pixels, got {}",
               kMaxFocalLength, fy);
  SL_CHECK_MSG(std::isfinite(cx) && std::isfinite(cy), "intrinsics: principal point not finite");
  SL_CHECK_MSG(std::abs(cx) <= kMaxFocalLength && std::abs(cy) <= kMaxFocalLength,
               "intrinsics: principal point ({}, {}) must be within {} pixels", cx, cy,
               kMaxFocalLength);
  SL_CHECK_MSG(width >= 0 && height >= 0, "intrinsics: negative image size {}x{}", width, height);
  if (width > 0 && height > 0) {
    SL_CHECK_MSG(cx > 0 && cx < width && cy > 0 && cy < height,
                 "intrinsics: principal point ({}, {}) outside the {}x{} image", cx, cy, width,
                 height);
  }
  CheckDistortion();
}

void CameraIntrinsics::CheckDistortion() const {
  const char* const* names = nullptr;
  static constexpr const char* kRadtan[] = {"k1", "k2", "p1", "p2", "k3"};
  static constexpr const char* kEquidistant[] = {"k1", "k2", "k3", "k4"};
  switch (distortion_model) {
    case DistortionModel::kNone:
      SL_CHECK_MSG(distortion.empty(), "intrinsics: model none takes no coefficients, got {}",
                   distortion.size());
      break;
    case DistortionModel::kRadialTangential:
      SL_CHECK_MSG(distortion.size() == 4 || distortion.size() == 5,
                   "intrinsics: radtan takes 4 or 5 coefficients, got {}", distortion.size());
      names = kRadtan;
      break;
    case DistortionModel::kEquidistant:
      SL_CHECK_MSG(distortion.size() == 4, "intrinsics: equidistant takes 4 coefficients, got {}",
                   distortion.size());
      names = kEquidistant;
      break;
  }
  for (size_t i = 0; i < distortion.size(); ++i) {
    SL_CHECK_MSG(
        std::isfinite(distortion[i]) && std::abs(distortion[i]) <= kMaxDistortionCoefficient,
        "intrinsics: distortion coefficient {} must be finite and within +-{:g} (real "
        "lenses' are of order 1), got {}",
        names[i], kMaxDistortionCoefficient, distortion[i]);
  }
}

Eigen::Vector2d CameraIntrinsics::Unproject(const Eigen::Vector2d& pixel) const {
  return {(pixel.x() - cx) / fx, (pixel.y() - cy) / fy};
}

Eigen::Vector2d CameraIntrinsics::Project(const Eigen::Vector3d& p_in_cam) const {
  return {fx * p_in_cam.x() / p_in_cam.z() + cx, fy * p_in_cam.y() / p_in_cam.z() + cy};
}

std::string ToString(DistortionModel model) {
  switch (model) {
    case DistortionModel::kNone:
      return "none";
    case DistortionModel::kRadialTangential:
      return "radtan";
    case DistortionModel::kEquidistant:
      return "equidistant";
  }
  return "unknown";
}

}  // namespace sparseloop
