// The castle ring family: the Strecha castle-P30 ring (real images, exact poses) with raw
// poses made by drifting the GT relative motions (a heading bias per keyframe and / or a scale
// growth per keyframe, plus seeded random per-step noise). The pipeline must find the ring
// closure and the corrected trajectory must be much closer to the GT than the raw one: a verified
// loop pulls the drift back (docs/POSEGRAPH.md, "Loop information").
// The same family under a bias about the other camera axes (pitch, roll): the drift is the one
// named, the ring closure is found with an accurate loop, and the correction holds
// (bench/castle_drift measures the whole family).
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "castle_input.h"
#include "sparseloop/eval/metrics.h"
#include "sparseloop/pipeline/pipeline.h"
#include "test_util.h"

namespace sparseloop {
namespace {

using test::CastleDrift;
using test::CastleRing;

double Ate(const Trajectory& gt, const Trajectory& est) {
  EvaluationOptions options;
  options.compute_rpe = false;
  options.compute_kitti = false;
  return EvaluateTrajectory(gt, est, options).ate.rmse;
}

struct FamilyRow {
  CastleDrift spec;
  double raw_ate = 0.0;
  double corrected_ate = 0.0;
  int loops = 0;
  int accepted = 0;
};

FamilyRow RunFamilyRow(const CastleRing& castle, const CastleDrift& spec,
                       const PipelineOptions& options) {
  FamilyRow row;
  row.spec = spec;
  const Trajectory raw = test::DriftCastle(castle.gt, spec);
  const PipelineResult result = RunPipeline(castle.dataset, raw, options);
  row.raw_ate = Ate(castle.gt, raw);
  row.corrected_ate = Ate(castle.gt, result.corrected);
  row.loops = static_cast<int>(result.loops.size());
  for (bool a : result.loop_accepted) row.accepted += a ? 1 : 0;
  return row;
}

// A heading (yaw) bias per keyframe: about the camera's y axis (image down).
CastleDrift Yaw(double deg, double scale_step, uint64_t seed) {
  return {Eigen::Vector3d(0.0, deg, 0.0), scale_step, seed};
}

std::vector<CastleDrift> FamilySpecs() {
  std::vector<CastleDrift> specs;
  // The five reference rows (heading bias and scale growth), then the same up to 1 deg and 1 % per
  // keyframe with noise seeds.
  const std::vector<std::pair<double, double>> biases = {
      {0.2, 1.003}, {0.5, 1.005}, {1.0, 1.0}, {0.0, 1.01}, {1.0, 1.01}};
  for (const auto& [yaw, scale] : biases) specs.push_back(Yaw(yaw, scale, 0));
  for (uint64_t seed : {11u, 12u}) {
    for (const auto& [yaw, scale] : biases) specs.push_back(Yaw(yaw, scale, seed));
  }
  return specs;
}

// Every raw step of test::DriftCastle is the GT step turned by exactly the bias, about the camera
// axis it names (x pitch, y yaw, z roll) and with its sign, its length times scale_step^i: a bias
// applied about another axis, in the world frame, with the other sign or another magnitude fails.
TEST(CastleDriftFamily, BiasTurnsEveryStepAboutItsCameraAxis) {
  SL_REQUIRE_DATA("castle_p30_768/gt_dense_cameras/0029.jpg.camera");
  const Trajectory gt = test::LoadCastleRing().gt;
  ASSERT_EQ(gt.size(), 30u);
  for (int axis = 0; axis < 3; ++axis) {
    for (const double deg : {0.2, 1.0, -0.5}) {
      SCOPED_TRACE(fmt::format("axis {} bias {} deg", axis, deg));
      const CastleDrift spec{deg * Eigen::Vector3d::Unit(axis), 1.01, 0};
      const Trajectory raw = test::DriftCastle(gt, spec);
      ASSERT_EQ(raw.size(), gt.size());
      const Eigen::Vector3d expected = deg * M_PI / 180.0 * Eigen::Vector3d::Unit(axis);
      for (size_t i = 1; i < gt.size(); ++i) {
        const Rigid3d g = gt.poses[i - 1].world_from_cam.Inverse() * gt.poses[i].world_from_cam;
        const Rigid3d r = raw.poses[i - 1].world_from_cam.Inverse() * raw.poses[i].world_from_cam;
        EXPECT_LT((LogSO3(g.rotation.conjugate() * r.rotation) - expected).norm(), 1e-9) << i;
        EXPECT_LT((r.translation - std::pow(1.01, i) * g.translation).norm(),
                  1e-9 * g.translation.norm())
            << i;
      }
      // Keyframe 1 (keyframe 0 exact): the camera axis of the bias is the GT's, the two others
      // are turned by |bias| about it.
      const Eigen::Matrix3d r1 = raw.poses[1].world_from_cam.rotation.toRotationMatrix();
      const Eigen::Matrix3d g1 = gt.poses[1].world_from_cam.rotation.toRotationMatrix();
      EXPECT_LT((r1.col(axis) - g1.col(axis)).norm(), 1e-12);
      for (int other = 0; other < 3; ++other) {
        if (other == axis) continue;
        EXPECT_NEAR(std::acos(std::clamp(r1.col(other).dot(g1.col(other)), -1.0, 1.0)),
                    std::abs(expected[axis]), 1e-7);
      }
    }
  }
  // The heading bias of the family (about y) and no bias at all are what they were before the
  // other axes: steps turned about y only, and the exact poses up to rounding.
  const Trajectory none = test::DriftCastle(gt, {});
  for (size_t i = 0; i < gt.size(); ++i) {
    EXPECT_LT(
        RotationAngle(none.poses[i].world_from_cam.rotation, gt.poses[i].world_from_cam.rotation),
        1e-9);
    EXPECT_LT(
        (none.poses[i].world_from_cam.translation - gt.poses[i].world_from_cam.translation).norm(),
        1e-9);
  }
}

// Seeded noise comes on top of the bias: the same seed gives the same noise whatever the bias, so
// the biased and the unbiased raw steps differ by exactly the bias.
TEST(CastleDriftFamily, NoiseDoesNotDependOnTheBias) {
  SL_REQUIRE_DATA("castle_p30_768/gt_dense_cameras/0029.jpg.camera");
  const Trajectory gt = test::LoadCastleRing().gt;
  const Trajectory plain = test::DriftCastle(gt, {Eigen::Vector3d::Zero(), 1.0, 12});
  const Trajectory pitched = test::DriftCastle(gt, {Eigen::Vector3d(0.5, 0.0, 0.0), 1.0, 12});
  const Trajectory other_seed = test::DriftCastle(gt, {Eigen::Vector3d::Zero(), 1.0, 13});
  double seed_change = 0.0;
  for (size_t i = 1; i < gt.size(); ++i) {
    const auto step = [&](const Trajectory& t) {
      return t.poses[i - 1].world_from_cam.Inverse() * t.poses[i].world_from_cam;
    };
    const Rigid3d a = step(plain), b = step(pitched);
    // Exp(bias) sits between the GT step and the noise: noise^-1 Exp(bias) noise, a rotation of
    // the same angle about a nearby axis.
    EXPECT_NEAR(RotationAngle(a.rotation, b.rotation), 0.5 * M_PI / 180.0, 1e-9) << i;
    EXPECT_LT((a.translation - b.translation).norm(), 1e-9) << i;
    seed_change = std::max(seed_change, RotationAngle(a.rotation, step(other_seed).rotation));
  }
  EXPECT_GT(seed_change, 1e-4);  // the seed does change the noise
}

// The ring under pitch and roll bias, two magnitudes, one seed (bench/castle_drift measures the
// whole family): doubling the bias doubles the raw ATE; the ring closure is found, accepted,
// metric and within 1 deg of the exact relative pose whatever the bias; no other loop is
// accepted; the correction brings pitch under 40 % of raw and roll under 75 %.
TEST(CastleDriftFamily, PitchAndRollBiasCloseTheRingWithAnAccurateLoop) {
  SL_REQUIRE_DATA("castle_p30_768/images/0029.jpg");
  const CastleRing castle = test::LoadCastleRing();
  const PipelineOptions options;
  for (const int axis : {0, 2}) {
    double previous_raw_ate = 0.0;
    for (const double deg : {0.5, 1.0}) {
      const CastleDrift spec{deg * Eigen::Vector3d::Unit(axis), 1.0, 11};
      SCOPED_TRACE(fmt::format("{} {} deg", axis == 0 ? "pitch" : "roll", deg));
      const Trajectory raw = test::DriftCastle(castle.gt, spec);
      const PipelineResult result = RunPipeline(castle.dataset, raw, options);
      const double raw_ate = Ate(castle.gt, raw), corrected_ate = Ate(castle.gt, result.corrected);
      int accepted = 0;
      for (size_t i = 0; i < result.loops.size(); ++i) {
        if (!result.loop_accepted[i]) continue;
        ++accepted;
        const LoopResult& loop = result.loops[i];
        const Rigid3d exact = castle.gt.poses.at(loop.match_id).world_from_cam.Inverse() *
                              castle.gt.poses.at(loop.query_id).world_from_cam;
        // The ring closure (views at both ends of the ring), metric, its rotation within 1 deg
        // of the exact one: the local map's relative poses come from the images, so the loop
        // does not inherit the bias (with the raw relative poses 29 -> 02 was a two-view loop
        // 5.4 deg off under pitch, and 1.8 / 2.8 deg off under 0.5 / 1 deg of roll).
        EXPECT_GE(std::abs(loop.query_id - loop.match_id), 25)
            << loop.query_id << " -> " << loop.match_id;
        EXPECT_NE(loop.pose_kind, RelativePoseKind::kSE3UnitTranslation);
        EXPECT_GT(loop.local_poses_from_images, loop.local_poses_raw);
        EXPECT_LT(RotationAngle(exact.rotation, loop.match_from_query.rotation) * 180.0 / M_PI, 1.0)
            << loop.query_id << " -> " << loop.match_id;
      }
      std::cerr << fmt::format(
          "castle {} {:.1f} deg, seed 11: raw ATE {:.3f}, corrected {:.3f} ({:.0f} %), accepted "
          "{}\n",
          axis == 0 ? "pitch" : "roll", deg, raw_ate, corrected_ate,
          100.0 * corrected_ate / raw_ate, accepted);
      EXPECT_GE(accepted, 1);
      // Pitch: 10-17 % of raw. Roll: 45-55 % (seed 11); the 40 % target is not met under roll
      // (docs/POSEGRAPH.md, "Under pitch and roll"), but the correction no longer makes the
      // trajectory worse than raw (119-129 % with the raw relative poses).
      EXPECT_LT(corrected_ate, (axis == 0 ? 0.4 : 0.75) * raw_ate);
      if (previous_raw_ate > 0.0) {
        EXPECT_GT(raw_ate, 1.6 * previous_raw_ate);
        EXPECT_LT(raw_ate, 2.4 * previous_raw_ate);
      }
      previous_raw_ate = raw_ate;
    }
  }
}

TEST(CastleDriftFamily, CorrectedAteIsAtMost40PercentOfRaw) {
  SL_REQUIRE_DATA("castle_p30_768/images/0029.jpg");
  const CastleRing castle = test::LoadCastleRing();
  const PipelineOptions options;
  for (const CastleDrift& spec : FamilySpecs()) {
    const FamilyRow row = RunFamilyRow(castle, spec, options);
    std::cerr << fmt::format(
        "castle drift {:.1f} deg, x{:.3f}, seed {}: raw ATE {:.3f}, corrected {:.3f} ({:.0f} %), "
        "loops {} accepted {}\n",
        spec.bias_deg.y(), spec.scale_step, spec.seed, row.raw_ate, row.corrected_ate,
        100.0 * row.corrected_ate / row.raw_ate, row.loops, row.accepted);
    EXPECT_GE(row.accepted, 1) << spec.bias_deg.y() << " " << spec.scale_step << " " << spec.seed;
    EXPECT_LE(row.corrected_ate, 0.4 * row.raw_ate)
        << spec.bias_deg.y() << " deg, x" << spec.scale_step << ", seed " << spec.seed;
  }
}

}  // namespace
}  // namespace sparseloop
