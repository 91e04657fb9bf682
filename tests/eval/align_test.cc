#include "sparseloop/eval/align.h"

#include <gtest/gtest.h>

#include "eval/eval_test_util.h"
#include "sparseloop/eval/metrics.h"
#include "test_util.h"

namespace sparseloop {
namespace {

using test::MakeLoopTrajectory;
using test::RandomSim3;

std::vector<Eigen::Vector3d> Transform(const Sim3d& t, const std::vector<Eigen::Vector3d>& pts) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : pts) out.push_back(t * p);
  return out;
}

void ExpectSim3Near(const Sim3d& a, const Sim3d& b, double tol) {
  EXPECT_NEAR(a.scale, b.scale, tol * b.scale);
  EXPECT_LE(RotationAngle(a.rotation, b.rotation), tol);
  EXPECT_LE((a.translation - b.translation).norm(), tol * (1.0 + b.translation.norm()));
}

TEST(Umeyama, Sim3RecoversRandomTransformOnLoop) {
  auto rng = test::SeededRng(1);
  const auto gt = MakeLoopTrajectory(500).Positions();
  for (int trial = 0; trial < 20; ++trial) {
    const Sim3d gt_from_est = RandomSim3(rng);
    // est = inverse transform of gt, so aligning est back onto gt must find gt_from_est.
    const auto est = Transform(gt_from_est.Inverse(), gt);
    const auto result = Umeyama(est, gt, Alignment::kSim3);
    EXPECT_EQ(result.status, AlignmentStatus::kOk);
    EXPECT_EQ(result.num_points, gt.size());
    ExpectSim3Near(result.gt_from_est, gt_from_est, 1e-9);
    EXPECT_LT(result.rms_residual, 1e-9);
    EXPECT_LT(ComputeAte(gt, est, result.gt_from_est).max, 1e-9);
  }
}

TEST(Umeyama, Se3RecoversRigidTransformAndKeepsScaleOne) {
  auto rng = test::SeededRng(2);
  const auto gt = MakeLoopTrajectory(300).Positions();
  Sim3d rigid = RandomSim3(rng);
  rigid.scale = 1.0;
  const auto est = Transform(rigid.Inverse(), gt);
  const auto result = Umeyama(est, gt, Alignment::kSE3);
  EXPECT_EQ(result.status, AlignmentStatus::kOk);
  ExpectSim3Near(result.gt_from_est, rigid, 1e-9);
  EXPECT_EQ(result.gt_from_est.scale, 1.0);
}

TEST(Umeyama, Se3CannotFixScaleButSim3Can) {
  const auto gt = MakeLoopTrajectory(200).Positions();
  const auto est =
      Transform(Sim3d(0.5, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()), gt);
  EXPECT_GT(ComputeAte(gt, est, Umeyama(est, gt, Alignment::kSE3).gt_from_est).rmse, 1.0);
  const auto sim3 = Umeyama(est, gt, Alignment::kSim3);
  EXPECT_NEAR(sim3.gt_from_est.scale, 2.0, 1e-12);
  EXPECT_LT(ComputeAte(gt, est, sim3.gt_from_est).rmse, 1e-9);
}

TEST(Umeyama, MatchesBruteForceOnNoisyData) {
  // With noise there is no exact transform: the closed form must be a local minimum of the
  // squared error, i.e. no small perturbation of (scale, rotation, translation) improves it.
  auto rng = test::SeededRng(3);
  const auto gt = MakeLoopTrajectory(100).Positions();
  std::normal_distribution<double> noise(0.0, 0.5);
  auto est = Transform(RandomSim3(rng), gt);
  for (auto& p : est) p += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  const auto result = Umeyama(est, gt, Alignment::kSim3);
  auto cost = [&](const Sim3d& t) {
    double c = 0;
    for (size_t i = 0; i < gt.size(); ++i) c += (gt[i] - t * est[i]).squaredNorm();
    return c;
  };
  const double best = cost(result.gt_from_est);
  for (int k = 0; k < 7; ++k) {
    for (double sign : {-1.0, 1.0}) {
      Vector7d d = Vector7d::Zero();
      d(k) = sign * 1e-4;
      const Sim3d perturbed = result.gt_from_est * Sim3d::Exp(d);
      EXPECT_GE(cost(perturbed), best) << "tangent " << k << " sign " << sign;
    }
  }
}

TEST(Umeyama, NoneIsIdentity) {
  const auto gt = MakeLoopTrajectory(50).Positions();
  const auto est =
      Transform(Sim3d(2.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3)), gt);
  const auto result = Umeyama(est, gt, Alignment::kNone);
  EXPECT_EQ(result.status, AlignmentStatus::kOk);
  ExpectSim3Near(result.gt_from_est, Sim3d(), 0.0);
  EXPECT_GT(result.rms_residual, 1.0);
}

