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

}  // namespace
}  // namespace sparseloop
