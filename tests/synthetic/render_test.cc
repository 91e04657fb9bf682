#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "cameras.h"
#include "sparseloop/synthetic/renderer.h"
#include "sparseloop/synthetic/worlds.h"
#include "test_util.h"

namespace sparseloop::synthetic {
namespace {

std::shared_ptr<const TextureSet> SmallTextures() {
  ProceduralTextureOptions o;
  o.count = 4;
  o.size = 256;
  return MakeProceduralTextures(o);
}

CameraIntrinsics SmallCamera() { return test::PinholeCamera(200.0, 160, 120, 79.5, 59.5); }

// Nadir camera at (x, y, altitude), heading `yaw` (rad) about world z.
Rigid3d NadirPose(double x, double y, double altitude, double yaw) {
  const Eigen::Vector3d forward(std::cos(yaw), std::sin(yaw), 0.0);
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  Eigen::Matrix3d R;
  R.col(2) = -up;
  R.col(0) = forward.cross(up);
  R.col(1) = R.col(2).cross(R.col(0));
  return Rigid3d(Eigen::Quaterniond(R), Eigen::Vector3d(x, y, altitude));
}

float Bilinear(const Image8& img, double u, double v) {
  const int u0 = static_cast<int>(std::floor(u)), v0 = static_cast<int>(std::floor(v));
  const double a = u - u0, b = v - v0;
  auto at = [&](int x, int y) { return static_cast<double>(img.at(x, y)); };
  return static_cast<float>((1 - a) * (1 - b) * at(u0, v0) + a * (1 - b) * at(u0 + 1, v0) +
                            (1 - a) * b * at(u0, v0 + 1) + a * b * at(u0 + 1, v0 + 1));
}

TEST(Render, SameSeedSameBytesForAnyThreadCount) {
  const World world = MakeAerialWorld(SmallTextures());
  RenderOptions o;
  o.noise_sigma = 2.0;
  o.blur_sigma = 0.8;
  const Rigid3d pose = NadirPose(3.0, -7.0, 40.0, 0.4);
  const Photometric ph{1.1, 0.9};
  const auto a = RenderFrame(world, SmallCamera(), pose, o, ph, 7);
  o.num_threads = 3;
  const auto b = RenderFrame(world, SmallCamera(), pose, o, ph, 7);
  EXPECT_EQ(a.image.pixels, b.image.pixels);
  EXPECT_EQ(a.depth.depth, b.depth.depth);
  // A different frame seed changes the noise only.
  const auto c = RenderFrame(world, SmallCamera(), pose, o, ph, 8);
  EXPECT_NE(a.image.pixels, c.image.pixels);
  EXPECT_EQ(a.depth.depth, c.depth.depth);
  // Not a flat image.
  const auto [mn, mx] = std::minmax_element(a.image.pixels.begin(), a.image.pixels.end());
  EXPECT_GT(*mx - *mn, 60);
}

TEST(Render, NadirDepthEqualsAltitudeExactly) {
  const World world = MakeAerialWorld(SmallTextures());
  const auto f = RenderFrame(world, SmallCamera(), NadirPose(0, 0, 37.5, 1.0), {});
  for (float d : f.depth.depth) ASSERT_NEAR(d, 37.5f, 1e-4f);
}

TEST(Render, TiltedDepthMatchesRayPlaneOracle) {
  const World world = MakeAerialWorld(SmallTextures());
  // Tilted 30 deg: the top rows see the sky when the tilt is large; here all rows hit ground.
  FlightPlanOptions plan;
  plan.tilt_deg = 30.0;
  plan.frames = 10;
  const Rigid3d pose = MakeFlightTrajectory(plan).poses[3].world_from_cam;
  const CameraIntrinsics cam = SmallCamera();
  const auto f = RenderFrame(world, cam, pose, {});
  for (int v = 0; v < cam.height; v += 7)
    for (int u = 0; u < cam.width; u += 7) {
      const Eigen::Vector3d d_cam = cam.Unproject(Eigen::Vector2d(u, v)).homogeneous();
      const Eigen::Vector3d d_world = pose.rotation * d_cam;
      // Oracle: plane z = 0, z-depth = camera height / (-d_world.z) for the z=1 ray.
      const double expected = pose.translation.z() / -d_world.z();
      ASSERT_NEAR(f.depth.at(u, v), expected, 1e-4 * expected) << u << "," << v;
    }
}

// Back-project a pixel with its depth, project into a second GT pose: the second ray must hit the
// same world point, and the rendered intensities must agree (sub-pixel).
TEST(Render, ReprojectionThroughDepthLandsOnTheSameTexturePoint) {
  const World world = MakeAerialWorld(SmallTextures());
  const CameraIntrinsics cam = SmallCamera();
  const Rigid3d a = NadirPose(0.0, 0.0, 30.0, 0.2);
  const Rigid3d b = NadirPose(2.3, -1.7, 31.0, 0.35);
  RenderOptions o;
  o.noise_sigma = 0.0;
  const auto fa = RenderFrame(world, cam, a, o);
  const auto fb = RenderFrame(world, cam, b, o);
  std::vector<double> diff_right, diff_shifted;
  int checked = 0;
  for (int v = 10; v < cam.height - 10; v += 3) {
    for (int u = 10; u < cam.width - 10; u += 3) {
      const double depth = fa.depth.at(u, v);
      ASSERT_GT(depth, 0.0);
      const Eigen::Vector3d p_in_world =
          a * (depth * cam.Unproject(Eigen::Vector2d(u, v)).homogeneous());
      // The depth map is exact: tracing the same ray hits the same point.
      const Hit hit_a = world.Trace(a.translation, p_in_world - a.translation);
      ASSERT_LT((hit_a.p_in_world - p_in_world).norm(), 1e-6);
      const Eigen::Vector3d p_in_b = b.Inverse() * p_in_world;
      const Eigen::Vector2d uv = cam.Project(p_in_b);
      if (uv.x() < 2 || uv.y() < 2 || uv.x() > cam.width - 3 || uv.y() > cam.height - 3) continue;
      const Eigen::Vector3d ray_b = b.rotation * cam.Unproject(uv).homogeneous();
      const Hit hit_b = world.Trace(b.translation, ray_b);
      ASSERT_LT((hit_b.p_in_world - p_in_world).norm(), 1e-6);
      EXPECT_LT((hit_b.st - hit_a.st).norm(), 1e-6);
      diff_right.push_back(std::abs(Bilinear(fb.image, uv.x(), uv.y()) - fa.image.at(u, v)));
      diff_shifted.push_back(
          std::abs(Bilinear(fb.image, uv.x() + 1.0, uv.y() + 0.5) - fa.image.at(u, v)));
      ++checked;
    }
  }
  ASSERT_GT(checked, 500);
  auto median = [](std::vector<double> x) {
    std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
    return x[x.size() / 2];
  };
  const double m_right = median(diff_right), m_shifted = median(diff_shifted);
  EXPECT_LT(m_right, 3.0);
  EXPECT_GT(m_shifted, 2.0 * m_right + 1.0) << "a 1-pixel error must be visible";
}

// A checkerboard of single texels seen far away must average to grey (no aliasing).
TEST(Render, DistantFineCheckerboardAveragesToGrey) {
  auto set = std::make_shared<TextureSet>();
  std::vector<uint8_t> checker(64 * 64);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) checker[y * 64 + x] = ((x + y) % 2) ? 255 : 0;
  set->textures.emplace_back(64, 64, checker);
  set->names.push_back("checker");
  World world;
  world.textures = set;
  Material m;
  m.texels_per_metre = 100.0;  // 1 cm texels
  world.materials.push_back(m);
  Quad plane;
  plane.infinite = true;
  world.quads.push_back(plane);
  RenderOptions o;
  o.noise_sigma = 0.0;
  const auto f = RenderFrame(world, SmallCamera(), NadirPose(0, 0, 50.0, 0.0), o);
  double sum = 0, sum2 = 0;
  for (uint8_t p : f.image.pixels) sum += p, sum2 += static_cast<double>(p) * p;
  const double n = static_cast<double>(f.image.pixels.size());
  const double mean = sum / n, stddev = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 127.5, 3.0);
  EXPECT_LT(stddev, 5.0);  // point sampling would give ~127
}

