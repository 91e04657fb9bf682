#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "sparseloop/synthetic/vslam_sim.h"
#include "test_util.h"

namespace sparseloop::synthetic {
namespace {

// A straight drive along camera z (KITTI-like), 1 m per frame, with a gentle turn.
Trajectory StraightDrive(int n) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    StampedPose p;
    p.frame = i;
    p.timestamp = 0.1 * i;
    const double yaw = 0.002 * i;
    p.world_from_cam = Rigid3d(ExpSO3(Eigen::Vector3d(0, yaw, 0)),
                               Eigen::Vector3d(std::sin(yaw) * i, 0.0, std::cos(yaw) * i));
    t.poses.push_back(p);
  }
  return t;
}

DriftOptions NoDrift() {
  DriftOptions o;
  o.rotation_noise_deg_per_sqrt_m = 0.0;
  o.rotation_bias_deg_per_100m.setZero();
  o.translation_noise = 0.0;
  o.scale_noise_per_sqrt_m = 0.0;
  o.scale_bias_per_100m = 0.0;
  return o;
}

TEST(SimulateDrift, NoDriftReproducesGroundTruth) {
  const Trajectory gt = StraightDrive(200);
  const auto r = SimulateDrift(gt, NoDrift());
  ASSERT_EQ(r.raw.size(), gt.size());
  for (size_t i = 0; i < gt.size(); ++i) {
    EXPECT_LT(
        (r.raw.poses[i].world_from_cam.translation - gt.poses[i].world_from_cam.translation).norm(),
        1e-9);
    EXPECT_LT(
        RotationAngle(r.raw.poses[i].world_from_cam.rotation, gt.poses[i].world_from_cam.rotation),
        1e-9);
    EXPECT_EQ(r.raw.poses[i].timestamp, gt.poses[i].timestamp);
    EXPECT_DOUBLE_EQ(r.scale[i], 1.0);
  }
}

TEST(SimulateDrift, YawBiasAccumulatesLinearlyWithDistance) {
  const Trajectory gt = StraightDrive(1001);  // 1000 m
  DriftOptions o = NoDrift();
  o.rotation_bias_deg_per_100m = {0.0, 1.0, 0.0};
  const auto r = SimulateDrift(gt, o);
  // The heading error is 1 deg per 100 m of path (biases about the same axis add up).
  const double path = gt.CumulativeDistances().back();
  const double err = RotationAngle(r.raw.poses.back().world_from_cam.rotation,
                                   gt.poses.back().world_from_cam.rotation);
  EXPECT_NEAR(err * 180.0 / M_PI, path / 100.0, 1e-6);
}

TEST(SimulateDrift, ChainStepsCarryTheScale) {
  const Trajectory gt = StraightDrive(300);
  DriftOptions o = NoDrift();
  o.scale_bias_per_100m = 0.2;
  o.scale_noise_per_sqrt_m = 0.01;
  o.initial_scale = 2.0;
  const auto r = SimulateDrift(gt, o);
  EXPECT_DOUBLE_EQ(r.scale[0], 2.0);
  for (size_t i = 0; i + 1 < gt.size(); ++i) {
    const Rigid3d raw_rel =
        r.raw.poses[i].world_from_cam.Inverse() * r.raw.poses[i + 1].world_from_cam;
    const Rigid3d gt_rel = gt.poses[i].world_from_cam.Inverse() * gt.poses[i + 1].world_from_cam;
    // raw_{i+1} = raw_i * [R | s t]: same relative rotation, translation scaled by s_{i+1}.
    EXPECT_NEAR(raw_rel.translation.norm() / gt_rel.translation.norm(), r.scale[i + 1], 1e-9);
    EXPECT_LT(RotationAngle(raw_rel.rotation, gt_rel.rotation), 1e-9);
  }
  // Scale drift with positive bias grows: exp(0.2 * 3) ~ 1.8 ratio over 300 m (noise is small).
  EXPECT_GT(r.scale.back() / r.scale.front(), 1.4);
  // LocalScale recovers the simulated scale from the trajectories alone.
  const auto est = LocalScale(gt, r.raw, 3);
  for (size_t i = 10; i + 10 < gt.size(); i += 37)
    EXPECT_NEAR(est[i], r.scale[i], 0.05 * r.scale[i]);
}

// The relative rotation of raw step i: gt_rel^-1 raw_rel as a rotation vector (rad).
Eigen::Vector3d StepRotationError(const Trajectory& gt, const Trajectory& raw, size_t i) {
  const Rigid3d raw_rel = raw.poses[i].world_from_cam.Inverse() * raw.poses[i + 1].world_from_cam;
  const Rigid3d gt_rel = gt.poses[i].world_from_cam.Inverse() * gt.poses[i + 1].world_from_cam;
  return LogSO3(gt_rel.rotation.conjugate() * raw_rel.rotation);
}