TEST(Umeyama, DegenerateInputs) {
  // Fewer than 3 points.
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  const auto few = Umeyama(two, two, Alignment::kSim3);
  EXPECT_EQ(few.status, AlignmentStatus::kTooFewPoints);
  ExpectSim3Near(few.gt_from_est, Sim3d(), 0.0);

  // Collinear points: a minimiser (zero residual here) but flagged as degenerate.
  std::vector<Eigen::Vector3d> line_est, line_gt;
  for (int i = 0; i < 10; ++i) {
    line_est.emplace_back(i, 0, 0);
    line_gt.emplace_back(0, 2.0 * i + 1.0, 5);
  }
  const auto collinear = Umeyama(line_est, line_gt, Alignment::kSim3);
  EXPECT_EQ(collinear.status, AlignmentStatus::kDegenerate);
  EXPECT_NEAR(collinear.gt_from_est.scale, 2.0, 1e-12);
  EXPECT_LT(collinear.rms_residual, 1e-9);

  // All estimate points identical: pure translation onto the gt mean.
  const std::vector<Eigen::Vector3d> same(5, Eigen::Vector3d(1, 1, 1));
  const std::vector<Eigen::Vector3d> spread = {
      {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {4, 4, 4}};
  const auto point = Umeyama(same, spread, Alignment::kSim3);
  EXPECT_EQ(point.status, AlignmentStatus::kDegenerate);
  EXPECT_EQ(point.gt_from_est.scale, 1.0);
  EXPECT_LT((point.gt_from_est.translation - Eigen::Vector3d(0, 0, 0)).norm(), 1e-12);

  // Mismatched sizes are a caller bug.
  EXPECT_THROW(Umeyama(two, same, Alignment::kSE3), std::invalid_argument);
}

TEST(Umeyama, ReflectionIsNeverReturned) {
  // A mirrored point set: the best proper rotation must have det +1.
  const auto gt = MakeLoopTrajectory(80).Positions();
  std::vector<Eigen::Vector3d> mirrored;
  for (const auto& p : gt) mirrored.emplace_back(-p.x(), p.y(), p.z());
  const auto result = Umeyama(mirrored, gt, Alignment::kSE3);
  EXPECT_NEAR(result.gt_from_est.rotation.toRotationMatrix().determinant(), 1.0, 1e-12);
  EXPECT_GT(result.rms_residual, 1.0);
}

TEST(Umeyama, ParseAlignment) {
  EXPECT_EQ(ParseAlignment("sim3"), Alignment::kSim3);
  EXPECT_EQ(ParseAlignment("se3"), Alignment::kSE3);
  EXPECT_EQ(ParseAlignment("none"), Alignment::kNone);
  EXPECT_THROW(ParseAlignment("SIM3x"), std::invalid_argument);
  for (auto a : {Alignment::kNone, Alignment::kSE3, Alignment::kSim3}) {
    EXPECT_EQ(ParseAlignment(ToString(a)), a);
  }
}

TEST(Umeyama, KittiSequence00MovedBySim3AlignsBack) {
  SL_REQUIRE_DATA("kitti_gt_poses/00.txt");
  const auto gt =
      test::KittiTrajectory(test::ReadKittiMatrices(test::DataDir() / "kitti_gt_poses/00.txt"));
  ASSERT_EQ(gt.size(), 4541u);
  auto rng = test::SeededRng(4);
  const Sim3d gt_from_est = RandomSim3(rng);
  const Sim3d est_from_gt = gt_from_est.Inverse();
  Trajectory est = gt;
  for (auto& pose : est.poses)
    pose.world_from_cam = ApplyAlignment(est_from_gt, pose.world_from_cam);
  EvaluationOptions options;
  options.association.method = AssociationMethod::kIndex;
  options.alignment = Alignment::kSim3;
  const auto eval = EvaluateTrajectory(gt, est, options);
  ASSERT_EQ(eval.status, EvaluationStatus::kOk);
  EXPECT_EQ(eval.association.pairs.size(), gt.size());
  ExpectSim3Near(eval.alignment.gt_from_est, gt_from_est, 1e-9);
  EXPECT_LT(eval.ate.rmse, 1e-6);
  EXPECT_LT(eval.ate.max, 1e-6);
  ASSERT_TRUE(eval.kitti && eval.kitti->t_err_pct);
  EXPECT_LT(*eval.kitti->t_err_pct, 1e-9);
  EXPECT_LT(*eval.kitti->r_err_deg_per_100m, 1e-4);
  ASSERT_TRUE(eval.rpe && eval.rpe->rotation_deg);
  EXPECT_LT(eval.rpe->translation.max, 1e-6);
}

}  // namespace
}  // namespace sparseloop
