#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "sparseloop/core/camera.h"

namespace sparseloop {
namespace {

CameraIntrinsics Kitti() {
  CameraIntrinsics c;
  c.fx = c.fy = 718.856;
  c.cx = 607.1928;
  c.cy = 185.2157;
  c.width = 1241;
  c.height = 376;
  return c;
}

TEST(Camera, ProjectUnprojectRoundTrip) {
  const CameraIntrinsics c = Kitti();
  EXPECT_NO_THROW(c.Check());
  const Eigen::Vector3d p(1.0, -0.5, 7.0);
  const Eigen::Vector2d px = c.Project(p);
  EXPECT_NEAR((c.Unproject(px) - p.head<2>() / p.z()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(((c.K() * p).hnormalized() - px).norm(), 0.0, 1e-9);
}

TEST(Camera, CheckRejectsBadFields) {
  CameraIntrinsics c = Kitti();
  c.fx = -1;
  EXPECT_THROW(c.Check(), std::invalid_argument);
  c = Kitti();
  c.cx = 5000;
  EXPECT_THROW(c.Check(), std::invalid_argument);
  c = Kitti();
  c.distortion_model = DistortionModel::kRadialTangential;
  c.distortion = {0.1};
  EXPECT_THROW(c.Check(), std::invalid_argument);
  c.distortion = {0.1, 0.01, 0.0, 0.0};
  EXPECT_NO_THROW(c.Check());
}

// A distortion coefficient beyond any lens (1e10: a unit or transcription error) is refused
// naming the coefficient; cv::undistortPoints gave nonsense keypoints without a word.
TEST(Camera, CheckRejectsAbsurdDistortion) {
  CameraIntrinsics c = Kitti();
  c.distortion_model = DistortionModel::kRadialTangential;
  c.distortion = {1e10, 0.0, 0.0, 0.0};
  try {
    c.Check();
    ADD_FAILURE() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("k1"), std::string::npos) << e.what();
  }
  c.distortion = {-0.28, 0.07, 2e-4, 2e-5, -150.0};
  EXPECT_THROW(c.Check(), std::invalid_argument);
  c.distortion = {-0.28, 0.07, 2e-4, 2e-5, 1.2};
  EXPECT_NO_THROW(c.Check());
  c.distortion_model = DistortionModel::kEquidistant;
  c.distortion = {0.0035, 0.0007, -0.002, 1e3};
  EXPECT_THROW(c.Check(), std::invalid_argument);
}

}  // namespace
}  // namespace sparseloop