TEST(Render, PhotometricDriftChangesOverTime) {
  PhotometricDriftOptions o;
  const auto p0 = PhotometricForFrame(0, o);
  const auto p1 = PhotometricForFrame(300, o);
  EXPECT_GT(std::abs(p0.gain - p1.gain) + std::abs(p0.gamma - p1.gamma), 0.02);
  for (int i = 0; i < 3000; i += 97) {
    const auto p = PhotometricForFrame(i, o);
    EXPECT_LE(std::abs(p.gain - 1.0), o.gain_amplitude + 1e-12);
    EXPECT_LE(std::abs(p.gamma - 1.0), o.gamma_amplitude + 1e-12);
  }
  const auto again = PhotometricForFrame(300, o);
  EXPECT_EQ(again.gain, p1.gain);
}

TEST(Render, RejectsBadOptions) {
  const World world = MakeAerialWorld(SmallTextures());
  RenderOptions o;
  o.num_threads = 0;
  EXPECT_THROW(RenderFrame(world, SmallCamera(), Rigid3d(), o), std::invalid_argument);
  CameraIntrinsics no_size = SmallCamera();
  no_size.width = 0;
  EXPECT_THROW(RenderFrame(world, no_size, Rigid3d(), {}), std::invalid_argument);
}

}  // namespace
}  // namespace sparseloop::synthetic