// A bias per frame about one camera axis (x pitch, y yaw, z roll): every raw step's rotation
// differs from the GT step's by exactly that rotation, whatever the step length, and the steps'
// translations are the GT's.
TEST(SimulateDrift, PerFrameBiasIsEveryStepsRotationError) {
  const Trajectory gt = StraightDrive(50);
  for (int axis = 0; axis < 3; ++axis) {
    SCOPED_TRACE(axis);
    DriftOptions o = NoDrift();
    o.rotation_bias_deg_per_frame = 0.7 * Eigen::Vector3d::Unit(axis);
    const auto r = SimulateDrift(gt, o);
    const Eigen::Vector3d expected = 0.7 * M_PI / 180.0 * Eigen::Vector3d::Unit(axis);
    for (size_t i = 0; i + 1 < gt.size(); ++i) {
      EXPECT_LT((StepRotationError(gt, r.raw, i) - expected).norm(), 1e-12) << i;
      const Rigid3d raw_rel =
          r.raw.poses[i].world_from_cam.Inverse() * r.raw.poses[i + 1].world_from_cam;
      const Rigid3d gt_rel = gt.poses[i].world_from_cam.Inverse() * gt.poses[i + 1].world_from_cam;
      EXPECT_LT((raw_rel.translation - gt_rel.translation).norm(), 1e-9) << i;
    }
    // About y, the axis of the drive's own turn, the 49 steps' errors add up to 34.3 deg.
    if (axis == 1) {
      EXPECT_NEAR(RotationAngle(r.raw.poses.back().world_from_cam.rotation,
                                gt.poses.back().world_from_cam.rotation) *
                      180.0 / M_PI,
                  49 * 0.7, 1e-6);
    }
  }
}

// With the default noise and per-metre bias, the per-frame bias is one more factor per step and
// draws no random numbers: the same seed gives the same steps, each turned by exactly the bias.
TEST(SimulateDrift, PerFrameBiasComposesWithTheNoise) {
  const Trajectory gt = StraightDrive(100);
  DriftOptions o;
  const auto plain = SimulateDrift(gt, o);
  o.rotation_bias_deg_per_frame = {0.3, -0.2, 0.5};
  const auto biased = SimulateDrift(gt, o);
  const Eigen::Quaterniond bias = ExpSO3(o.rotation_bias_deg_per_frame * M_PI / 180.0);
  for (size_t i = 0; i + 1 < gt.size(); ++i) {
    const Rigid3d a =
        plain.raw.poses[i].world_from_cam.Inverse() * plain.raw.poses[i + 1].world_from_cam;
    const Rigid3d b =
        biased.raw.poses[i].world_from_cam.Inverse() * biased.raw.poses[i + 1].world_from_cam;
    EXPECT_LT(RotationAngle(b.rotation, a.rotation * bias), 1e-12) << i;
    EXPECT_LT((b.translation - a.translation).norm(), 1e-9) << i;
    EXPECT_DOUBLE_EQ(biased.scale[i + 1], plain.scale[i + 1]);
  }
}

TEST(SimulateDrift, PerFrameBiasMustBeFiniteAndBelow180Degrees) {
  const Trajectory gt = StraightDrive(5);
  DriftOptions o;
  for (const Eigen::Vector3d& bad :
       {Eigen::Vector3d(std::nan(""), 0.0, 0.0), Eigen::Vector3d(0.0, 0.0, 180.0),
        Eigen::Vector3d(150.0, 150.0, 0.0)}) {
    o.rotation_bias_deg_per_frame = bad;
    EXPECT_THROW(
        {
          try {
            SimulateDrift(gt, o);
          } catch (const std::invalid_argument& e) {
            EXPECT_NE(std::string(e.what()).find("rotation_bias_per_frame"), std::string::npos)
                << e.what();
            throw;
          }
        },
        std::invalid_argument);
  }
  o.rotation_bias_deg_per_frame = {0.0, 0.0, 179.0};
  EXPECT_NO_THROW(SimulateDrift(gt, o));
}

TEST(SimulateDrift, SeededAndNoisy) {
  const Trajectory gt = StraightDrive(300);
  DriftOptions o;
  const auto a = SimulateDrift(gt, o);
  const auto b = SimulateDrift(gt, o);
  o.seed += 1;
  const auto c = SimulateDrift(gt, o);
  EXPECT_EQ(a.raw.poses.back().world_from_cam.ToVector(),
            b.raw.poses.back().world_from_cam.ToVector());
  EXPECT_GT((a.raw.poses.back().world_from_cam.translation -
             c.raw.poses.back().world_from_cam.translation)
                .norm(),
            1e-3);
  o.initial_scale = 0.0;
  EXPECT_THROW(SimulateDrift(gt, o), std::invalid_argument);
}

TEST(SelectMappedPixels, PicksEdgesWithValidDepthInRawScale) {
  Image8 img;
  DepthMap depth;
  img.width = depth.width = 64;
  img.height = depth.height = 48;
  img.pixels.assign(64 * 48, 50);
  depth.depth.assign(64 * 48, 4.0f);
  for (int v = 0; v < 48; ++v)
    for (int u = 30; u < 64; ++u) img.pixels[v * 64 + u] = 200;  // vertical edge at u = 29.5
  for (int v = 0; v < 24; ++v)
    for (int u = 0; u < 64; ++u) depth.depth[v * 64 + u] = 0.0f;  // top half is sky
  MappedPixelOptions o;
  o.cell_size = 8;
  o.border = 2;
  const auto px = SelectMappedPixels(img, depth, 0.5, o);
  ASSERT_FALSE(px.empty());
  for (const auto& p : px) {
    EXPECT_TRUE(p.u == 29.0f || p.u == 30.0f) << p.u;
    EXPECT_GE(p.v, 24.0f);
    EXPECT_FLOAT_EQ(p.depth, 2.0f);
  }
}

}  // namespace
}  // namespace sparseloop::synthetic
